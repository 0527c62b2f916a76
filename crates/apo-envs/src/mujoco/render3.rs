//! MuJoCo 3.17's renderer for the `mujoco3` physics (cargo feature `mujoco3`): the scene of
//! [`super::scene`] — the tracking camera, the floor grid, the tasks' decor — drawn by the
//! renderer of the library the physics runs on (`mjv_updateScene`, `mjr_render`,
//! `mjr_readPixels`), on the same headless OpenGL context ([`super::gl`]).
//!
//! Unlike MuJoCo 2.2.2's, these structs are not opaque: `mujoco-rs` generated them from the
//! 3.17 headers, so their fields are written by name.

use std::ffi::{c_int, CStr};

use mujoco_rs::mujoco_c as c;

use super::gl::GlContext;
use super::scene::{
    camera_id, copy_flipped, grid, Decor, TrackView, CAMERA_FIXED, CAMERA_TRACKING, CATEGORY_ALL,
    FONT_SCALE, FRAMEBUFFER_WINDOW, MAX_GEOMS,
};
use crate::render::{Camera, Frame, RenderError};

/// `mjOBJ_CAMERA`.
const OBJ_CAMERA: c_int = 7;

/// MuJoCo 3.17's renderer of one environment.
pub(crate) struct Mj3Renderer {
    gl: GlContext,
    model: *const c::mjModel,
    scene: Box<c::mjvScene>,
    option: Box<c::mjvOption>,
    perturb: Box<c::mjvPerturb>,
    camera: Box<c::mjvCamera>,
    context: Box<c::mjrContext>,
    /// Pixels as MuJoCo reads them (rows from the bottom).
    pixels: Vec<u8>,
}

// SAFETY: as `Mj2Renderer`: the renderer owns its context and MuJoCo structs and is used
// through `&mut self` only, on one thread at a time; `model` points to the model of the
// environment that owns the renderer, which outlives it, and is only read.
unsafe impl Send for Mj3Renderer {}

impl std::fmt::Debug for Mj3Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mj3Renderer")
            .field("size", &self.gl.size())
            .finish_non_exhaustive()
    }
}

/// A zeroed MuJoCo struct on the heap, for the `mjv_default*`/`mjr_default*` functions to
/// fill.
///
/// # Safety
/// `T` must be a C struct for which all-zero bytes are a valid value (numbers and pointers).
unsafe fn zeroed<T>() -> Box<T> {
    // SAFETY: guaranteed by the caller.
    Box::new(unsafe { std::mem::zeroed() })
}

impl Mj3Renderer {
    fn new(model: *const c::mjModel, width: u32, height: u32) -> Result<Mj3Renderer, RenderError> {
        let gl = GlContext::new(width, height)?;
        // SAFETY: the structs are plain C data; the default functions set them up before use.
        let mut renderer = unsafe {
            Mj3Renderer {
                gl,
                model,
                scene: zeroed(),
                option: zeroed(),
                perturb: zeroed(),
                camera: zeroed(),
                context: zeroed(),
                pixels: vec![0; 3 * width as usize * height as usize],
            }
        };
        // SAFETY: the model is live; the context is current (GlContext::new made it so), as
        // mjr_makeContext needs.
        unsafe {
            c::mjv_defaultScene(&mut *renderer.scene);
            c::mjv_makeScene(model, &mut *renderer.scene, MAX_GEOMS);
            c::mjv_defaultOption(&mut *renderer.option);
            c::mjv_defaultPerturb(&mut *renderer.perturb);
            c::mjv_defaultCamera(&mut *renderer.camera);
            c::mjr_defaultContext(&mut *renderer.context);
            c::mjr_makeContext(model, &mut *renderer.context, FONT_SCALE);
            c::mjr_setBuffer(FRAMEBUFFER_WINDOW, &mut *renderer.context);
        }
        renderer.gl.release();
        Ok(renderer)
    }

    /// [`super::render::SceneRenderer::render`] of MuJoCo 3.17's `model` and `data`, with the
    /// renderer in `slot` or, when it does not fit them, a new one.
    pub(super) fn render(
        slot: &mut Option<Mj3Renderer>,
        model: *const c::mjModel,
        data: *mut c::mjData,
        camera: &Camera,
        track: TrackView,
        decor: &[Decor],
        frame: &mut Frame,
    ) -> Result<(), RenderError> {
        // SAFETY: `model` is the live model of `data`.
        let fixed = camera_id(camera, || camera_names(unsafe { &*model }))?;
        let size = (frame.width(), frame.height());
        let current = matches!(slot, Some(r) if r.gl.size() == size && r.model == model);
        if !current {
            *slot = None; // free the old context before making the new one
            *slot = Some(Mj3Renderer::new(model, size.0, size.1)?);
        }
        let Some(renderer) = slot.as_mut() else {
            return Err(RenderError::Failed("no renderer".into()));
        };
        renderer.draw(data, fixed, track, decor, frame)
    }

