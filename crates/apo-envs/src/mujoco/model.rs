//! The safe wrapper: [`Model`] (a compiled MuJoCo model) and [`Data`] (its simulation state).
//!
//! Both run on one of two physics backends, chosen per model with [`Physics`]: MuJoCo 2.2.2
//! (the default, Debian's library opened at run time) or MuJoCo 3.17 (cargo feature
//! `mujoco3`). The API is the same for both; the `physics` module has the backends.
//!
//! # Threads
//!
//! - [`Model`] is `Send + Sync`. After loading, the model is never written except by
//!   [`Model::set_body_pose`], which takes `&mut self`; every other method takes `&self`, and
//!   MuJoCo's simulation functions only read the model. So one model is shared read-only
//!   between environments on several threads, as an `Arc<Model>`.
//! - [`Data`] is `Send + Sync`. It owns its MuJoCo data (MuJoCo keeps no hidden pointer to it,
//!   and the libraries keep no per-thread state), so it can move to another thread; every
//!   method that writes takes `&mut self`, so shared references only read.
//!   Each environment owns its own `Data`.

use std::path::Path;
use std::sync::Arc;

use super::error::MujocoError;
use super::physics::{default_physics, Physics, PhysicsData, PhysicsModel};
pub use super::physics::{ContactForce, Dynamics, ObjKind, Warning};

/// A compiled MuJoCo model, read-only after loading except for [`Model::set_body_pose`]. See
/// the module doc on threads.
pub struct Model {
    raw: Box<dyn PhysicsModel>,
}

impl std::fmt::Debug for Model {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Model")
            .field("physics", &self.physics())
            .field("nq", &self.nq())
            .field("nv", &self.nv())
            .field("nu", &self.nu())
            .field("nbody", &self.nbody())
            .field("timestep", &self.timestep())
            .finish()
    }
}

/// A MuJoCo `int` address or size as a count; negative values count as 0.
fn size(n: i32) -> usize {
    usize::try_from(n).unwrap_or(0)
}

impl Model {
    /// Loads and compiles an MJCF file with the default physics ([`default_physics`]). A missing
    /// file or an invalid model gives [`MujocoError::Model`] with MuJoCo's own message.
    pub fn from_xml_file(path: impl AsRef<Path>) -> Result<Model, MujocoError> {
        Model::from_xml_file_with(path, default_physics())
    }

    /// Compiles an MJCF model given as text with the default physics ([`default_physics`]),
    /// through MuJoCo's in-memory file system, so the model may not include other files or
    /// meshes. An invalid model gives [`MujocoError::Model`] with MuJoCo's own message.
    pub fn from_xml_str(xml: &str) -> Result<Model, MujocoError> {
        Model::from_xml_str_with(xml, default_physics())
    }

    /// Like [`Model::from_xml_file`], with `physics`. A backend this build lacks gives
    /// [`MujocoError::Unavailable`].
    pub fn from_xml_file_with(
        path: impl AsRef<Path>,
        physics: Physics,
    ) -> Result<Model, MujocoError> {
        let raw = load_xml_file(physics, path.as_ref())?;
        Ok(Model { raw })
    }

    /// Like [`Model::from_xml_str`], with `physics`. A backend this build lacks gives
    /// [`MujocoError::Unavailable`].
    pub fn from_xml_str_with(xml: &str, physics: Physics) -> Result<Model, MujocoError> {
        let raw = load_xml_str(physics, xml)?;
        Ok(Model { raw })
    }

    /// The physics backend this model was compiled by (and its data run on).
    pub fn physics(&self) -> Physics {
        self.raw.physics()
    }

    /// Number of generalized coordinates (`qpos` length).
    pub fn nq(&self) -> usize {
        self.raw.nq()
    }

    /// Number of degrees of freedom (`qvel` length).
    pub fn nv(&self) -> usize {
        self.raw.nv()
    }

