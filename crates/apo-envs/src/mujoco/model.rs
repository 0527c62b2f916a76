//! The safe wrapper: [`Model`] (a compiled `mjModel`) and [`Data`] (an `mjData` bound to it).
//!
//! # Threads
//!
//! - [`Model`] is `Send + Sync`. After loading, the `mjModel` is never written: every
//!   method takes `&self`, and MuJoCo's simulation functions take it as `const mjModel*`.
//!   So one model is shared read-only between environments on several threads, as an
//!   `Arc<Model>`.
//! - [`Data`] is `Send + Sync`. It owns its `mjData` (MuJoCo keeps no hidden pointer to it,
//!   and the library keeps no per-thread state), so it can move to another thread; every
//!   method that writes takes `&mut self`, so shared references only read.
//!   Each environment owns its own `Data`.

use std::ffi::{c_char, CStr, CString};
use std::mem::MaybeUninit;
use std::path::Path;
use std::ptr::NonNull;
use std::sync::{Arc, Mutex};

use super::error::MujocoError;
use super::ffi::{mjData, mjModel, mjVFS, mjtObj, mjtWarning, MujocoApi};
use super::library::api;

/// The kinds of named model objects that can be looked up with [`Model::id`].
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
    fn raw(self) -> mjtObj {
        match self {
            ObjKind::Body => mjtObj::mjOBJ_BODY,
            ObjKind::Joint => mjtObj::mjOBJ_JOINT,
            ObjKind::Geom => mjtObj::mjOBJ_GEOM,
            ObjKind::Site => mjtObj::mjOBJ_SITE,
            ObjKind::Sensor => mjtObj::mjOBJ_SENSOR,
            ObjKind::Actuator => mjtObj::mjOBJ_ACTUATOR,
            ObjKind::Key => mjtObj::mjOBJ_KEY,
        }
    }

    fn label(self) -> &'static str {
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

/// MuJoCo's simulator warnings (`mjtWarning`), counted per [`Data`] since its last reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Warning {
    /// (Near) singular inertia matrix.
    Inertia,
    /// Too many contacts for the contact buffer; some were dropped.
    ContactFull,
    /// Too many constraints for the constraint buffer; some were dropped.
    ConstraintFull,
    /// Too many visual geoms (rendering only).
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

    fn raw(self) -> mjtWarning {
        match self {
            Warning::Inertia => mjtWarning::mjWARN_INERTIA,
            Warning::ContactFull => mjtWarning::mjWARN_CONTACTFULL,
            Warning::ConstraintFull => mjtWarning::mjWARN_CNSTRFULL,
            Warning::VisualGeomFull => mjtWarning::mjWARN_VGEOMFULL,
            Warning::BadQpos => mjtWarning::mjWARN_BADQPOS,
            Warning::BadQvel => mjtWarning::mjWARN_BADQVEL,
            Warning::BadQacc => mjtWarning::mjWARN_BADQACC,
            Warning::BadCtrl => mjtWarning::mjWARN_BADCTRL,
        }
    }
}

/// A compiled MuJoCo model (`mjModel`), read-only after loading. See the module doc on threads.
pub struct Model {
    raw: NonNull<mjModel>,
    api: &'static MujocoApi,
}

// SAFETY: see the module documentation: the mjModel is never mutated after loading and
// MuJoCo only reads it (through `const mjModel*`), so moving it or sharing references
// between threads cannot race.
unsafe impl Send for Model {}
// SAFETY: as above.
unsafe impl Sync for Model {}

impl std::fmt::Debug for Model {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Model")
            .field("nq", &self.nq())
            .field("nv", &self.nv())
            .field("nu", &self.nu())
            .field("nbody", &self.nbody())
            .field("timestep", &self.timestep())
            .finish()
    }
}

/// Size of MuJoCo's error message buffer for the XML loader.
const ERROR_LEN: usize = 1000;
/// The name the in-memory file gets in MuJoCo's virtual file system.
const VFS_NAME: &CStr = c"model.xml";

/// Builds a slice from a MuJoCo array pointer; MuJoCo leaves pointers of empty arrays null.
///
/// # Safety
/// When `len > 0`, `ptr` must point to `len` initialized `T`s that live at least as long as `'a`
/// and are not written while the slice exists.
unsafe fn slice<'a, T>(ptr: *const T, len: usize) -> &'a [T] {
    if len == 0 || ptr.is_null() {
        &[]
    } else {
        // SAFETY: guaranteed by the caller.
        unsafe { std::slice::from_raw_parts(ptr, len) }
    }
}

