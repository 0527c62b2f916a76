//! The physics backends behind [`Model`](super::Model) and [`Data`](super::Data).
//!
//! [`Physics`] names a backend; [`set_default_physics`] picks the one that
//! [`Model::from_xml_str`](super::Model::from_xml_str) and
//! [`Model::from_xml_file`](super::Model::from_xml_file) use, and
//! [`Model::from_xml_str_with`](super::Model::from_xml_str_with) picks one for a single model.
//!
//! Inside the crate a backend is a pair of object-safe traits, [`PhysicsModel`] and
//! [`PhysicsData`]: the raw operations `Model` and `Data` are built on. `super::mj2` implements
//! them over Debian's MuJoCo 2.2.2, and `super::mj3` (feature `mujoco3`) over MuJoCo 3.17
//! through the `mujoco-rs` crate.

use std::cell::Cell;
use std::fmt;
use std::str::FromStr;
use std::sync::atomic::{AtomicU8, Ordering};

use serde::{Deserialize, Serialize};

use super::error::MujocoError;

/// A physics engine for the MuJoCo environments.
///
/// The two backends compile the same MJCF models. Without contacts they simulate the same
/// trajectories to rounding; MuJoCo 3 changed parts of the collision and constraint code, so
/// trajectories with contacts part within a few steps (measured in `docs/mujoco.md`, "MuJoCo 3").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Physics {
    /// MuJoCo 2.2.2, Debian's `libmujoco-dev`, opened at run time (see
    /// [`check_library`](super::check_library) and `APO_MUJOCO_LIB`): the default, in every
    /// build, and what the Gymnasium v4 suites were written for.
    #[default]
    Mujoco2,
    /// MuJoCo 3.17.0 through the `mujoco-rs` 7.0.0 crate, linked when the binary is built.
    /// Only in builds with the cargo feature `mujoco3`; in other builds loading a model with
    /// it fails with [`MujocoError::Unavailable`].
    Mujoco3,
}

impl Physics {
    /// Every backend, in the order of [`Physics::name`]'s listing.
    pub const ALL: [Physics; 2] = [Physics::Mujoco2, Physics::Mujoco3];

    /// The backend's name, as [`FromStr`] accepts it and [`fmt::Display`] writes it:
    /// `mujoco2` or `mujoco3`.
    pub const fn name(self) -> &'static str {
        match self {
            Physics::Mujoco2 => "mujoco2",
            Physics::Mujoco3 => "mujoco3",
        }
    }

    /// The MuJoCo version the backend's bindings are for (`2.2.2` or `3.17.0`).
    pub const fn version(self) -> &'static str {
        match self {
            Physics::Mujoco2 => "2.2.2",
            Physics::Mujoco3 => "3.17.0",
        }
    }

    /// Whether this build contains the backend. MuJoCo 2 is always built in (its library may
    /// still be missing at run time: see [`Physics::check`]); MuJoCo 3 needs the cargo feature
    /// `mujoco3`.
    pub const fn is_built(self) -> bool {
        match self {
            Physics::Mujoco2 => true,
            Physics::Mujoco3 => cfg!(feature = "mujoco3"),
        }
    }
}

impl fmt::Display for Physics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Physics {
    type Err = MujocoError;

    /// Parses `mujoco2` or `mujoco3` (ignoring case and surrounding blanks); any other text
    /// gives [`MujocoError::InvalidInput`] listing the choices.
    fn from_str(text: &str) -> Result<Physics, MujocoError> {
        let wanted = text.trim();
        Physics::ALL
            .into_iter()
            .find(|physics| physics.name().eq_ignore_ascii_case(wanted))
            .ok_or_else(|| {
                let choices = Physics::ALL.map(Physics::name).join(", ");
                MujocoError::InvalidInput(format!(
                    "unknown MuJoCo physics `{wanted}`; the choices are: {choices}"
                ))
            })
    }
}

