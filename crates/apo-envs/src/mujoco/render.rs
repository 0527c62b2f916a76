//! MuJoCo's own renderer on a headless OpenGL context ([`super::gl`]): what
//! [`crate::Env::render`] of the MuJoCo environments draws with.
//!
//! A [`SceneRenderer`] belongs to one environment and holds nothing until the first render,
//! which opens the OpenGL context, makes MuJoCo's scene (`mjv_makeScene`) and its OpenGL
//! resources (`mjr_makeContext`) for the environment's model. Each frame then runs `mjv_updateScene` on
//! the environment's data, adds the task's [`Decor`] (what the simulation does not hold as
//! geoms: GUARD's goal, hazards and robbers, the reach targets of the hand), renders into the
//! context's buffer (`mjr_render`) and reads the pixels back (`mjr_readPixels`). Training
//! never makes one: an environment that is not asked to render pays nothing.
//!
//! The renderer's functions come from the MuJoCo 2.2.2 library the physics loaded; the
//! structs they fill (`mjvScene`, `mjvOption`, `mjvPerturb`, `mjvCamera`, `mjrContext`) are
//! kept as opaque memory of their 2.2.2 sizes, and only the few fields set here are written,
//! at their 2.2.2 offsets (measured with the C compiler against Debian's headers; see
//! `docs/render.md`). The library's version is checked when it is loaded (`mj_version`).
//! The [`super::Physics::Mujoco3`] environments render with MuJoCo 3.17's own renderer
//! (`render3.rs`, feature `mujoco3`) on the same context and with the same scene.

use std::ffi::{c_char, c_int, c_uchar, c_void, CStr};
use std::sync::OnceLock;

use super::ffi::{mjData, mjModel};
use super::gl::GlContext;
use super::library;
use super::model::Data;
#[cfg(feature = "mujoco3")]
use super::render3::Mj3Renderer;
use super::scene::{
    camera_id, copy_flipped, grid, Decor, TrackView, CAMERA_FIXED, CAMERA_TRACKING, CATEGORY_ALL,
    FONT_SCALE, FRAMEBUFFER_WINDOW, MAX_GEOMS,
};
use crate::render::{Camera, Frame, RenderError};

/// `sizeof(mjvScene)` in MuJoCo 2.2.2.
const SCENE_SIZE: usize = 8656;
/// `sizeof(mjvGeom)`.
const GEOM_SIZE: usize = 248;
/// `sizeof(mjvOption)`.
const OPTION_SIZE: usize = 68;
/// `sizeof(mjvPerturb)`.
const PERTURB_SIZE: usize = 104;
/// `sizeof(mjvCamera)`.
const CAMERA_SIZE: usize = 64;
/// `sizeof(mjrContext)`.
const CONTEXT_SIZE: usize = 2304;

/// `mjvScene.maxgeom`, `.ngeom` (ints) and `.geoms` (a pointer): their offsets.
const SCENE_MAXGEOM: usize = 0;
const SCENE_NGEOM: usize = 4;
const SCENE_GEOMS: usize = 8;
/// `mjvCamera.type`, `.fixedcamid`, `.trackbodyid` (ints), `.distance`, `.azimuth` and
/// `.elevation` (doubles): their offsets.
const CAMERA_TYPE: usize = 0;
const CAMERA_FIXEDCAMID: usize = 4;
const CAMERA_TRACKBODYID: usize = 8;
const CAMERA_DISTANCE: usize = 40;
const CAMERA_AZIMUTH: usize = 48;
const CAMERA_ELEVATION: usize = 56;

/// `mjrRect`.
#[repr(C)]
#[derive(Clone, Copy)]
struct Rect {
    left: c_int,
    bottom: c_int,
    width: c_int,
    height: c_int,
}