/// Like [`slice`], mutable.
///
/// # Safety
/// As for [`slice`], and nothing else may access the memory while the slice exists.
unsafe fn slice_mut<'a, T>(ptr: *mut T, len: usize) -> &'a mut [T] {
    if len == 0 || ptr.is_null() {
        &mut []
    } else {
        // SAFETY: guaranteed by the caller.
        unsafe { std::slice::from_raw_parts_mut(ptr, len) }
    }
}

fn size(n: i32) -> usize {
    usize::try_from(n).unwrap_or(0)
}

impl Model {
    /// Loads and compiles an MJCF file. A missing file or an invalid model gives
    /// [`MujocoError::Model`] with MuJoCo's own message.
    pub fn from_xml_file(path: impl AsRef<Path>) -> Result<Model, MujocoError> {
        let api = api()?;
        let path = path.as_ref();
        let source_name = path.display().to_string();
        let c_path = CString::new(path.as_os_str().as_encoded_bytes()).map_err(|_| {
            MujocoError::InvalidInput(format!("path {source_name} contains a NUL byte"))
        })?;
        // SAFETY: a NUL-terminated path and no VFS.
        unsafe { load(api, &c_path, std::ptr::null(), source_name) }
    }

    /// Compiles an MJCF model given as text (through MuJoCo's in-memory file system, so
    /// the model may not include other files or meshes). An invalid model gives
    /// [`MujocoError::Model`] with MuJoCo's own message.
    pub fn from_xml_str(xml: &str) -> Result<Model, MujocoError> {
        let api = api()?;
        let len = i32::try_from(xml.len())
            .map_err(|_| MujocoError::InvalidInput("model text over 2 GiB".into()))?;
        // mjVFS is about 2 MB (2000 file names of 1000 bytes): keep it off the stack.
        let mut vfs: Box<MaybeUninit<mjVFS>> = Box::new_uninit();
        let vfs_ptr = vfs.as_mut_ptr();
        // SAFETY: `mj_defaultVFS` initializes the whole struct (it zeroes it).
        unsafe { api.mj_defaultVFS(vfs_ptr) };
        // SAFETY: `vfs_ptr` is an initialized VFS; the file name is NUL-terminated; the file
        // buffer MuJoCo allocates has `len` bytes, and we copy exactly `len` bytes into it.
        let result = unsafe {
            if api.mj_makeEmptyFileVFS(vfs_ptr, VFS_NAME.as_ptr(), len) != 0 {
                api.mj_deleteVFS(vfs_ptr);
                return Err(MujocoError::InvalidInput(
                    "MuJoCo could not create an in-memory file for the model".into(),
                ));
            }
            let index = api.mj_findFileVFS(vfs_ptr, VFS_NAME.as_ptr());
            let file = usize::try_from(index)
                .ok()
                .map(|i| (*vfs_ptr).filedata[i])
                .filter(|p| !p.is_null());
            match file {
                Some(buffer) => {
                    std::ptr::copy_nonoverlapping(xml.as_ptr(), buffer.cast::<u8>(), xml.len());
                    load(api, VFS_NAME, vfs_ptr, "<string>".into())
                }
                None => Err(MujocoError::InvalidInput(
                    "MuJoCo lost the in-memory file for the model".into(),
                )),
            }
        };
        // SAFETY: frees the file buffers MuJoCo allocated; the VFS is not used afterwards.
        unsafe { api.mj_deleteVFS(vfs_ptr) };
        result
    }

    /// The raw pointer, for the FFI calls of this module.
    fn ptr(&self) -> *const mjModel {
        self.raw.as_ptr()
    }

    /// The mjModel struct, for reading its fields.
    fn raw(&self) -> &mjModel {
        // SAFETY: `raw` points to a live mjModel owned by `self` that nothing writes.
        unsafe { self.raw.as_ref() }
    }

    /// Number of generalized coordinates (`qpos` length).
    pub fn nq(&self) -> usize {
        size(self.raw().nq)
    }

    /// Number of degrees of freedom (`qvel` length).
    pub fn nv(&self) -> usize {
        size(self.raw().nv)
    }

    /// Number of actuators (`ctrl` length).
    pub fn nu(&self) -> usize {
        size(self.raw().nu)
    }