    /// Number of actuators (`ctrl` length).
    pub fn nu(&self) -> usize {
        self.raw.nu()
    }

    /// Number of bodies, the world body included.
    pub fn nbody(&self) -> usize {
        self.raw.nbody()
    }

    /// Number of joints.
    pub fn njnt(&self) -> usize {
        self.raw.njnt()
    }

    /// Number of sites.
    pub fn nsite(&self) -> usize {
        self.raw.nsite()
    }

    /// Number of sensors.
    pub fn nsensor(&self) -> usize {
        self.raw.nsensor()
    }

    /// Total length of the sensor data (`sensordata` length).
    pub fn nsensordata(&self) -> usize {
        self.raw.nsensordata()
    }

    /// Number of keyframes.
    pub fn nkey(&self) -> usize {
        self.raw.nkey()
    }

    /// The simulation time step in seconds (`opt.timestep`).
    pub fn timestep(&self) -> f64 {
        self.raw.timestep()
    }

    /// The reference configuration `qpos0` (`[nq]`), the state `mj_resetData` sets.
    pub fn qpos0(&self) -> &[f64] {
        self.raw.qpos0()
    }

    /// The mass of each body (`[nbody]`).
    pub fn body_mass(&self) -> &[f64] {
        self.raw.body_mass()
    }

    /// The control range `[low, high]` of each actuator (`[nu]`); only meaningful where
    /// [`Model::actuator_ctrllimited`] is true.
    pub fn actuator_ctrlrange(&self) -> &[[f64; 2]] {
        self.raw.actuator_ctrlrange()
    }

    /// Whether actuator `id`'s control is clamped to its control range.
    pub fn actuator_ctrllimited(&self, id: usize) -> bool {
        self.raw.actuator_ctrllimited(id)
    }

    /// The address in `qpos` of joint `id`'s first coordinate.
    pub fn joint_qpos_adr(&self, id: usize) -> Option<usize> {
        self.raw.jnt_qposadr().get(id).map(|&a| size(a))
    }

    /// The address in `qvel` of joint `id`'s first degree of freedom.
    pub fn joint_dof_adr(&self, id: usize) -> Option<usize> {
        self.raw.jnt_dofadr().get(id).map(|&a| size(a))
    }

    /// The range `[address, address + dim)` of sensor `id`'s values in `sensordata`.
    pub fn sensor_range(&self, id: usize) -> Option<std::ops::Range<usize>> {
        let adr = size(*self.raw.sensor_adr().get(id)?);
        let dim = size(*self.raw.sensor_dim().get(id)?);
        Some(adr..adr + dim)
    }

    /// The `qpos` of keyframe `id` (`[nq]`).
    pub fn key_qpos(&self, id: usize) -> Option<&[f64]> {
        let nq = self.nq();
        let start = id.checked_mul(nq)?;
        self.raw.key_qpos().get(start..start.checked_add(nq)?)
    }

    /// Body frame positions relative to the parent body (`[nbody][3]`).
    pub fn body_pos(&self) -> &[[f64; 3]] {
        self.raw.body_pos()
    }

    /// Body frame orientations relative to the parent body, as unit quaternions `(w, x, y, z)`
    /// (`[nbody][4]`).
    pub fn body_quat(&self) -> &[[f64; 4]] {
        self.raw.body_quat()
    }

    /// The fields of the compiled model that decide its dynamics (masses, inertias, joints,
    /// damping, armature, contact parameters, actuators, time step), copied: what a test
    /// compares to pin a model against published facts.
    pub fn dynamics(&self) -> Dynamics {
        self.raw.dynamics()
    }

