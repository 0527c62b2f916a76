//! The MuJoCo 3.17 backend ([`Physics::Mujoco3`], cargo feature `mujoco3`): the
//! [`PhysicsModel`] and [`PhysicsData`] traits over the `mujoco-rs` 7.0.0 crate, which links
//! `libmujoco.so.3.17.0` when the binary is built.
//!
//! The safe wrappers of `mujoco-rs` do the work where they exist: [`MjModel::from_xml_string`]
//! and [`MjModel::from_xml`] load, [`MjData`] steps, resets and exposes the arrays. The raw
//! bindings (`mujoco_rs::mujoco_c`) are used for the version check, MuJoCo's error and warning
//! hooks, the renderer (`render3.rs`), and three pointer accesses the wrappers have no safe form for (`qpos` and `qvel`
//! borrowed together, and writing a body's pose into a model that a data shares).
//!
//! Differences from MuJoCo 2.2 that this module absorbs:
//! - `mjtWarning` lost `mjWARN_VGEOMFULL` (seven warnings, renumbered after `mjWARN_CNSTRFULL`):
//!   [`Warning::VisualGeomFull`] always counts 0 here.
//! - Sizes are `mjtSize` (`i64`) instead of `int`, and control flags `mjtBool` (`bool`).
//! - Controls are split from actuators (`nu` controls, `nactuator` actuators, each with
//!   `actuator_ctrladr`/`actuator_ctrlnum`); `actuator_ctrlrange` and `actuator_ctrllimited`
//!   are per control. Models whose actuators do not take exactly one control each, in order,
//!   are rejected, so actuator `i` drives `ctrl[i]` as in MuJoCo 2.2.
//! - `mjContact` gained fields (the geoms are also in `geom[2]`); only `mj_contactForce` and the
//!   `geom` and `pos` fields are used, through the wrappers' own layout.
//!
//! # Threads
//!
//! `mujoco-rs` declares `MjModel` `Send + Sync` and `MjData<M>` `Send`/`Sync` when `M` is;
//! the data here holds an `Arc<MjModel>`, so [`Mj3Model`] and [`Mj3Data`] are `Send + Sync`
//! without any `unsafe impl` of this module.

use std::ffi::c_char;
use std::io::Write;
use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

use mujoco_rs::error::MjModelError;
use mujoco_rs::mujoco_c;
use mujoco_rs::wrappers::{MjData, MjModel, MjtObjBase, MjtWarning};

use super::error::MujocoError;
use super::physics::{
    ContactForce, Dynamics, ObjKind, Physics, PhysicsData, PhysicsModel, Warning,
};

/// MuJoCo 3's object type of `kind`.
fn obj_type(kind: ObjKind) -> MjtObjBase {
    match kind {
        ObjKind::Body => MjtObjBase::mjOBJ_BODY,
        ObjKind::Joint => MjtObjBase::mjOBJ_JOINT,
        ObjKind::Geom => MjtObjBase::mjOBJ_GEOM,
        ObjKind::Site => MjtObjBase::mjOBJ_SITE,
        ObjKind::Sensor => MjtObjBase::mjOBJ_SENSOR,
        ObjKind::Actuator => MjtObjBase::mjOBJ_ACTUATOR,
        ObjKind::Key => MjtObjBase::mjOBJ_KEY,
    }
}

/// MuJoCo 3's warning type of `warning`; `None` for the visual-geom warning, which MuJoCo 3
/// removed.
fn warning_type(warning: Warning) -> Option<MjtWarning> {
    match warning {
        Warning::Inertia => Some(MjtWarning::mjWARN_INERTIA),
        Warning::ContactFull => Some(MjtWarning::mjWARN_CONTACTFULL),
        Warning::ConstraintFull => Some(MjtWarning::mjWARN_CNSTRFULL),
        Warning::VisualGeomFull => None,
        Warning::BadQpos => Some(MjtWarning::mjWARN_BADQPOS),
        Warning::BadQvel => Some(MjtWarning::mjWARN_BADQVEL),
        Warning::BadQacc => Some(MjtWarning::mjWARN_BADQACC),
        Warning::BadCtrl => Some(MjtWarning::mjWARN_BADCTRL),
    }
}

/// A MuJoCo 3 size (`mjtSize`, 64 bits) as a count; negative values (never written by MuJoCo)
/// count as 0.
fn size(n: i64) -> usize {
    usize::try_from(n).unwrap_or(0)
}