    /// Number of bodies, the world body included.
    pub fn nbody(&self) -> usize {
        size(self.raw().nbody)
    }

    /// Number of joints.
    pub fn njnt(&self) -> usize {
        size(self.raw().njnt)
    }

    /// Number of sites.
    pub fn nsite(&self) -> usize {
        size(self.raw().nsite)
    }

    /// Number of sensors.
    pub fn nsensor(&self) -> usize {
        size(self.raw().nsensor)
    }

    /// Total length of the sensor data (`sensordata` length).
    pub fn nsensordata(&self) -> usize {
        size(self.raw().nsensordata)
    }

    /// Number of keyframes.
    pub fn nkey(&self) -> usize {
        size(self.raw().nkey)
    }

    /// The simulation time step in seconds (`opt.timestep`).
    pub fn timestep(&self) -> f64 {
        self.raw().opt.timestep
    }

    /// The reference configuration `qpos0` (`[nq]`), the state `mj_resetData` sets.
    pub fn qpos0(&self) -> &[f64] {
        // SAFETY: qpos0 has nq entries and the model is read-only.
        unsafe { slice(self.raw().qpos0, self.nq()) }
    }

    /// The mass of each body (`[nbody]`).
    pub fn body_mass(&self) -> &[f64] {
        // SAFETY: body_mass has nbody entries and the model is read-only.
        unsafe { slice(self.raw().body_mass, self.nbody()) }
    }

    /// The control range `[low, high]` of each actuator (`[nu]`); only meaningful where
    /// [`Model::actuator_ctrllimited`] is true.
    pub fn actuator_ctrlrange(&self) -> &[[f64; 2]] {
        // SAFETY: actuator_ctrlrange has nu*2 entries, laid out as nu pairs.
        unsafe { slice(self.raw().actuator_ctrlrange.cast::<[f64; 2]>(), self.nu()) }
    }

    /// Whether actuator `id`'s control is clamped to its control range.
    pub fn actuator_ctrllimited(&self, id: usize) -> bool {
        // SAFETY: actuator_ctrllimited has nu entries.
        unsafe { slice(self.raw().actuator_ctrllimited, self.nu()) }
            .get(id)
            .is_some_and(|&b| b != 0)
    }

    /// The address in `qpos` of joint `id`'s first coordinate.
    pub fn joint_qpos_adr(&self, id: usize) -> Option<usize> {
        // SAFETY: jnt_qposadr has njnt entries.
        unsafe { slice(self.raw().jnt_qposadr, self.njnt()) }
            .get(id)
            .map(|&a| size(a))
    }

    /// The address in `qvel` of joint `id`'s first degree of freedom.
    pub fn joint_dof_adr(&self, id: usize) -> Option<usize> {
        // SAFETY: jnt_dofadr has njnt entries.
        unsafe { slice(self.raw().jnt_dofadr, self.njnt()) }
            .get(id)
            .map(|&a| size(a))
    }

    /// The range `[address, address + dim)` of sensor `id`'s values in `sensordata`.
    pub fn sensor_range(&self, id: usize) -> Option<std::ops::Range<usize>> {
        let n = self.nsensor();
        // SAFETY: sensor_adr and sensor_dim have nsensor entries.
        let (adr, dim) = unsafe {
            (
                slice(self.raw().sensor_adr, n),
                slice(self.raw().sensor_dim, n),
            )
        };
        Some(size(*adr.get(id)?)..size(*adr.get(id)?) + size(*dim.get(id)?))
    }

    /// The `qpos` of keyframe `id` (`[nq]`).
    pub fn key_qpos(&self, id: usize) -> Option<&[f64]> {
        let nq = self.nq();
        // SAFETY: key_qpos has nkey*nq entries.
        let all = unsafe { slice(self.raw().key_qpos, self.nkey() * nq) };
        all.get(id * nq..(id + 1) * nq)
    }

    /// Body frame positions relative to the parent body (`[nbody][3]`).
    pub fn body_pos(&self) -> &[[f64; 3]] {
        // SAFETY: body_pos has nbody*3 entries.
        unsafe { slice(self.raw().body_pos.cast::<[f64; 3]>(), self.nbody()) }
    }

    /// Body frame orientations relative to the parent body, as unit quaternions `(w, x, y, z)`
    /// (`[nbody][4]`).
    pub fn body_quat(&self) -> &[[f64; 4]] {
        // SAFETY: body_quat has nbody*4 entries.
        unsafe { slice(self.raw().body_quat.cast::<[f64; 4]>(), self.nbody()) }
    }