/// The process-wide default backend, as the index of a [`Physics`] variant.
static DEFAULT_PHYSICS: AtomicU8 = AtomicU8::new(0);

/// Sets the backend that [`Model::from_xml_str`](super::Model::from_xml_str) and
/// [`Model::from_xml_file`](super::Model::from_xml_file) use from now on, in every thread.
///
/// Models already loaded keep their backend. The registered environments load their models
/// through these two functions, so this picks the physics of every environment made later.
/// Setting a backend this build lacks is allowed: loading a model then fails with
/// [`MujocoError::Unavailable`].
pub fn set_default_physics(physics: Physics) {
    let index = match physics {
        Physics::Mujoco2 => 0,
        Physics::Mujoco3 => 1,
    };
    DEFAULT_PHYSICS.store(index, Ordering::Relaxed);
}

thread_local! {
    /// The backend chosen for the current thread by [`with_physics`], over the process default.
    static SCOPED: Cell<Option<Physics>> = const { Cell::new(None) };
}

/// The backend that [`Model::from_xml_str`](super::Model::from_xml_str) and
/// [`Model::from_xml_file`](super::Model::from_xml_file) use: the one a registry build with
/// [`MakeOptions::physics`](crate::MakeOptions::physics) is running under on this thread, else
/// [`Physics::Mujoco2`] unless [`set_default_physics`] chose another.
pub fn default_physics() -> Physics {
    if let Some(physics) = SCOPED.get() {
        return physics;
    }
    match DEFAULT_PHYSICS.load(Ordering::Relaxed) {
        1 => Physics::Mujoco3,
        _ => Physics::Mujoco2,
    }
}

/// Runs `build` with `physics` as this thread's [`default_physics`], then restores the previous
/// choice (also if `build` panics): how the registry builds an environment on the physics its
/// [`MakeOptions`](crate::MakeOptions) name, without touching other threads.
pub(crate) fn with_physics<R>(physics: Physics, build: impl FnOnce() -> R) -> R {
    /// Restores the previous choice when dropped.
    struct Restore(Option<Physics>);
    impl Drop for Restore {
        fn drop(&mut self) {
            SCOPED.set(self.0);
        }
    }
    let _restore = Restore(SCOPED.replace(Some(physics)));
    build()
}

/// A compiled model of one backend: the raw operations [`Model`](super::Model) needs.
///
/// Sizes are counts (`nq`, `nbody`, ...); the slices have exactly the lengths the method
/// documents, and are empty where MuJoCo left an array out.
pub(crate) trait PhysicsModel: Send + Sync + fmt::Debug {
    /// The backend of this model.
    fn physics(&self) -> Physics;

    /// Number of generalized coordinates.
    fn nq(&self) -> usize;
    /// Number of degrees of freedom.
    fn nv(&self) -> usize;
    /// Number of controls, which is also the number of actuators: each backend rejects models
    /// where the two differ.
    fn nu(&self) -> usize;
    /// Number of bodies, the world body included.
    fn nbody(&self) -> usize;
    /// Number of joints.
    fn njnt(&self) -> usize;
    /// Number of sites.
    fn nsite(&self) -> usize;
    /// Number of sensors.
    fn nsensor(&self) -> usize;
    /// Total length of the sensor data.
    fn nsensordata(&self) -> usize;
    /// Number of keyframes.
    fn nkey(&self) -> usize;
    /// The simulation time step in seconds.
    fn timestep(&self) -> f64;