    /// Places body `id` at `pos` with orientation `quat` (a unit quaternion `(w, x, y, z)`)
    /// relative to its parent: what editing the MJCF's `pos` and `quat` and compiling again
    /// would give, without compiling. Takes effect at the next `mj_forward`/`mj_step` of the
    /// model's data. Returns `false` (and changes nothing) if `id` is out of range.
    ///
    /// Only a model nothing else shares can be edited: see [`Data::model_mut`].
    pub fn set_body_pose(&mut self, id: usize, pos: [f64; 3], quat: [f64; 4]) -> bool {
        // `&mut self` is the contract of `PhysicsModel::set_body_pose`: a `Model` is only
        // reachable mutably before it is shared (no `Data` exists yet, since `Data::new` takes
        // an `Arc<Model>`) or through `Arc::get_mut` (no other `Arc`, hence at most the one
        // `Data` that `Data::model_mut` borrows exclusively).
        self.raw.set_body_pose(id, pos, quat)
    }

    /// The id of the object of `kind` named `name` (`mj_name2id`).
    pub fn id(&self, kind: ObjKind, name: &str) -> Result<usize, MujocoError> {
        let unknown = || MujocoError::UnknownName {
            kind: kind.label(),
            name: name.to_owned(),
        };
        if name.contains('\0') {
            return Err(unknown());
        }
        self.raw.name_to_id(kind, name).ok_or_else(unknown)
    }
}

/// The simulation state of a [`Model`] (MuJoCo's `mjData`); holds an `Arc` of its model, so
/// the model outlives it. See the module doc on threads.
pub struct Data {
    raw: Box<dyn PhysicsData>,
    model: Arc<Model>,
}

impl std::fmt::Debug for Data {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Data")
            .field("time", &self.time())
            .field("qpos", &self.qpos())
            .field("qvel", &self.qvel())
            .finish()
    }
}

impl Data {
    /// Allocates simulation data for `model`, in the reference configuration.
    pub fn new(model: Arc<Model>) -> Result<Data, MujocoError> {
        let raw = model.raw.make_data()?;
        Ok(Data { raw, model })
    }

    /// The MuJoCo 2.2.2 model and data behind this data, for the renderer; `None` on other
    /// physics. Valid while `self` is borrowed.
    pub(crate) fn mj2_raw(
        &mut self,
    ) -> Option<(*const super::ffi::mjModel, *mut super::ffi::mjData)> {
        self.raw.mj2_raw()
    }

    /// The MuJoCo 3.17 model and data behind this data, for the renderer; `None` on other
    /// physics. Valid while `self` is borrowed.
    #[cfg(feature = "mujoco3")]
    pub(crate) fn mj3_raw(
        &mut self,
    ) -> Option<(
        *const mujoco_rs::mujoco_c::mjModel,
        *mut mujoco_rs::mujoco_c::mjData,
    )> {
        self.raw.mj3_raw()
    }

    /// The model this data simulates.
    pub fn model(&self) -> &Arc<Model> {
        &self.model
    }

    /// The model, writable, when this data is its only holder (a model built for one
    /// environment with `Data::new(Arc::new(model))`); `None` when it is shared.
    pub fn model_mut(&mut self) -> Option<&mut Model> {
        Arc::get_mut(&mut self.model)
    }

    /// Advances the simulation by one time step (`mj_step`).
    pub fn step(&mut self) {
        self.raw.step();
    }

    /// Computes the derived quantities (positions, velocities, forces) of the current
    /// state without integrating (`mj_forward`).
    pub fn forward(&mut self) {
        self.raw.forward();
    }

    /// Resets to the reference configuration, zero velocity, zero controls and zero
    /// warning counters (`mj_resetData`).
    pub fn reset(&mut self) {
        self.raw.reset();
    }

    /// Computes `cacc`, `cfrc_int` and `cfrc_ext` (`mj_rnePostConstraint`), which `mj_step`
    /// leaves stale unless the model has force-related sensors.
    pub fn rne_post_constraint(&mut self) {
        self.raw.rne_post_constraint();
    }

    /// The simulation time in seconds.
    pub fn time(&self) -> f64 {
        self.raw.time()
    }