/// The renderer functions of MuJoCo 2.2.2 (mujoco.h), from the library the physics uses.
struct RenderApi {
    default_scene: unsafe extern "C" fn(*mut c_void),
    make_scene: unsafe extern "C" fn(*const mjModel, *mut c_void, c_int),
    free_scene: unsafe extern "C" fn(*mut c_void),
    default_option: unsafe extern "C" fn(*mut c_void),
    default_perturb: unsafe extern "C" fn(*mut c_void),
    default_free_camera: unsafe extern "C" fn(*const mjModel, *mut c_void),
    update_scene: unsafe extern "C" fn(
        *const mjModel,
        *mut mjData,
        *const c_void,
        *const c_void,
        *mut c_void,
        c_int,
        *mut c_void,
    ),
    init_geom:
        unsafe extern "C" fn(*mut c_void, c_int, *const f64, *const f64, *const f64, *const f32),
    default_context: unsafe extern "C" fn(*mut c_void),
    make_context: unsafe extern "C" fn(*const mjModel, *mut c_void, c_int),
    free_context: unsafe extern "C" fn(*mut c_void),
    set_buffer: unsafe extern "C" fn(c_int, *mut c_void),
    render: unsafe extern "C" fn(Rect, *mut c_void, *const c_void),
    read_pixels: unsafe extern "C" fn(*mut c_uchar, *mut f32, Rect, *const c_void),
    /// Keeps the library loaded while the function pointers are used.
    _library: libloading::Library,
}

static API: OnceLock<Result<RenderApi, String>> = OnceLock::new();

fn api() -> Result<&'static RenderApi, RenderError> {
    API.get_or_init(load)
        .as_ref()
        .map_err(|reason| RenderError::Failed(reason.clone()))
}

fn load() -> Result<RenderApi, String> {
    let library = library::open_again().map_err(|e| e.to_string())?;
    /// The symbol `name` of `library`.
    ///
    /// # Safety
    /// `T` must be the C type of the symbol.
    unsafe fn get<T: Copy>(library: &libloading::Library, name: &[u8]) -> Result<T, String> {
        // SAFETY: guaranteed by the caller.
        unsafe {
            library
                .get::<T>(name)
                .map(|s| *s)
                .map_err(|e| e.to_string())
        }
    }
    // SAFETY: the types are the prototypes of MuJoCo 2.2.2's mujoco.h; the library is the one
    // whose version the physics checked.
    unsafe {
        Ok(RenderApi {
            default_scene: get(&library, b"mjv_defaultScene\0")?,
            make_scene: get(&library, b"mjv_makeScene\0")?,
            free_scene: get(&library, b"mjv_freeScene\0")?,
            default_option: get(&library, b"mjv_defaultOption\0")?,
            default_perturb: get(&library, b"mjv_defaultPerturb\0")?,
            default_free_camera: get(&library, b"mjv_defaultFreeCamera\0")?,
            update_scene: get(&library, b"mjv_updateScene\0")?,
            init_geom: get(&library, b"mjv_initGeom\0")?,
            default_context: get(&library, b"mjr_defaultContext\0")?,
            make_context: get(&library, b"mjr_makeContext\0")?,
            free_context: get(&library, b"mjr_freeContext\0")?,
            set_buffer: get(&library, b"mjr_setBuffer\0")?,
            render: get(&library, b"mjr_render\0")?,
            read_pixels: get(&library, b"mjr_readPixels\0")?,
            _library: library,
        })
    }
}

/// Zeroed memory of `bytes` bytes, 8-byte aligned, for an opaque MuJoCo struct.
struct Opaque(Box<[u64]>);

impl Opaque {
    fn new(bytes: usize) -> Opaque {
        Opaque(vec![0u64; bytes.div_ceil(8)].into_boxed_slice())
    }

    fn ptr(&mut self) -> *mut c_void {
        self.0.as_mut_ptr().cast()
    }

    /// Writes `value` at byte `offset`.
    fn write<T: Copy>(&mut self, offset: usize, value: T) {
        let bytes = self.0.len() * 8;
        if offset + std::mem::size_of::<T>() <= bytes {
            // SAFETY: in bounds (checked); unaligned write, so any offset is fine.
            unsafe {
                self.ptr()
                    .cast::<u8>()
                    .add(offset)
                    .cast::<T>()
                    .write_unaligned(value)
            }
        }
    }