    fn draw(
        &mut self,
        data: *mut c::mjData,
        fixed: Option<Option<c_int>>,
        track: TrackView,
        decor: &[Decor],
        frame: &mut Frame,
    ) -> Result<(), RenderError> {
        self.gl.make_current()?;
        let model = self.model;
        // SAFETY: `model` and `data` are live and exclusively borrowed by the caller; the
        // structs were set up by `new`; the context is current.
        unsafe {
            let m = &*model;
            let last_body = usize::try_from(m.nbody - 1).unwrap_or(0);
            match fixed {
                Some(Some(id)) => {
                    self.camera.type_ = CAMERA_FIXED;
                    self.camera.fixedcamid = id;
                }
                Some(None) => c::mjv_defaultFreeCamera(model, &mut *self.camera),
                None => {
                    c::mjv_defaultFreeCamera(model, &mut *self.camera);
                    self.camera.type_ = CAMERA_TRACKING;
                    self.camera.trackbodyid =
                        c_int::try_from(track.body.min(last_body)).unwrap_or(0);
                    self.camera.distance = track.distance;
                    self.camera.azimuth = track.azimuth;
                    self.camera.elevation = track.elevation;
                }
            }
            c::mjv_updateScene(
                model,
                data,
                &*self.option,
                &*self.perturb,
                &mut *self.camera,
                CATEGORY_ALL,
                &mut *self.scene,
            );
            let followed = if fixed.is_none() && track.grid {
                let body = track.body.min(last_body);
                let xpos = std::slice::from_raw_parts((*data).xpos, 3 * (body + 1));
                Some([xpos[3 * body], xpos[3 * body + 1], 0.0])
            } else {
                None
            };
            self.add_decor(
                decor
                    .iter()
                    .copied()
                    .chain(followed.into_iter().flat_map(grid)),
            );
            let (width, height) = self.gl.size();
            let viewport = c::mjrRect {
                left: 0,
                bottom: 0,
                width: width as c_int,
                height: height as c_int,
            };
            c::mjr_render(viewport, &mut *self.scene, &*self.context);
            c::mjr_readPixels(
                self.pixels.as_mut_ptr(),
                std::ptr::null_mut(),
                viewport,
                &*self.context,
            );
        }
        self.gl.release();
        copy_flipped(&self.pixels, frame);
        Ok(())
    }

    /// Appends `decor` to the scene's geoms, as many as it has room for.
    fn add_decor(&mut self, decor: impl Iterator<Item = Decor>) {
        const IDENTITY: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let scene = &mut *self.scene;
        for d in decor {
            if scene.ngeom >= scene.maxgeom || scene.geoms.is_null() {
                break;
            }
            // SAFETY: `geoms` holds `maxgeom` mjvGeoms (mjv_makeScene) and `ngeom < maxgeom`.
            unsafe {
                c::mjv_initGeom(
                    scene.geoms.add(scene.ngeom as usize),
                    d.shape as c_int,
                    &d.size,
                    &d.pos,
                    &IDENTITY,
                    &d.rgba,
                );
            }
            scene.ngeom += 1;
        }
    }
}

impl Drop for Mj3Renderer {
    fn drop(&mut self) {
        if self.gl.make_current().is_ok() {
            // SAFETY: the structs were made by `new`, the context is current.
            unsafe {
                c::mjr_freeContext(&mut *self.context);
                c::mjv_freeScene(&mut *self.scene);
            }
            self.gl.release();
        }
    }
}

/// The model's camera names, in id order (unnamed cameras as empty names).
fn camera_names(model: &c::mjModel) -> Vec<String> {
    let count = c_int::try_from(model.ncam).unwrap_or(0);
    (0..count)
        .map(|i| {
            // SAFETY: `model` is live and `i` a camera id; the name is NUL-terminated.
            let name = unsafe { c::mj_id2name(model, OBJ_CAMERA, i) };
            if name.is_null() {
                String::new()
            } else {
                // SAFETY: a non-null name from mj_id2name is a NUL-terminated string of the model.
                unsafe { CStr::from_ptr(name) }
                    .to_string_lossy()
                    .into_owned()
            }
        })
        .collect()
}