    /// `qpos0` (`[nq]`).
    fn qpos0(&self) -> &[f64];
    /// `body_mass` (`[nbody]`).
    fn body_mass(&self) -> &[f64];
    /// `actuator_ctrlrange` (`[nu]`).
    fn actuator_ctrlrange(&self) -> &[[f64; 2]];
    /// Whether actuator `id` is control-limited; `false` when `id` is out of range.
    fn actuator_ctrllimited(&self, id: usize) -> bool;
    /// `jnt_qposadr` (`[njnt]`).
    fn jnt_qposadr(&self) -> &[i32];
    /// `jnt_dofadr` (`[njnt]`).
    fn jnt_dofadr(&self) -> &[i32];
    /// `sensor_adr` (`[nsensor]`).
    fn sensor_adr(&self) -> &[i32];
    /// `sensor_dim` (`[nsensor]`).
    fn sensor_dim(&self) -> &[i32];
    /// `key_qpos` (`[nkey * nq]`, keyframe after keyframe).
    fn key_qpos(&self) -> &[f64];
    /// `body_pos` (`[nbody]`).
    fn body_pos(&self) -> &[[f64; 3]];
    /// `body_quat` (`[nbody]`).
    fn body_quat(&self) -> &[[f64; 4]];
    /// The fields that decide the dynamics, copied.
    fn dynamics(&self) -> Dynamics;

    /// Writes `body_pos[id]` and `body_quat[id]`; `false` (and no change) when `id` is out of
    /// range.
    ///
    /// The backend data made by [`PhysicsModel::make_data`] may share this model's memory.
    /// The caller guarantees that while this runs nothing else reads the model: it holds the
    /// [`Model`](super::Model) exclusively, which (since every `Data` holds an `Arc` of its
    /// `Model`) means at most one `Data` exists for it, and that one is borrowed exclusively
    /// too (see [`Data::model_mut`](super::Data::model_mut)).
    fn set_body_pose(&mut self, id: usize, pos: [f64; 3], quat: [f64; 4]) -> bool;

    /// The id of the object of `kind` named `name` (`mj_name2id`), `None` if there is none.
    /// `name` holds no NUL byte (the caller checks).
    fn name_to_id(&self, kind: ObjKind, name: &str) -> Option<usize>;

    /// Allocates simulation data for this model, in the reference configuration. The data
    /// keeps this model's memory alive on its own (it holds a reference count of it).
    fn make_data(&self) -> Result<Box<dyn PhysicsData>, MujocoError>;
}

/// The simulation state of one backend model: the raw operations [`Data`](super::Data) needs.
/// Slice lengths are the model's sizes, as documented on each method of `Data`.
pub(crate) trait PhysicsData: Send + Sync {
    /// `mj_step`.
    fn step(&mut self);
    /// `mj_forward`.
    fn forward(&mut self);
    /// `mj_resetData`.
    fn reset(&mut self);
    /// `mj_rnePostConstraint`.
    fn rne_post_constraint(&mut self);

    /// The simulation time.
    fn time(&self) -> f64;
    /// `qpos` (`[nq]`).
    fn qpos(&self) -> &[f64];
    /// `qpos`, writable.
    fn qpos_mut(&mut self) -> &mut [f64];
    /// `qvel` (`[nv]`).
    fn qvel(&self) -> &[f64];
    /// `qvel`, writable.
    fn qvel_mut(&mut self) -> &mut [f64];
    /// `qpos` and `qvel` at once, writable.
    fn state_mut(&mut self) -> (&mut [f64], &mut [f64]);
    /// `ctrl` (`[nu]`).
    fn ctrl(&self) -> &[f64];
    /// `ctrl`, writable.
    fn ctrl_mut(&mut self) -> &mut [f64];
    /// `xpos` (`[nbody]`).
    fn xpos(&self) -> &[[f64; 3]];
    /// `xmat` (`[nbody]`).
    fn xmat(&self) -> &[[f64; 9]];
    /// `xfrc_applied`, writable (`[nbody]`).
    fn xfrc_applied_mut(&mut self) -> &mut [[f64; 6]];
    /// `xipos` (`[nbody]`).
    fn xipos(&self) -> &[[f64; 3]];
    /// `site_xpos` (`[nsite]`).
    fn site_xpos(&self) -> &[[f64; 3]];
    /// `cinert` (`[nbody]`).
    fn cinert(&self) -> &[[f64; 10]];
    /// `cvel` (`[nbody]`).
    fn cvel(&self) -> &[[f64; 6]];
    /// `cfrc_ext` (`[nbody]`).
    fn cfrc_ext(&self) -> &[[f64; 6]];
    /// `qfrc_actuator` (`[nv]`).
    fn qfrc_actuator(&self) -> &[f64];
    /// `qfrc_constraint` (`[nv]`).
    fn qfrc_constraint(&self) -> &[f64];
    /// `sensordata` (`[nsensordata]`).
    fn sensordata(&self) -> &[f64];