    /// Reads a `T` at byte `offset` (the zero value when out of bounds).
    fn read<T: Copy + Default>(&mut self, offset: usize) -> T {
        let bytes = self.0.len() * 8;
        if offset + std::mem::size_of::<T>() <= bytes {
            // SAFETY: in bounds (checked); MuJoCo wrote a `T` there.
            unsafe {
                self.ptr()
                    .cast::<u8>()
                    .add(offset)
                    .cast::<T>()
                    .read_unaligned()
            }
        } else {
            T::default()
        }
    }
}

/// One environment's renderer, for the physics its data runs on: an OpenGL context of the
/// frame's size and MuJoCo's scene and OpenGL resources for its model. Empty until the first
/// render; remade when the frame size or the model changes.
#[derive(Debug, Default)]
pub(crate) struct SceneRenderer {
    /// MuJoCo 2.2.2's renderer.
    mj2: Option<Mj2Renderer>,
    /// MuJoCo 3.17's renderer (`--physics mujoco3`).
    #[cfg(feature = "mujoco3")]
    mj3: Option<Mj3Renderer>,
}

impl SceneRenderer {
    /// Renders `data`'s state seen from `camera` (Track as `track` says), with `decor`
    /// added, into `frame`, with the renderer of `data`'s physics, remaking it when the frame
    /// size or the model changed.
    ///
    /// # Errors
    /// [`RenderError::UnknownCamera`] for a camera name the model lacks;
    /// [`RenderError::NoDisplay`] when no OpenGL context could be made;
    /// [`RenderError::Failed`] when the renderer's functions are missing.
    pub(crate) fn render(
        &mut self,
        data: &mut Data,
        camera: &Camera,
        track: TrackView,
        decor: &[Decor],
        frame: &mut Frame,
    ) -> Result<(), RenderError> {
        if let Some((model, raw)) = data.mj2_raw() {
            return Mj2Renderer::render(&mut self.mj2, model, raw, camera, track, decor, frame);
        }
        #[cfg(feature = "mujoco3")]
        if let Some((model, raw)) = data.mj3_raw() {
            return Mj3Renderer::render(&mut self.mj3, model, raw, camera, track, decor, frame);
        }
        Err(RenderError::Failed(
            "this physics has no renderer in this build".into(),
        ))
    }
}

/// MuJoCo 2.2.2's renderer of one environment.
pub(crate) struct Mj2Renderer {
    api: &'static RenderApi,
    gl: GlContext,
    model: *const mjModel,
    scene: Opaque,
    option: Opaque,
    perturb: Opaque,
    camera: Opaque,
    context: Opaque,
    /// Pixels as MuJoCo reads them (rows from the bottom).
    pixels: Vec<u8>,
}

// SAFETY: the renderer owns its context and MuJoCo structs and is used through `&mut self`
// only, on one thread at a time (see `GlContext`); `model` is a pointer to the model of the
// environment that owns the renderer, which outlives it, and is only read.
unsafe impl Send for Mj2Renderer {}

impl std::fmt::Debug for Mj2Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mj2Renderer")
            .field("size", &self.gl.size())
            .finish_non_exhaustive()
    }
}

impl Mj2Renderer {
    fn new(model: *const mjModel, width: u32, height: u32) -> Result<Mj2Renderer, RenderError> {
        let api = api()?;
        let gl = GlContext::new(width, height)?;
        let mut renderer = Mj2Renderer {
            api,
            gl,
            model,
            scene: Opaque::new(SCENE_SIZE),
            option: Opaque::new(OPTION_SIZE),
            perturb: Opaque::new(PERTURB_SIZE),
            camera: Opaque::new(CAMERA_SIZE),
            context: Opaque::new(CONTEXT_SIZE),
            pixels: vec![0; 3 * width as usize * height as usize],
        };
        // SAFETY: each struct has its 2.2.2 size; the model is live; the context is current
        // (GlContext::new made it so), as mjr_makeContext needs.
        unsafe {
            (api.default_scene)(renderer.scene.ptr());
            (api.make_scene)(model, renderer.scene.ptr(), MAX_GEOMS);
            (api.default_option)(renderer.option.ptr());
            (api.default_perturb)(renderer.perturb.ptr());
            (api.default_context)(renderer.context.ptr());
            (api.make_context)(model, renderer.context.ptr(), FONT_SCALE);
            (api.set_buffer)(FRAMEBUFFER_WINDOW, renderer.context.ptr());
        }
        Ok(renderer)
    }

