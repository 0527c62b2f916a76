//! The MuJoCo 2.2.2 backend ([`Physics::Mujoco2`]): Debian's `libmujoco-dev`, opened at run
//! time by [`super::library`], behind the [`PhysicsModel`] and [`PhysicsData`] traits.
//!
//! # Threads
//!
//! - [`Mj2Model`] is `Send + Sync`. After loading, the `mjModel` is only written by
//!   [`PhysicsModel::set_body_pose`], which runs while nothing else can reach the model (see
//!   its contract); MuJoCo's simulation functions take the model as `const mjModel*`. So one
//!   model is shared read-only between environments on several threads.
//! - [`Mj2Data`] is `Send + Sync`. It owns its `mjData` (MuJoCo keeps no hidden pointer to
//!   it, and the library keeps no per-thread state), so it can move to another thread; every
//!   method that writes takes `&mut self`, so shared references only read.

use std::ffi::{c_char, CStr, CString};
use std::mem::MaybeUninit;
use std::path::Path;
use std::ptr::NonNull;
use std::sync::{Arc, Mutex};

use super::error::MujocoError;
use super::ffi::{mjData, mjModel, mjVFS, mjtObj, mjtWarning, MujocoApi};
use super::library::api;
use super::physics::{
    ContactForce, Dynamics, ObjKind, Physics, PhysicsData, PhysicsModel, Warning,
};

/// MuJoCo 2.2's object type of `kind`.
fn obj_type(kind: ObjKind) -> mjtObj {
    match kind {
        ObjKind::Body => mjtObj::mjOBJ_BODY,
        ObjKind::Joint => mjtObj::mjOBJ_JOINT,
        ObjKind::Geom => mjtObj::mjOBJ_GEOM,
        ObjKind::Site => mjtObj::mjOBJ_SITE,
        ObjKind::Sensor => mjtObj::mjOBJ_SENSOR,
        ObjKind::Actuator => mjtObj::mjOBJ_ACTUATOR,
        ObjKind::Key => mjtObj::mjOBJ_KEY,
    }
}