/// A MuJoCo `int` index as a count or id; negative values count as 0.
fn index(n: i32) -> usize {
    usize::try_from(n).unwrap_or(0)
}

/// Builds a mutable slice from a MuJoCo array pointer; MuJoCo leaves pointers of empty arrays
/// null.
///
/// # Safety
/// When `len > 0`, `ptr` must point to `len` initialized `T`s that live at least as long as `'a`,
/// and nothing else may access them while the slice exists.
unsafe fn slice_mut<'a, T>(ptr: *mut T, len: usize) -> &'a mut [T] {
    if len == 0 || ptr.is_null() {
        &mut []
    } else {
        // SAFETY: guaranteed by the caller.
        unsafe { std::slice::from_raw_parts_mut(ptr, len) }
    }
}

/// The outcome of the one-time set-up, shared by every later call of [`check`].
static READY: OnceLock<Result<(), MujocoError>> = OnceLock::new();

/// Checks, once per process, that the linked library is the MuJoCo version `mujoco-rs` was
/// generated for, and installs this crate's error and warning hooks in it. Every model load
/// calls it first.
pub(crate) fn check() -> Result<(), MujocoError> {
    READY.get_or_init(set_up).clone()
}

/// The body of [`check`].
fn set_up() -> Result<(), MujocoError> {
    // SAFETY: `mj_version` takes no arguments and only returns a constant.
    let raw = unsafe { mujoco_c::mj_version() };
    let expected = mujoco_c::mjVERSION_HEADER;
    if u32::try_from(raw).ok() != Some(expected) {
        return Err(MujocoError::Unavailable {
            physics: Physics::Mujoco3.name(),
            reason: format!(
                "the linked MuJoCo library reports mj_version() = {raw}, but mujoco-rs 7.0.0 \
                 was generated for {expected} (3.17.0); put libmujoco.so.3.17.0 first on the \
                 loader path (LD_LIBRARY_PATH or the binary's rpath)"
            ),
        });
    }
    // SAFETY: plain stores of function pointers with the C signature MuJoCo expects into
    // MuJoCo 3's legacy hook variables, done once, inside `OnceLock::get_or_init`, before this
    // backend makes any other MuJoCo 3 call (every model load runs `check` first). MuJoCo
    // 3.17's default log handler still calls these hooks for errors and warnings (checked in
    // the disassembly of `mju_defaultLogHandler`, and by experiment: see NOTES.md).
    unsafe {
        mujoco_c::mju_user_error = Some(on_error);
        mujoco_c::mju_user_warning = Some(on_warning);
    }
    Ok(())
}

/// MuJoCo calls this on a fatal error (for example its arena overflowing) and requires that
/// it does not return. MuJoCo 3's default handler prints, logs and exits; we print and abort,
/// since unwinding a Rust panic through C frames would be undefined behaviour.
unsafe extern "C" fn on_error(message: *const c_char) {
    let text = if message.is_null() {
        "(no message)".into()
    } else {
        // SAFETY: MuJoCo passes a NUL-terminated string.
        unsafe { std::ffi::CStr::from_ptr(message) }.to_string_lossy()
    };
    let _ = writeln!(std::io::stderr(), "MuJoCo 3 fatal error: {text}; aborting");
    std::process::abort();
}

/// Replaces MuJoCo 3's default warning output, which prints to the console and appends to
/// `MUJOCO_LOG.TXT` in the working directory. Simulator warnings are reported through
/// `mjData.warning` instead ([`super::Data::warning_count`], and `StepInfo::unstable` in the
/// environments), as with MuJoCo 2.
unsafe extern "C" fn on_warning(_message: *const c_char) {}

/// Serializes model loads: MuJoCo 3 keeps the spec of the last XML load in a global (for
/// `mj_saveLastXML`), so two loads at once would race on it.
static LOAD_LOCK: Mutex<()> = Mutex::new(());