    /// [`SceneRenderer::render`] of MuJoCo 2.2.2's `model` and `data`, with the renderer in
    /// `slot` or, when it does not fit them, a new one.
    fn render(
        slot: &mut Option<Mj2Renderer>,
        model: *const mjModel,
        data: *mut mjData,
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
            *slot = Some(Mj2Renderer::new(model, size.0, size.1)?);
        }
        let Some(renderer) = slot.as_mut() else {
            return Err(RenderError::Failed("no renderer".into()));
        };
        renderer.draw(model, data, fixed, track, decor, frame)
    }

    fn draw(
        &mut self,
        model: *const mjModel,
        data: *mut mjData,
        fixed: Option<Option<c_int>>,
        track: TrackView,
        decor: &[Decor],
        frame: &mut Frame,
    ) -> Result<(), RenderError> {
        self.gl.make_current()?;
        let api = self.api;
        // SAFETY: `model` and `data` are live and exclusively borrowed by the caller; the
        // structs have their 2.2.2 sizes and were set up by `new`; the context is current.
        unsafe {
            let m = &*model;
            match fixed {
                Some(Some(id)) => {
                    self.camera.write(CAMERA_TYPE, CAMERA_FIXED);
                    self.camera.write(CAMERA_FIXEDCAMID, id);
                }
                Some(None) => (api.default_free_camera)(model, self.camera.ptr()),
                None => {
                    (api.default_free_camera)(model, self.camera.ptr());
                    let body = c_int::try_from(track.body).unwrap_or(0).min(m.nbody - 1);
                    self.camera.write(CAMERA_TYPE, CAMERA_TRACKING);
                    self.camera.write(CAMERA_TRACKBODYID, body);
                    self.camera.write(CAMERA_DISTANCE, track.distance);
                    self.camera.write(CAMERA_AZIMUTH, track.azimuth);
                    self.camera.write(CAMERA_ELEVATION, track.elevation);
                }
            }
            (api.update_scene)(
                model,
                data,
                self.option.ptr(),
                self.perturb.ptr(),
                self.camera.ptr(),
                CATEGORY_ALL,
                self.scene.ptr(),
            );
            let followed = if fixed.is_none() && track.grid {
                let body = track.body.min(usize::try_from(m.nbody - 1).unwrap_or(0));
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
            let viewport = Rect {
                left: 0,
                bottom: 0,
                width: width as c_int,
                height: height as c_int,
            };
            (api.render)(viewport, self.scene.ptr(), self.context.ptr());
            (api.read_pixels)(
                self.pixels.as_mut_ptr(),
                std::ptr::null_mut(),
                viewport,
                self.context.ptr(),
            );
        }
        self.gl.release();
        copy_flipped(&self.pixels, frame);
        Ok(())
    }

    /// Appends `decor` to the scene's geoms, as many as it has room for.
    ///
    /// # Safety
    /// The scene was made by `mjv_makeScene` and updated by `mjv_updateScene`.
    unsafe fn add_decor(&mut self, decor: impl Iterator<Item = Decor>) {
        let max = self.scene.read::<c_int>(SCENE_MAXGEOM);
        let mut count = self.scene.read::<c_int>(SCENE_NGEOM);
        let geoms = self.scene.read::<usize>(SCENE_GEOMS) as *mut u8;
        const IDENTITY: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        for d in decor {
            if count >= max || geoms.is_null() {
                break;
            }
            // SAFETY: `geoms` holds `maxgeom` mjvGeoms and `count < maxgeom`.
            unsafe {
                let geom = geoms.add(count as usize * GEOM_SIZE).cast::<c_void>();
                (self.api.init_geom)(
                    geom,
                    d.shape as c_int,
                    d.size.as_ptr(),
                    d.pos.as_ptr(),
                    IDENTITY.as_ptr(),
                    d.rgba.as_ptr(),
                );
            }
            count += 1;
        }
        self.scene.write(SCENE_NGEOM, count);
    }
}