/// MuJoCo 2.2's warning type of `warning` (2.2 has all eight).
fn warning_type(warning: Warning) -> mjtWarning {
    match warning {
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

/// An `mjModel` from `mj_loadXML`, freed when the last of its holders (the [`Mj2Model`] and
/// the [`Mj2Data`]s made from it) is dropped.
struct RawModel {
    ptr: NonNull<mjModel>,
    api: &'static MujocoApi,
}

// SAFETY: see the module documentation: MuJoCo only reads the mjModel (through
// `const mjModel*`), and the one writer, `set_body_pose`, runs while no other holder can reach
// it, so moving it or sharing references between threads cannot race.
unsafe impl Send for RawModel {}
// SAFETY: as above.
unsafe impl Sync for RawModel {}

impl RawModel {
    /// The raw pointer, for the FFI calls of this module.
    fn ptr(&self) -> *const mjModel {
        self.ptr.as_ptr()
    }

    /// The mjModel struct, for reading its fields.
    fn get(&self) -> &mjModel {
        // SAFETY: `ptr` points to a live mjModel owned by `self`, written only under the
        // contract of `set_body_pose`, which excludes readers.
        unsafe { self.ptr.as_ref() }
    }
}

impl Drop for RawModel {
    fn drop(&mut self) {
        // SAFETY: the model was allocated by mj_loadXML, and every Mj2Data holds an Arc of this
        // value, so no data outlives it.
        unsafe { self.api.mj_deleteModel(self.ptr.as_ptr()) }
    }
}

/// A compiled MuJoCo 2.2.2 model.
pub(crate) struct Mj2Model {
    raw: Arc<RawModel>,
}

impl std::fmt::Debug for Mj2Model {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mj2Model")
            .field("mjModel", &self.raw.ptr)
            .finish()
    }
}

/// Loads and compiles an MJCF file. A missing file or an invalid model gives
/// [`MujocoError::Model`] with MuJoCo's own message.
pub(crate) fn load_xml_file(path: &Path) -> Result<Box<dyn PhysicsModel>, MujocoError> {
    let api = api()?;
    let source_name = path.display().to_string();
    let c_path = CString::new(path.as_os_str().as_encoded_bytes()).map_err(|_| {
        MujocoError::InvalidInput(format!("path {source_name} contains a NUL byte"))
    })?;
    // SAFETY: a NUL-terminated path and no VFS.
    let model = unsafe { load(api, &c_path, std::ptr::null(), source_name) }?;
    Ok(Box::new(model))
}

/// Compiles an MJCF model given as text (through MuJoCo's in-memory file system, so the model
/// may not include other files or meshes). An invalid model gives [`MujocoError::Model`] with
/// MuJoCo's own message.
pub(crate) fn load_xml_str(xml: &str) -> Result<Box<dyn PhysicsModel>, MujocoError> {
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
    let model = result?;
    Ok(Box::new(model))
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
) -> Result<Mj2Model, MujocoError> {
    let mut error = [0 as c_char; ERROR_LEN];
    // MuJoCo 2.2 does not document its XML loader as thread-safe: one load at a time.
    let _guard = LOAD_LOCK
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    // SAFETY: a NUL-terminated file name, a valid or null VFS, and an error buffer of the size passed.
    let raw = unsafe { api.mj_loadXML(file.as_ptr(), vfs, error.as_mut_ptr(), ERROR_LEN as i32) };
    match NonNull::new(raw) {
        Some(ptr) => Ok(Mj2Model {
            raw: Arc::new(RawModel { ptr, api }),
        }),
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

impl Mj2Model {
    /// The mjModel struct, for reading its fields.
    fn raw(&self) -> &mjModel {
        self.raw.get()
    }
}

impl PhysicsModel for Mj2Model {
    fn physics(&self) -> Physics {
        Physics::Mujoco2
    }

    fn nq(&self) -> usize {
        size(self.raw().nq)
    }

    fn nv(&self) -> usize {
        size(self.raw().nv)
    }

    fn nu(&self) -> usize {
        size(self.raw().nu)
    }

    fn nbody(&self) -> usize {
        size(self.raw().nbody)
    }

    fn njnt(&self) -> usize {
        size(self.raw().njnt)
    }

    fn nsite(&self) -> usize {
        size(self.raw().nsite)
    }

    fn nsensor(&self) -> usize {
        size(self.raw().nsensor)
    }

    fn nsensordata(&self) -> usize {
        size(self.raw().nsensordata)
    }

    fn nkey(&self) -> usize {
        size(self.raw().nkey)
    }

    fn timestep(&self) -> f64 {
        self.raw().opt.timestep
    }

    fn qpos0(&self) -> &[f64] {
        // SAFETY: qpos0 has nq entries and the model is read-only.
        unsafe { slice(self.raw().qpos0, self.nq()) }
    }

    fn body_mass(&self) -> &[f64] {
        // SAFETY: body_mass has nbody entries and the model is read-only.
        unsafe { slice(self.raw().body_mass, self.nbody()) }
    }

    fn actuator_ctrlrange(&self) -> &[[f64; 2]] {
        // SAFETY: actuator_ctrlrange has nu*2 entries, laid out as nu pairs.
        unsafe { slice(self.raw().actuator_ctrlrange.cast::<[f64; 2]>(), self.nu()) }
    }

    fn actuator_ctrllimited(&self, id: usize) -> bool {
        // SAFETY: actuator_ctrllimited has nu entries.
        unsafe { slice(self.raw().actuator_ctrllimited, self.nu()) }
            .get(id)
            .is_some_and(|&b| b != 0)
    }

    fn jnt_qposadr(&self) -> &[i32] {
        // SAFETY: jnt_qposadr has njnt entries.
        unsafe { slice(self.raw().jnt_qposadr, self.njnt()) }
    }

    fn jnt_dofadr(&self) -> &[i32] {
        // SAFETY: jnt_dofadr has njnt entries.
        unsafe { slice(self.raw().jnt_dofadr, self.njnt()) }
    }

    fn sensor_adr(&self) -> &[i32] {
        // SAFETY: sensor_adr has nsensor entries.
        unsafe { slice(self.raw().sensor_adr, self.nsensor()) }
    }

    fn sensor_dim(&self) -> &[i32] {
        // SAFETY: sensor_dim has nsensor entries.
        unsafe { slice(self.raw().sensor_dim, self.nsensor()) }
    }

    fn key_qpos(&self) -> &[f64] {
        // SAFETY: key_qpos has nkey*nq entries.
        unsafe { slice(self.raw().key_qpos, self.nkey() * self.nq()) }
    }

    fn body_pos(&self) -> &[[f64; 3]] {
        // SAFETY: body_pos has nbody*3 entries.
        unsafe { slice(self.raw().body_pos.cast::<[f64; 3]>(), self.nbody()) }
    }

    fn body_quat(&self) -> &[[f64; 4]] {
        // SAFETY: body_quat has nbody*4 entries.
        unsafe { slice(self.raw().body_quat.cast::<[f64; 4]>(), self.nbody()) }
    }

    fn dynamics(&self) -> Dynamics {
        let m = self.raw();
        let (nbody, njnt, nv, nu) = (self.nbody(), self.njnt(), self.nv(), self.nu());
        let ngeom = size(m.ngeom);
        // SAFETY: each array has the documented number of entries (MuJoCo's mjmodel.h), laid
        // out object after object, and the model is read-only here.
        unsafe {
            Dynamics {
                timestep: m.opt.timestep,
                gravity: m.opt.gravity,
                magnetic: m.opt.magnetic,
                integrator: m.opt.integrator,
                cone: m.opt.cone,
                impratio: m.opt.impratio,
                iterations: m.opt.iterations,
                tolerance: m.opt.tolerance,
                disableflags: m.opt.disableflags,
                enableflags: m.opt.enableflags,
                body_mass: slice(m.body_mass, nbody).to_vec(),
                body_inertia: slice(m.body_inertia.cast::<[f64; 3]>(), nbody).to_vec(),
                jnt_pos: slice(m.jnt_pos.cast::<[f64; 3]>(), njnt).to_vec(),
                jnt_axis: slice(m.jnt_axis.cast::<[f64; 3]>(), njnt).to_vec(),
                jnt_stiffness: slice(m.jnt_stiffness, njnt).to_vec(),
                jnt_limited: slice(m.jnt_limited, njnt).iter().map(|&b| b != 0).collect(),
                jnt_range: slice(m.jnt_range.cast::<[f64; 2]>(), njnt).to_vec(),
                dof_armature: slice(m.dof_armature, nv).to_vec(),
                dof_damping: slice(m.dof_damping, nv).to_vec(),
                geom_size: slice(m.geom_size.cast::<[f64; 3]>(), ngeom).to_vec(),
                geom_pos: slice(m.geom_pos.cast::<[f64; 3]>(), ngeom).to_vec(),
                geom_friction: slice(m.geom_friction.cast::<[f64; 3]>(), ngeom).to_vec(),
                geom_condim: slice(m.geom_condim, ngeom).to_vec(),
                geom_margin: slice(m.geom_margin, ngeom).to_vec(),
                geom_solref: slice(m.geom_solref.cast::<[f64; 2]>(), ngeom).to_vec(),
                geom_solimp: slice(m.geom_solimp.cast::<[f64; 5]>(), ngeom).to_vec(),
                actuator_gear: slice(m.actuator_gear.cast::<[f64; 6]>(), nu).to_vec(),
                actuator_forcelimited: slice(m.actuator_forcelimited, nu)
                    .iter()
                    .map(|&b| b != 0)
                    .collect(),
                actuator_forcerange: slice(m.actuator_forcerange.cast::<[f64; 2]>(), nu).to_vec(),
            }
        }
    }

    fn set_body_pose(&mut self, id: usize, pos: [f64; 3], quat: [f64; 4]) -> bool {
        let nbody = self.nbody();
        if id >= nbody {
            return false;
        }
        let (body_pos, body_quat) = (self.raw().body_pos, self.raw().body_quat);
        // SAFETY: body_pos (nbody*3) and body_quat (nbody*4) are arrays of this model, `id` is
        // in range, and the trait's contract guarantees nothing reads the model meanwhile: the
        // `Model` is borrowed exclusively, and the one `Data` that may share this mjModel is
        // borrowed exclusively too. The arrays live in MuJoCo's model buffer, outside the
        // mjModel struct that `raw()` borrows.
        unsafe {
            slice_mut(body_pos.cast::<[f64; 3]>(), nbody)[id] = pos;
            slice_mut(body_quat.cast::<[f64; 4]>(), nbody)[id] = quat;
        }
        true
    }

    fn name_to_id(&self, kind: ObjKind, name: &str) -> Option<usize> {
        let c_name = CString::new(name).ok()?;
        // SAFETY: a live model, a valid mjtObj and a NUL-terminated name.
        let id = unsafe {
            self.raw
                .api
                .mj_name2id(self.raw.ptr(), obj_type(kind) as i32, c_name.as_ptr())
        };
        usize::try_from(id).ok()
    }

    fn make_data(&self) -> Result<Box<dyn PhysicsData>, MujocoError> {
        // SAFETY: a live model.
        let raw = unsafe { self.raw.api.mj_makeData(self.raw.ptr()) };
        let ptr = NonNull::new(raw).ok_or(MujocoError::Allocation)?;
        Ok(Box::new(Mj2Data {
            ptr,
            model: Arc::clone(&self.raw),
        }))
    }
}

/// The simulation state (`mjData`) of an [`Mj2Model`]; holds an `Arc` of the model's memory,
/// so the model outlives it.
pub(crate) struct Mj2Data {
    ptr: NonNull<mjData>,
    model: Arc<RawModel>,
}

// SAFETY: see the module documentation: the mjData is owned exclusively by this value,
// MuJoCo keeps no thread-bound state for it, and writes go through `&mut self`.
unsafe impl Send for Mj2Data {}
// SAFETY: as above; `&Mj2Data` only gives read access.
unsafe impl Sync for Mj2Data {}

impl Mj2Data {
    /// The mjData struct, for reading its fields.
    fn raw(&self) -> &mjData {
        // SAFETY: `ptr` points to a live mjData owned by `self`.
        unsafe { self.ptr.as_ref() }
    }

    /// The model's mjModel struct, for its sizes.
    fn m(&self) -> &mjModel {
        self.model.get()
    }
}

impl PhysicsData for Mj2Data {
    fn step(&mut self) {
        // SAFETY: a live model and its own, exclusively borrowed data.
        unsafe { self.model.api.mj_step(self.model.ptr(), self.ptr.as_ptr()) }
    }

    fn forward(&mut self) {
        // SAFETY: as in `step`.
        unsafe {
            self.model
                .api
                .mj_forward(self.model.ptr(), self.ptr.as_ptr())
        }
    }

    fn reset(&mut self) {
        // SAFETY: as in `step`.
        unsafe {
            self.model
                .api
                .mj_resetData(self.model.ptr(), self.ptr.as_ptr())
        }
    }

    fn rne_post_constraint(&mut self) {
        // SAFETY: as in `step`.
        unsafe {
            self.model
                .api
                .mj_rnePostConstraint(self.model.ptr(), self.ptr.as_ptr())
        }
    }

    fn time(&self) -> f64 {
        self.raw().time
    }

    fn qpos(&self) -> &[f64] {
        // SAFETY: qpos has nq entries, written only through `&mut self`.
        unsafe { slice(self.raw().qpos, size(self.m().nq)) }
    }

    fn qpos_mut(&mut self) -> &mut [f64] {
        // SAFETY: qpos has nq entries and `self` is borrowed exclusively.
        unsafe { slice_mut(self.raw().qpos, size(self.m().nq)) }
    }

    fn qvel(&self) -> &[f64] {
        // SAFETY: qvel has nv entries.
        unsafe { slice(self.raw().qvel, size(self.m().nv)) }
    }

    fn qvel_mut(&mut self) -> &mut [f64] {
        // SAFETY: qvel has nv entries and `self` is borrowed exclusively.
        unsafe { slice_mut(self.raw().qvel, size(self.m().nv)) }
    }

    fn state_mut(&mut self) -> (&mut [f64], &mut [f64]) {
        let (nq, nv) = (size(self.m().nq), size(self.m().nv));
        let (qpos, qvel) = (self.raw().qpos, self.raw().qvel);
        // SAFETY: qpos (nq entries) and qvel (nv entries) are disjoint arrays of mjData, and
        // `self` is borrowed exclusively for the lifetime of both slices.
        unsafe { (slice_mut(qpos, nq), slice_mut(qvel, nv)) }
    }

    fn ctrl(&self) -> &[f64] {
        // SAFETY: ctrl has nu entries.
        unsafe { slice(self.raw().ctrl, size(self.m().nu)) }
    }

    fn ctrl_mut(&mut self) -> &mut [f64] {
        // SAFETY: ctrl has nu entries and `self` is borrowed exclusively.
        unsafe { slice_mut(self.raw().ctrl, size(self.m().nu)) }
    }

    fn xpos(&self) -> &[[f64; 3]] {
        // SAFETY: xpos has nbody*3 entries.
        unsafe { slice(self.raw().xpos.cast::<[f64; 3]>(), size(self.m().nbody)) }
    }

    fn xmat(&self) -> &[[f64; 9]] {
        // SAFETY: xmat has nbody*9 entries.
        unsafe { slice(self.raw().xmat.cast::<[f64; 9]>(), size(self.m().nbody)) }
    }

    fn xfrc_applied_mut(&mut self) -> &mut [[f64; 6]] {
        // SAFETY: xfrc_applied has nbody*6 entries and `self` is borrowed exclusively.
        unsafe {
            slice_mut(
                self.raw().xfrc_applied.cast::<[f64; 6]>(),
                size(self.m().nbody),
            )
        }
    }

    fn xipos(&self) -> &[[f64; 3]] {
        // SAFETY: xipos has nbody*3 entries.
        unsafe { slice(self.raw().xipos.cast::<[f64; 3]>(), size(self.m().nbody)) }
    }

    fn site_xpos(&self) -> &[[f64; 3]] {
        // SAFETY: site_xpos has nsite*3 entries.
        unsafe {
            slice(
                self.raw().site_xpos.cast::<[f64; 3]>(),
                size(self.m().nsite),
            )
        }
    }

    fn cinert(&self) -> &[[f64; 10]] {
        // SAFETY: cinert has nbody*10 entries.
        unsafe { slice(self.raw().cinert.cast::<[f64; 10]>(), size(self.m().nbody)) }
    }

    fn cvel(&self) -> &[[f64; 6]] {
        // SAFETY: cvel has nbody*6 entries.
        unsafe { slice(self.raw().cvel.cast::<[f64; 6]>(), size(self.m().nbody)) }
    }

    fn cfrc_ext(&self) -> &[[f64; 6]] {
        // SAFETY: cfrc_ext has nbody*6 entries.
        unsafe { slice(self.raw().cfrc_ext.cast::<[f64; 6]>(), size(self.m().nbody)) }
    }

    fn qfrc_actuator(&self) -> &[f64] {
        // SAFETY: qfrc_actuator has nv entries.
        unsafe { slice(self.raw().qfrc_actuator, size(self.m().nv)) }
    }

    fn qfrc_constraint(&self) -> &[f64] {
        // SAFETY: qfrc_constraint has nv entries.
        unsafe { slice(self.raw().qfrc_constraint, size(self.m().nv)) }
    }

    fn sensordata(&self) -> &[f64] {
        // SAFETY: sensordata has nsensordata entries.
        unsafe { slice(self.raw().sensordata, size(self.m().nsensordata)) }
    }

    fn ncon(&self) -> usize {
        size(self.raw().ncon)
    }

    fn contact_force(&self, i: usize) -> Option<ContactForce> {
        let index = i32::try_from(i).ok().filter(|_| i < self.ncon())?;
        // SAFETY: `contact` has at least ncon entries.
        let contact = unsafe { self.raw().contact.add(i).read() };
        let mut force = [0.0; 6];
        // SAFETY: a live model and data, a contact index in range, and a 6-element buffer.
        unsafe {
            self.model.api.mj_contactForce(
                self.model.ptr(),
                self.ptr.as_ptr(),
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

    fn warning_count(&self, warning: Warning) -> u64 {
        u64::try_from(self.raw().warning[warning_type(warning) as usize].number).unwrap_or(0)
    }

    fn mj2_raw(&mut self) -> Option<(*const mjModel, *mut mjData)> {
        Some((self.model.ptr(), self.ptr.as_ptr()))
    }
}

impl Drop for Mj2Data {
    fn drop(&mut self) {
        // SAFETY: the data was allocated by mj_makeData and is not used afterwards; the model
        // it was made for is still alive (this value holds an Arc of it).
        unsafe { self.model.api.mj_deleteData(self.ptr.as_ptr()) }
    }
}