    /// Places body `id` at `pos` with orientation `quat` (a unit quaternion `(w, x, y, z)`)
    /// relative to its parent: what editing the MJCF's `pos` and `quat` and compiling again
    /// would give, without compiling. Takes effect at the next `mj_forward`/`mj_step` of the
    /// model's data. Returns `false` (and changes nothing) if `id` is out of range.
    ///
    /// Only a model nothing else shares can be edited: see [`Data::model_mut`].
    pub fn set_body_pose(&mut self, id: usize, pos: [f64; 3], quat: [f64; 4]) -> bool {
        if id >= self.nbody() {
            return false;
        }
        // SAFETY: body_pos (nbody*3) and body_quat (nbody*4) are arrays of this model, `id` is
        // in range, and `&mut self` guarantees nothing reads the model meanwhile.
        unsafe {
            let raw = self.raw.as_mut();
            slice_mut(raw.body_pos.cast::<[f64; 3]>(), size(raw.nbody))[id] = pos;
            slice_mut(raw.body_quat.cast::<[f64; 4]>(), size(raw.nbody))[id] = quat;
        }
        true
    }

    /// The id of the object of `kind` named `name` (`mj_name2id`).
    pub fn id(&self, kind: ObjKind, name: &str) -> Result<usize, MujocoError> {
        let unknown = || MujocoError::UnknownName {
            kind: kind.label(),
            name: name.to_owned(),
        };
        let c_name = CString::new(name).map_err(|_| unknown())?;
        // SAFETY: a live model, a valid mjtObj and a NUL-terminated name.
        let id = unsafe {
            self.api
                .mj_name2id(self.ptr(), kind.raw() as i32, c_name.as_ptr())
        };
        usize::try_from(id).map_err(|_| unknown())
    }
}

/// Serializes calls of `mj_loadXML`.
static LOAD_LOCK: Mutex<()> = Mutex::new(());

/// Runs `mj_loadXML` and wraps the result.
///
/// # Safety
/// `vfs` is null or an initialized VFS.
unsafe fn load(
    api: &'static MujocoApi,
    file: &CStr,
    vfs: *const mjVFS,
    source_name: String,
) -> Result<Model, MujocoError> {
    let mut error = [0 as c_char; ERROR_LEN];
    // MuJoCo 2.2 does not document its XML loader as thread-safe: one load at a time.
    let _guard = LOAD_LOCK
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    // SAFETY: a NUL-terminated file name, a valid or null VFS, and an error buffer of the size passed.
    let raw = unsafe { api.mj_loadXML(file.as_ptr(), vfs, error.as_mut_ptr(), ERROR_LEN as i32) };
    match NonNull::new(raw) {
        Some(raw) => Ok(Model { raw, api }),
        None => {
            // SAFETY: MuJoCo writes a NUL-terminated message into the buffer (zeroed beforehand).
            let message = unsafe { CStr::from_ptr(error.as_ptr()) }
                .to_string_lossy()
                .trim()
                .to_owned();
            let message = if message.is_empty() {
                "unknown error".to_owned()
            } else {
                message
            };
            Err(MujocoError::Model {
                source_name,
                message,
            })
        }
    }
}

impl Drop for Model {
    fn drop(&mut self) {
        // SAFETY: the model was allocated by mj_loadXML, and every Data holds an Arc to it,
        // so no Data outlives it.
        unsafe { self.api.mj_deleteModel(self.raw.as_ptr()) }
    }
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

/// The simulation state of a [`Model`] (`mjData`); holds an `Arc` of its model, so the
/// model outlives it. See the module doc on threads.
pub struct Data {
    raw: NonNull<mjData>,
    model: Arc<Model>,
}

// SAFETY: see the module documentation: the mjData is owned exclusively by this value,
// MuJoCo keeps no thread-bound state for it, and writes go through `&mut self`.
unsafe impl Send for Data {}
// SAFETY: as above; `&Data` only gives read access.
unsafe impl Sync for Data {}

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
        // SAFETY: a live model.
        let raw = unsafe { model.api.mj_makeData(model.ptr()) };
        let raw = NonNull::new(raw).ok_or(MujocoError::Allocation)?;
        Ok(Data { raw, model })
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

    fn raw(&self) -> &mjData {
        // SAFETY: `raw` points to a live mjData owned by `self`.
        unsafe { self.raw.as_ref() }
    }