impl Drop for Mj2Renderer {
    fn drop(&mut self) {
        if self.gl.make_current().is_ok() {
            // SAFETY: the structs were made by `new`, the context is current.
            unsafe {
                (self.api.free_context)(self.context.ptr());
                (self.api.free_scene)(self.scene.ptr());
            }
            self.gl.release();
        }
    }
}

/// The model's camera names, in id order (unnamed cameras as empty names).
fn camera_names(model: &mjModel) -> Vec<String> {
    let count = usize::try_from(model.ncam).unwrap_or(0);
    (0..count)
        .map(|i| {
            // SAFETY: `name_camadr` has `ncam` entries, each the offset of a NUL-terminated
            // name in `names`.
            unsafe {
                let adr = *model.name_camadr.add(i);
                let name: *const c_char = model.names.offset(adr as isize);
                CStr::from_ptr(name).to_string_lossy().into_owned()
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sizes and offsets above against Debian's MuJoCo 2.2.2 headers (`libmujoco-dev`),
    /// as the C compiler lays the structs out.
    #[test]
    fn struct_layouts_match_the_headers() {
        let dir = std::env::temp_dir().join(format!("apo-render-layout-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let source = dir.join("layout.c");
        std::fs::write(
            &source,
            r#"#include <stdio.h>
#include <stddef.h>
#include <mujoco/mujoco.h>
int main(void) {
  printf("%zu %zu %zu %zu %zu %zu\n", sizeof(mjvScene), sizeof(mjvGeom), sizeof(mjvOption),
         sizeof(mjvPerturb), sizeof(mjvCamera), sizeof(mjrContext));
  printf("%zu %zu %zu\n", offsetof(mjvScene, maxgeom), offsetof(mjvScene, ngeom),
         offsetof(mjvScene, geoms));
  printf("%zu %zu %zu %zu %zu %zu\n", offsetof(mjvCamera, type), offsetof(mjvCamera, fixedcamid),
         offsetof(mjvCamera, trackbodyid), offsetof(mjvCamera, distance),
         offsetof(mjvCamera, azimuth), offsetof(mjvCamera, elevation));
  return 0;
}
"#,
        )
        .expect("write the probe");
        let binary = dir.join("layout");
        let built = std::process::Command::new("cc")
            .arg(&source)
            .arg("-o")
            .arg(&binary)
            .output()
            .expect("cc runs (Debian's build-essential)");
        assert!(
            built.status.success(),
            "the probe does not compile against /usr/include/mujoco (libmujoco-dev): {}",
            String::from_utf8_lossy(&built.stderr)
        );
        let out = std::process::Command::new(&binary)
            .output()
            .expect("the probe runs");
        let numbers: Vec<usize> = String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .map(|n| n.parse().expect("a number"))
            .collect();
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(
            numbers,
            [
                SCENE_SIZE,
                GEOM_SIZE,
                OPTION_SIZE,
                PERTURB_SIZE,
                CAMERA_SIZE,
                CONTEXT_SIZE,
                SCENE_MAXGEOM,
                SCENE_NGEOM,
                SCENE_GEOMS,
                CAMERA_TYPE,
                CAMERA_FIXEDCAMID,
                CAMERA_TRACKBODYID,
                CAMERA_DISTANCE,
                CAMERA_AZIMUTH,
                CAMERA_ELEVATION,
            ]
        );
    }
}