    /// Generalized coordinates (`[nq]`).
    pub fn qpos(&self) -> &[f64] {
        self.raw.qpos()
    }

    /// Generalized coordinates, writable (`[nq]`); call [`Data::forward`] after changing them
    /// to update the derived quantities.
    pub fn qpos_mut(&mut self) -> &mut [f64] {
        self.raw.qpos_mut()
    }

    /// Generalized velocities (`[nv]`).
    pub fn qvel(&self) -> &[f64] {
        self.raw.qvel()
    }

    /// Generalized velocities, writable (`[nv]`).
    pub fn qvel_mut(&mut self) -> &mut [f64] {
        self.raw.qvel_mut()
    }

    /// `qpos` and `qvel` at once, writable (`[nq]`, `[nv]`).
    pub fn state_mut(&mut self) -> (&mut [f64], &mut [f64]) {
        self.raw.state_mut()
    }

    /// Actuator controls (`[nu]`).
    pub fn ctrl(&self) -> &[f64] {
        self.raw.ctrl()
    }

    /// Actuator controls, writable (`[nu]`).
    pub fn ctrl_mut(&mut self) -> &mut [f64] {
        self.raw.ctrl_mut()
    }

    /// Body frame positions in world coordinates (`[nbody][3]`).
    pub fn xpos(&self) -> &[[f64; 3]] {
        self.raw.xpos()
    }

    /// Body frame orientations in world coordinates, as row-major rotation matrices
    /// (`[nbody][9]`): a vector `v` in the body's frame is `R · v` in the world's.
    pub fn xmat(&self) -> &[[f64; 9]] {
        self.raw.xmat()
    }

    /// External forces and torques applied to each body's centre of mass in world
    /// coordinates, force first (`[nbody][6]`), writable; MuJoCo keeps them until changed.
    pub fn xfrc_applied_mut(&mut self) -> &mut [[f64; 6]] {
        self.raw.xfrc_applied_mut()
    }

    /// Body centre-of-mass positions in world coordinates (`[nbody][3]`).
    pub fn xipos(&self) -> &[[f64; 3]] {
        self.raw.xipos()
    }

    /// Site positions in world coordinates (`[nsite][3]`).
    pub fn site_xpos(&self) -> &[[f64; 3]] {
        self.raw.site_xpos()
    }

    /// Body inertias in the centre-of-mass frame (`[nbody][10]`).
    pub fn cinert(&self) -> &[[f64; 10]] {
        self.raw.cinert()
    }

    /// Body velocities in the centre-of-mass frame, rotation first (`[nbody][6]`).
    pub fn cvel(&self) -> &[[f64; 6]] {
        self.raw.cvel()
    }

    /// External (contact) forces on each body in the centre-of-mass frame, torque first
    /// (`[nbody][6]`); up to date only after [`Data::rne_post_constraint`].
    pub fn cfrc_ext(&self) -> &[[f64; 6]] {
        self.raw.cfrc_ext()
    }

    /// Actuator forces in generalized coordinates (`[nv]`).
    pub fn qfrc_actuator(&self) -> &[f64] {
        self.raw.qfrc_actuator()
    }

    /// Constraint forces in generalized coordinates (`[nv]`).
    pub fn qfrc_constraint(&self) -> &[f64] {
        self.raw.qfrc_constraint()
    }

    /// All sensor values (`[nsensordata]`); see [`Model::sensor_range`] for one sensor's part.
    pub fn sensordata(&self) -> &[f64] {
        self.raw.sensordata()
    }

    /// The values of the sensor named `name`.
    pub fn sensor(&self, name: &str) -> Result<&[f64], MujocoError> {
        let id = self.model.id(ObjKind::Sensor, name)?;
        let range = self
            .model
            .sensor_range(id)
            .ok_or(MujocoError::UnknownName {
                kind: "sensor",
                name: name.into(),
            })?;
        self.sensordata()
            .get(range)
            .ok_or(MujocoError::UnknownName {
                kind: "sensor",
                name: name.into(),
            })
    }