    /// Advances the simulation by one time step (`mj_step`).
    pub fn step(&mut self) {
        // SAFETY: a live model and its own, exclusively borrowed data.
        unsafe { self.model.api.mj_step(self.model.ptr(), self.raw.as_ptr()) }
    }

    /// Computes the derived quantities (positions, velocities, forces) of the current
    /// state without integrating (`mj_forward`).
    pub fn forward(&mut self) {
        // SAFETY: as in `step`.
        unsafe {
            self.model
                .api
                .mj_forward(self.model.ptr(), self.raw.as_ptr())
        }
    }

    /// Resets to the reference configuration, zero velocity, zero controls and zero
    /// warning counters (`mj_resetData`).
    pub fn reset(&mut self) {
        // SAFETY: as in `step`.
        unsafe {
            self.model
                .api
                .mj_resetData(self.model.ptr(), self.raw.as_ptr())
        }
    }

    /// Computes `cacc`, `cfrc_int` and `cfrc_ext` (`mj_rnePostConstraint`), which `mj_step`
    /// leaves stale unless the model has force-related sensors.
    pub fn rne_post_constraint(&mut self) {
        // SAFETY: as in `step`.
        unsafe {
            self.model
                .api
                .mj_rnePostConstraint(self.model.ptr(), self.raw.as_ptr())
        }
    }

    /// The simulation time in seconds.
    pub fn time(&self) -> f64 {
        self.raw().time
    }

    /// Generalized coordinates (`[nq]`).
    pub fn qpos(&self) -> &[f64] {
        // SAFETY: qpos has nq entries, written only through `&mut self`.
        unsafe { slice(self.raw().qpos, self.model.nq()) }
    }

    /// Generalized coordinates, writable (`[nq]`); call [`Data::forward`] after changing them
    /// to update the derived quantities.
    pub fn qpos_mut(&mut self) -> &mut [f64] {
        // SAFETY: qpos has nq entries and `self` is borrowed exclusively.
        unsafe { slice_mut(self.raw.as_ref().qpos, self.model.nq()) }
    }

    /// Generalized velocities (`[nv]`).
    pub fn qvel(&self) -> &[f64] {
        // SAFETY: qvel has nv entries.
        unsafe { slice(self.raw().qvel, self.model.nv()) }
    }

    /// Generalized velocities, writable (`[nv]`).
    pub fn qvel_mut(&mut self) -> &mut [f64] {
        // SAFETY: qvel has nv entries and `self` is borrowed exclusively.
        unsafe { slice_mut(self.raw.as_ref().qvel, self.model.nv()) }
    }

    /// `qpos` and `qvel` at once, writable (`[nq]`, `[nv]`).
    pub fn state_mut(&mut self) -> (&mut [f64], &mut [f64]) {
        let (nq, nv) = (self.model.nq(), self.model.nv());
        // SAFETY: qpos (nq entries) and qvel (nv entries) are disjoint arrays of mjData, and
        // `self` is borrowed exclusively for the lifetime of both slices.
        unsafe {
            let raw = self.raw.as_ref();
            (slice_mut(raw.qpos, nq), slice_mut(raw.qvel, nv))
        }
    }

    /// Actuator controls (`[nu]`).
    pub fn ctrl(&self) -> &[f64] {
        // SAFETY: ctrl has nu entries.
        unsafe { slice(self.raw().ctrl, self.model.nu()) }
    }

    /// Actuator controls, writable (`[nu]`).
    pub fn ctrl_mut(&mut self) -> &mut [f64] {
        // SAFETY: ctrl has nu entries and `self` is borrowed exclusively.
        unsafe { slice_mut(self.raw.as_ref().ctrl, self.model.nu()) }
    }

    /// Body frame positions in world coordinates (`[nbody][3]`).
    pub fn xpos(&self) -> &[[f64; 3]] {
        // SAFETY: xpos has nbody*3 entries.
        unsafe { slice(self.raw().xpos.cast::<[f64; 3]>(), self.model.nbody()) }
    }

    /// Body frame orientations in world coordinates, as row-major rotation matrices
    /// (`[nbody][9]`): a vector `v` in the body's frame is `R · v` in the world's.
    pub fn xmat(&self) -> &[[f64; 9]] {
        // SAFETY: xmat has nbody*9 entries.
        unsafe { slice(self.raw().xmat.cast::<[f64; 9]>(), self.model.nbody()) }
    }