    /// Number of active contacts.
    fn ncon(&self) -> usize;
    /// Contact `i`'s geoms, position and force (`mj_contactForce`); `None` when `i >= ncon`.
    fn contact_force(&self, i: usize) -> Option<ContactForce>;
    /// How many times `warning` fired since the last reset; 0 for a warning the backend's
    /// MuJoCo version does not have.
    fn warning_count(&self, warning: Warning) -> u64;

    /// The MuJoCo 2.2.2 `mjModel` and `mjData` behind this data, for the renderer; `None` for
    /// other backends. The pointers are valid while `self` is borrowed.
    fn mj2_raw(&mut self) -> Option<(*const super::ffi::mjModel, *mut super::ffi::mjData)> {
        None
    }

    /// The MuJoCo 3.17 `mjModel` and `mjData` behind this data, for the renderer; `None` for
    /// other backends. The pointers are valid while `self` is borrowed.
    #[cfg(feature = "mujoco3")]
    fn mj3_raw(
        &mut self,
    ) -> Option<(
        *const mujoco_rs::mujoco_c::mjModel,
        *mut mujoco_rs::mujoco_c::mjData,
    )> {
        None
    }
}

/// The kinds of named model objects that can be looked up with [`Model::id`](super::Model::id).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ObjKind {
    /// A body (`<body>`).
    Body,
    /// A joint (`<joint>`, `<freejoint>`).
    Joint,
    /// A geom (`<geom>`).
    Geom,
    /// A site (`<site>`).
    Site,
    /// A sensor (`<sensor>` children).
    Sensor,
    /// An actuator (`<actuator>` children).
    Actuator,
    /// A keyframe (`<key>`).
    Key,
}

impl ObjKind {
    pub(crate) fn label(self) -> &'static str {
        match self {
            ObjKind::Body => "body",
            ObjKind::Joint => "joint",
            ObjKind::Geom => "geom",
            ObjKind::Site => "site",
            ObjKind::Sensor => "sensor",
            ObjKind::Actuator => "actuator",
            ObjKind::Key => "keyframe",
        }
    }
}

/// MuJoCo's simulator warnings (`mjtWarning`), counted per [`Data`](super::Data) since its last reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Warning {
    /// (Near) singular inertia matrix.
    Inertia,
    /// Too many contacts for the contact buffer; some were dropped.
    ContactFull,
    /// Too many constraints for the constraint buffer; some were dropped.
    ConstraintFull,
    /// Too many visual geoms (rendering only). MuJoCo 3 no longer has this warning: with
    /// [`Physics::Mujoco3`] its count is always 0.
    VisualGeomFull,
    /// A non-finite or huge number in `qpos`; MuJoCo reset the state.
    BadQpos,
    /// A non-finite or huge number in `qvel`; MuJoCo reset the state.
    BadQvel,
    /// A non-finite or huge number in `qacc`; MuJoCo reset the state.
    BadQacc,
    /// A non-finite or huge number in `ctrl`; MuJoCo zeroed the controls.
    BadCtrl,
}

impl Warning {
    /// The warnings that mean the simulated state can no longer be trusted: the bad-number
    /// warnings and the buffer overflows. (Inertia and visual warnings do not count.)
    pub const UNSTABLE: [Warning; 6] = [
        Warning::ContactFull,
        Warning::ConstraintFull,
        Warning::BadQpos,
        Warning::BadQvel,
        Warning::BadQacc,
        Warning::BadCtrl,
    ];
}