/// Takes [`LOAD_LOCK`], whether or not a panicking thread poisoned it.
fn load_lock() -> MutexGuard<'static, ()> {
    LOAD_LOCK
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Compiles an MJCF model given as text (through MuJoCo's in-memory file system, so the model
/// may not include other files or meshes). An invalid model gives [`MujocoError::Model`] with
/// MuJoCo's own message.
pub(crate) fn load_xml_str(xml: &str) -> Result<Box<dyn PhysicsModel>, MujocoError> {
    check()?;
    let source_name = "<string>";
    let loaded = {
        let _guard = load_lock();
        // The one panic `from_xml_string` documents is a version mismatch, which `check`
        // excluded.
        MjModel::from_xml_string(xml)
    };
    let model = loaded.map_err(|err| load_error(source_name, err))?;
    Ok(Box::new(Mj3Model::new(model, source_name)?))
}

/// Loads and compiles an MJCF file. A missing file or an invalid model gives
/// [`MujocoError::Model`] with MuJoCo's own message; a path with a NUL byte, or one that is
/// not UTF-8 (which `mujoco-rs` requires), gives [`MujocoError::InvalidInput`].
pub(crate) fn load_xml_file(path: &Path) -> Result<Box<dyn PhysicsModel>, MujocoError> {
    check()?;
    let source_name = path.display().to_string();
    if path.as_os_str().as_encoded_bytes().contains(&0) {
        return Err(MujocoError::InvalidInput(format!(
            "path {source_name} contains a NUL byte"
        )));
    }
    if path.to_str().is_none() {
        return Err(MujocoError::InvalidInput(format!(
            "path {source_name} is not valid UTF-8, which MuJoCo 3 (through mujoco-rs) needs"
        )));
    }
    let loaded = {
        let _guard = load_lock();
        // The panics `from_xml` documents are a NUL byte in the path and a version mismatch,
        // both excluded above.
        MjModel::from_xml(path)
    };
    let model = loaded.map_err(|err| load_error(&source_name, err))?;
    Ok(Box::new(Mj3Model::new(model, &source_name)?))
}

/// Turns a `mujoco-rs` load error into this crate's error, keeping MuJoCo's own message.
fn load_error(source_name: &str, err: MjModelError) -> MujocoError {
    match err {
        MjModelError::LoadFailed(message) => {
            let message = message.trim();
            let message = if message.is_empty() {
                "unknown error"
            } else {
                message
            };
            MujocoError::Model {
                source_name: source_name.to_owned(),
                message: message.to_owned(),
            }
        }
        MjModelError::VfsError(vfs) => MujocoError::InvalidInput(format!(
            "MuJoCo could not create an in-memory file for the model: {vfs}"
        )),
        MjModelError::InvalidUtf8Path => {
            MujocoError::InvalidInput(format!("path {source_name} is not valid UTF-8"))
        }
        other => MujocoError::Model {
            source_name: source_name.to_owned(),
            message: other.to_string(),
        },
    }
}

/// A compiled MuJoCo 3.17 model. The `Arc` is shared with the [`Mj3Data`]s made from it.
#[derive(Debug)]
pub(crate) struct Mj3Model {
    model: Arc<MjModel>,
}

impl Mj3Model {
    /// Wraps a freshly loaded model, rejecting actuators that do not take exactly one control
    /// each, in order (MuJoCo 3's multi-input actuators), since the public API indexes controls
    /// by actuator id.
    fn new(model: MjModel, source_name: &str) -> Result<Mj3Model, MujocoError> {
        let (nu, nactuator) = (model.ffi().nu, model.ffi().nactuator);
        let in_order = model
            .actuator_ctrladr()
            .iter()
            .enumerate()
            .all(|(i, &adr)| usize::try_from(adr).ok() == Some(i));
        if nu != nactuator || !in_order {
            return Err(MujocoError::Model {
                source_name: source_name.to_owned(),
                message: format!(
                    "the model has {nactuator} actuators taking {nu} controls; apo's MuJoCo \
                     layer needs one control per actuator, in actuator order"
                ),
            });
        }
        Ok(Mj3Model {
            model: Arc::new(model),
        })
    }
}

impl PhysicsModel for Mj3Model {
    fn physics(&self) -> Physics {
        Physics::Mujoco3
    }

    fn nq(&self) -> usize {
        size(self.model.ffi().nq)
    }

    fn nv(&self) -> usize {
        size(self.model.ffi().nv)
    }

    fn nu(&self) -> usize {
        size(self.model.ffi().nu)
    }

    fn nbody(&self) -> usize {
        size(self.model.ffi().nbody)
    }

    fn njnt(&self) -> usize {
        size(self.model.ffi().njnt)
    }

    fn nsite(&self) -> usize {
        size(self.model.ffi().nsite)
    }

    fn nsensor(&self) -> usize {
        size(self.model.ffi().nsensor)
    }

    fn nsensordata(&self) -> usize {
        size(self.model.ffi().nsensordata)
    }

    fn nkey(&self) -> usize {
        size(self.model.ffi().nkey)
    }

    fn timestep(&self) -> f64 {
        self.model.opt().timestep
    }

    fn qpos0(&self) -> &[f64] {
        self.model.qpos0()
    }

    fn body_mass(&self) -> &[f64] {
        self.model.body_mass()
    }

    fn actuator_ctrlrange(&self) -> &[[f64; 2]] {
        self.model.actuator_ctrlrange()
    }

    fn actuator_ctrllimited(&self, id: usize) -> bool {
        self.model
            .actuator_ctrllimited()
            .get(id)
            .copied()
            .unwrap_or(false)
    }

    fn jnt_qposadr(&self) -> &[i32] {
        self.model.jnt_qposadr()
    }

    fn jnt_dofadr(&self) -> &[i32] {
        self.model.jnt_dofadr()
    }

    fn sensor_adr(&self) -> &[i32] {
        self.model.sensor_adr()
    }

    fn sensor_dim(&self) -> &[i32] {
        self.model.sensor_dim()
    }

    fn key_qpos(&self) -> &[f64] {
        self.model.key_qpos()
    }

    fn body_pos(&self) -> &[[f64; 3]] {
        self.model.body_pos()
    }

    fn body_quat(&self) -> &[[f64; 4]] {
        self.model.body_quat()
    }

    fn dynamics(&self) -> Dynamics {
        let m = &self.model;
        let opt = m.opt();
        let nu = self.nu();
        Dynamics {
            timestep: opt.timestep,
            gravity: opt.gravity,
            magnetic: opt.magnetic,
            integrator: opt.integrator,
            cone: opt.cone,
            impratio: opt.impratio,
            iterations: opt.iterations,
            tolerance: opt.tolerance,
            disableflags: opt.disableflags,
            enableflags: opt.enableflags,
            body_mass: m.body_mass().to_vec(),
            body_inertia: m.body_inertia().to_vec(),
            jnt_pos: m.jnt_pos().to_vec(),
            jnt_axis: m.jnt_axis().to_vec(),
            jnt_stiffness: m.jnt_stiffness().to_vec(),
            jnt_limited: m.jnt_limited().to_vec(),
            jnt_range: m.jnt_range().to_vec(),
            dof_armature: m.dof_armature().to_vec(),
            dof_damping: m.dof_damping().to_vec(),
            geom_size: m.geom_size().to_vec(),
            geom_pos: m.geom_pos().to_vec(),
            geom_friction: m.geom_friction().to_vec(),
            geom_condim: m.geom_condim().to_vec(),
            geom_margin: m.geom_margin().to_vec(),
            geom_solref: m.geom_solref().to_vec(),
            geom_solimp: m.geom_solimp().to_vec(),
            actuator_gear: m.actuator_gear().iter().take(nu).copied().collect(),
            actuator_forcelimited: m.actuator_forcelimited().iter().take(nu).copied().collect(),
            actuator_forcerange: m.actuator_forcerange().iter().take(nu).copied().collect(),
        }
    }

    fn set_body_pose(&mut self, id: usize, pos: [f64; 3], quat: [f64; 4]) -> bool {
        let nbody = self.nbody();
        if id >= nbody {
            return false;
        }
        // The `MjData` made from this model holds a second `Arc` of it, so `Arc::get_mut` (and
        // with it the safe `MjModel::body_pos_mut`) is not available: write through MuJoCo's
        // array pointers instead.
        let raw = self.model.ffi();
        let (body_pos, body_quat) = (raw.body_pos, raw.body_quat);
        // SAFETY: body_pos (nbody*3) and body_quat (nbody*4) are arrays of this model, `id` is
        // in range, and the trait's contract guarantees nothing reads the model meanwhile: the
        // `Model` is borrowed exclusively, and the one `Data` that may share this `MjModel` is
        // borrowed exclusively too. The arrays live in MuJoCo's model buffer, outside the
        // mjModel struct that `ffi()` borrows, and no slice of them is alive (every slice the
        // model hands out borrows `self`).
        unsafe {
            slice_mut(body_pos.cast::<[f64; 3]>(), nbody)[id] = pos;
            slice_mut(body_quat.cast::<[f64; 4]>(), nbody)[id] = quat;
        }
        true
    }

    fn name_to_id(&self, kind: ObjKind, name: &str) -> Option<usize> {
        // `MjModel::name_to_id` panics on a NUL byte; the caller excludes it, and so do we.
        if name.contains('\0') {
            return None;
        }
        self.model.name_to_id(obj_type(kind), name)
    }

    fn make_data(&self) -> Result<Box<dyn PhysicsData>, MujocoError> {
        let data = MjData::try_new(Arc::clone(&self.model)).map_err(|_| MujocoError::Allocation)?;
        Ok(Box::new(Mj3Data { data }))
    }
}

/// The simulation state of an [`Mj3Model`]: `mujoco-rs`'s `MjData`, which holds an `Arc` of the
/// model, so the model outlives it.
pub(crate) struct Mj3Data {
    data: MjData<Arc<MjModel>>,
}

impl PhysicsData for Mj3Data {
    fn step(&mut self) {
        self.data.step();
    }

    fn mj3_raw(&mut self) -> Option<(*const mujoco_c::mjModel, *mut mujoco_c::mjData)> {
        let model: *const mujoco_c::mjModel = self.data.model().ffi();
        // SAFETY: the pointer is only handed to MuJoCo's renderer, which reads the state and
        // writes the data's visualization buffers, while `self` is exclusively borrowed.
        let data: *mut mujoco_c::mjData = unsafe { self.data.ffi_mut() };
        Some((model, data))
    }

    fn forward(&mut self) {
        self.data.forward();
    }

    fn reset(&mut self) {
        self.data.reset();
    }

    fn rne_post_constraint(&mut self) {
        self.data.rne_post_constraint();
    }

    fn time(&self) -> f64 {
        self.data.time()
    }

    fn qpos(&self) -> &[f64] {
        self.data.qpos()
    }

    fn qpos_mut(&mut self) -> &mut [f64] {
        self.data.qpos_mut()
    }

    fn qvel(&self) -> &[f64] {
        self.data.qvel()
    }

    fn qvel_mut(&mut self) -> &mut [f64] {
        self.data.qvel_mut()
    }

    fn state_mut(&mut self) -> (&mut [f64], &mut [f64]) {
        let (nq, nv) = (
            size(self.data.model().ffi().nq),
            size(self.data.model().ffi().nv),
        );
        let (qpos, qvel) = (self.data.ffi().qpos, self.data.ffi().qvel);
        // SAFETY: qpos (nq entries) and qvel (nv entries) are disjoint arrays in MuJoCo's data
        // buffer (outside the mjData struct that `ffi()` borrowed), and `self` is borrowed
        // exclusively for the lifetime of both slices.
        unsafe { (slice_mut(qpos, nq), slice_mut(qvel, nv)) }
    }

    fn ctrl(&self) -> &[f64] {
        self.data.ctrl()
    }

    fn ctrl_mut(&mut self) -> &mut [f64] {
        self.data.ctrl_mut()
    }

    fn xpos(&self) -> &[[f64; 3]] {
        self.data.xpos()
    }

    fn xmat(&self) -> &[[f64; 9]] {
        self.data.xmat()
    }

    fn xfrc_applied_mut(&mut self) -> &mut [[f64; 6]] {
        self.data.xfrc_applied_mut()
    }

    fn xipos(&self) -> &[[f64; 3]] {
        self.data.xipos()
    }

    fn site_xpos(&self) -> &[[f64; 3]] {
        self.data.site_xpos()
    }

    fn cinert(&self) -> &[[f64; 10]] {
        self.data.cinert()
    }

    fn cvel(&self) -> &[[f64; 6]] {
        self.data.cvel()
    }

    fn cfrc_ext(&self) -> &[[f64; 6]] {
        self.data.cfrc_ext()
    }

    fn qfrc_actuator(&self) -> &[f64] {
        self.data.qfrc_actuator()
    }

    fn qfrc_constraint(&self) -> &[f64] {
        self.data.qfrc_constraint()
    }

    fn sensordata(&self) -> &[f64] {
        self.data.sensordata()
    }

    fn ncon(&self) -> usize {
        index(self.data.ncon())
    }

    fn contact_force(&self, i: usize) -> Option<ContactForce> {
        let contact = self.data.contact().get(i)?;
        let force = self.data.try_contact_force(i).ok()?;
        Some(ContactForce {
            geom1: index(contact.geom[0]),
            geom2: index(contact.geom[1]),
            pos: contact.pos,
            force,
        })
    }

    fn warning_count(&self, warning: Warning) -> u64 {
        warning_type(warning)
            .and_then(|kind| self.data.warning().get(kind as usize))
            .map_or(0, |stat| u64::try_from(stat.number).unwrap_or(0))
    }
}