    /// External forces and torques applied to each body's centre of mass in world
    /// coordinates, force first (`[nbody][6]`), writable; MuJoCo keeps them until changed.
    pub fn xfrc_applied_mut(&mut self) -> &mut [[f64; 6]] {
        // SAFETY: xfrc_applied has nbody*6 entries and `self` is borrowed exclusively.
        unsafe {
            slice_mut(
                self.raw.as_ref().xfrc_applied.cast::<[f64; 6]>(),
                self.model.nbody(),
            )
        }
    }

    /// Body centre-of-mass positions in world coordinates (`[nbody][3]`).
    pub fn xipos(&self) -> &[[f64; 3]] {
        // SAFETY: xipos has nbody*3 entries.
        unsafe { slice(self.raw().xipos.cast::<[f64; 3]>(), self.model.nbody()) }
    }

    /// Site positions in world coordinates (`[nsite][3]`).
    pub fn site_xpos(&self) -> &[[f64; 3]] {
        // SAFETY: site_xpos has nsite*3 entries.
        unsafe { slice(self.raw().site_xpos.cast::<[f64; 3]>(), self.model.nsite()) }
    }

    /// Body inertias in the centre-of-mass frame (`[nbody][10]`).
    pub fn cinert(&self) -> &[[f64; 10]] {
        // SAFETY: cinert has nbody*10 entries.
        unsafe { slice(self.raw().cinert.cast::<[f64; 10]>(), self.model.nbody()) }
    }

    /// Body velocities in the centre-of-mass frame, rotation first (`[nbody][6]`).
    pub fn cvel(&self) -> &[[f64; 6]] {
        // SAFETY: cvel has nbody*6 entries.
        unsafe { slice(self.raw().cvel.cast::<[f64; 6]>(), self.model.nbody()) }
    }

    /// External (contact) forces on each body in the centre-of-mass frame, torque first
    /// (`[nbody][6]`); up to date only after [`Data::rne_post_constraint`].
    pub fn cfrc_ext(&self) -> &[[f64; 6]] {
        // SAFETY: cfrc_ext has nbody*6 entries.
        unsafe { slice(self.raw().cfrc_ext.cast::<[f64; 6]>(), self.model.nbody()) }
    }

    /// Actuator forces in generalized coordinates (`[nv]`).
    pub fn qfrc_actuator(&self) -> &[f64] {
        // SAFETY: qfrc_actuator has nv entries.
        unsafe { slice(self.raw().qfrc_actuator, self.model.nv()) }
    }

    /// Constraint forces in generalized coordinates (`[nv]`).
    pub fn qfrc_constraint(&self) -> &[f64] {
        // SAFETY: qfrc_constraint has nv entries.
        unsafe { slice(self.raw().qfrc_constraint, self.model.nv()) }
    }

    /// All sensor values (`[nsensordata]`); see [`Model::sensor_range`] for one sensor's part.
    pub fn sensordata(&self) -> &[f64] {
        // SAFETY: sensordata has nsensordata entries.
        unsafe { slice(self.raw().sensordata, self.model.nsensordata()) }
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
        size(self.raw().ncon)
    }

    /// The force of contact `i` (`0..ncon`), in the contact frame.
    pub fn contact_force(&self, i: usize) -> Option<ContactForce> {
        let index = i32::try_from(i).ok().filter(|_| i < self.ncon())?;
        // SAFETY: `contact` has at least ncon entries.
        let contact = unsafe { self.raw().contact.add(i).read() };
        let mut force = [0.0; 6];
        // SAFETY: a live model and data, a contact index in range, and a 6-element buffer.
        unsafe {
            self.model.api.mj_contactForce(
                self.model.ptr(),
                self.raw.as_ptr(),
                index,
                force.as_mut_ptr(),
            )
        };
        Some(ContactForce {
            geom1: size(contact.geom1),
            geom2: size(contact.geom2),
            pos: contact.pos,
            force,
        })
    }

    /// How many times `warning` fired since the last reset.
    pub fn warning_count(&self, warning: Warning) -> u64 {
        u64::try_from(self.raw().warning[warning.raw() as usize].number).unwrap_or(0)
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

impl Drop for Data {
    fn drop(&mut self) {
        // SAFETY: the data was allocated by mj_makeData and is not used afterwards.
        unsafe { self.model.api.mj_deleteData(self.raw.as_ptr()) }
    }
}