/// The fields of a compiled model that decide its dynamics, copied out of it: what two models
/// must share to move alike (names, sensors and visuals left out). Each vector has one entry
/// per object, in the model's order: bodies (world first), joints, degrees of freedom, geoms,
/// actuators. Angles are in radians, as MuJoCo compiles them.
#[derive(Debug, Clone, PartialEq)]
pub struct Dynamics {
    /// `opt.timestep`, seconds.
    pub timestep: f64,
    /// `opt.gravity`.
    pub gravity: [f64; 3],
    /// `opt.magnetic`.
    pub magnetic: [f64; 3],
    /// `opt.integrator` (MuJoCo's `mjtIntegrator`: 0 is Euler).
    pub integrator: i32,
    /// `opt.cone` (`mjtCone`: 0 pyramidal, 1 elliptic).
    pub cone: i32,
    /// `opt.impratio`.
    pub impratio: f64,
    /// `opt.iterations`, the constraint solver's.
    pub iterations: i32,
    /// `opt.tolerance`, the constraint solver's.
    pub tolerance: f64,
    /// `opt.disableflags` (`mjtDisableBit` bits of the backend's MuJoCo version).
    pub disableflags: i32,
    /// `opt.enableflags` (`mjtEnableBit` bits of the backend's MuJoCo version).
    pub enableflags: i32,
    /// `body_mass` (`[nbody]`).
    pub body_mass: Vec<f64>,
    /// `body_inertia`, the diagonal inertia in the body's inertial frame (`[nbody][3]`).
    pub body_inertia: Vec<[f64; 3]>,
    /// `jnt_pos`, each joint's anchor in its body's frame (`[njnt][3]`).
    pub jnt_pos: Vec<[f64; 3]>,
    /// `jnt_axis` (`[njnt][3]`).
    pub jnt_axis: Vec<[f64; 3]>,
    /// `jnt_stiffness` (`[njnt]`).
    pub jnt_stiffness: Vec<f64>,
    /// `jnt_limited` (`[njnt]`).
    pub jnt_limited: Vec<bool>,
    /// `jnt_range`, only meaningful where `jnt_limited` (`[njnt][2]`).
    pub jnt_range: Vec<[f64; 2]>,
    /// `dof_armature` (`[nv]`).
    pub dof_armature: Vec<f64>,
    /// `dof_damping` (`[nv]`).
    pub dof_damping: Vec<f64>,
    /// `geom_size` (`[ngeom][3]`).
    pub geom_size: Vec<[f64; 3]>,
    /// `geom_pos`, each geom's centre in its body's frame (`[ngeom][3]`).
    pub geom_pos: Vec<[f64; 3]>,
    /// `geom_friction`: sliding, torsional, rolling (`[ngeom][3]`).
    pub geom_friction: Vec<[f64; 3]>,
    /// `geom_condim` (`[ngeom]`).
    pub geom_condim: Vec<i32>,
    /// `geom_margin` (`[ngeom]`).
    pub geom_margin: Vec<f64>,
    /// `geom_solref` (`[ngeom][2]`).
    pub geom_solref: Vec<[f64; 2]>,
    /// `geom_solimp` (`[ngeom][5]`).
    pub geom_solimp: Vec<[f64; 5]>,
    /// `actuator_gear` (`[nu][6]`).
    pub actuator_gear: Vec<[f64; 6]>,
    /// `actuator_forcelimited` (`[nu]`).
    pub actuator_forcelimited: Vec<bool>,
    /// `actuator_forcerange`, only meaningful where `actuator_forcelimited` (`[nu][2]`).
    pub actuator_forcerange: Vec<[f64; 2]>,
}

/// The force of one contact, from `mj_contactForce`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactForce {
    /// The first geom of the contact.
    pub geom1: usize,
    /// The second geom of the contact.
    pub geom2: usize,
    /// The contact point in world coordinates.
    pub pos: [f64; 3],
    /// Normal force, two tangential forces, then three torques, in the contact frame.
    pub force: [f64; 6],
}