    /// Number of active contacts.
    pub fn ncon(&self) -> usize {
        self.raw.ncon()
    }

    /// The force of contact `i` (`0..ncon`), in the contact frame.
    pub fn contact_force(&self, i: usize) -> Option<ContactForce> {
        self.raw.contact_force(i)
    }

    /// How many times `warning` fired since the last reset.
    pub fn warning_count(&self, warning: Warning) -> u64 {
        self.raw.warning_count(warning)
    }

    /// The total count of the [`Warning::UNSTABLE`] warnings since the last reset.
    pub fn unstable_warnings(&self) -> u64 {
        Warning::UNSTABLE
            .iter()
            .map(|&w| self.warning_count(w))
            .sum()
    }

    /// Whether the simulation can no longer be trusted: an [`Warning::UNSTABLE`] warning fired
    /// since [`Data::unstable_warnings`] read `before`, or the state is not finite.
    pub fn unstable_since(&self, before: u64) -> bool {
        self.unstable_warnings() != before || !self.state_is_finite()
    }

    /// Whether `qpos` and `qvel` are all finite.
    pub fn state_is_finite(&self) -> bool {
        self.qpos().iter().chain(self.qvel()).all(|x| x.is_finite())
    }
}

impl Physics {
    /// Checks that the backend can load models: for MuJoCo 2 that its library opens and is
    /// version 2.2.2 ([`check_library`](super::check_library)), for MuJoCo 3 that it is in
    /// this build and that the linked library is the version `mujoco-rs` was generated for.
    /// Call it at start-up to fail early with a clear message; every model load checks too.
    pub fn check(self) -> Result<(), MujocoError> {
        match self {
            Physics::Mujoco2 => super::library::check_library(),
            Physics::Mujoco3 => mujoco3_check(),
        }
    }
}

/// Compiles the MJCF text `xml` with `physics`.
fn load_xml_str(physics: Physics, xml: &str) -> Result<Box<dyn PhysicsModel>, MujocoError> {
    match physics {
        Physics::Mujoco2 => super::mj2::load_xml_str(xml),
        #[cfg(feature = "mujoco3")]
        Physics::Mujoco3 => super::mj3::load_xml_str(xml),
        #[cfg(not(feature = "mujoco3"))]
        Physics::Mujoco3 => Err(mujoco3_not_built()),
    }
}

/// Loads and compiles the MJCF file at `path` with `physics`.
fn load_xml_file(physics: Physics, path: &Path) -> Result<Box<dyn PhysicsModel>, MujocoError> {
    match physics {
        Physics::Mujoco2 => super::mj2::load_xml_file(path),
        #[cfg(feature = "mujoco3")]
        Physics::Mujoco3 => super::mj3::load_xml_file(path),
        #[cfg(not(feature = "mujoco3"))]
        Physics::Mujoco3 => Err(mujoco3_not_built()),
    }
}

/// [`Physics::check`] for MuJoCo 3.
#[cfg(feature = "mujoco3")]
fn mujoco3_check() -> Result<(), MujocoError> {
    super::mj3::check()
}

/// [`Physics::check`] for MuJoCo 3 in a build without it.
#[cfg(not(feature = "mujoco3"))]
fn mujoco3_check() -> Result<(), MujocoError> {
    Err(mujoco3_not_built())
}

/// The error of every MuJoCo 3 request in a build without the `mujoco3` feature.
#[cfg(not(feature = "mujoco3"))]
fn mujoco3_not_built() -> MujocoError {
    MujocoError::Unavailable {
        physics: Physics::Mujoco3.name(),
        reason: "this build does not include MuJoCo 3.17; rebuild with `--features mujoco3` \
                 (which links libmujoco.so.3.17.0 through mujoco-rs)"
            .into(),
    }
}
