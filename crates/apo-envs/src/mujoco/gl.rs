//! A headless OpenGL context for MuJoCo's renderer: EGL (a GPU's driver, or Mesa's software
//! rasterizer) or OSMesa, opened at run time, so that nothing here is needed to build or to
//! train.
//!
//! The libraries are tried in order: EGL on its device platform (the first device: a GPU
//! where there is one), EGL's Mesa surfaceless platform, then OSMesa. `APO_GL=egl` or
//! `APO_GL=osmesa` picks one. The context draws into an off-screen buffer (an EGL pbuffer or
//! OSMesa's memory buffer) of the frame's size, MuJoCo's "window" buffer.
//!
//! MuJoCo 2.2.2 finds the context's library itself (it looks for a loaded `libEGL.so` or
//! `libOSMesa.so` and asks it for the OpenGL functions), so the library must stay loaded while
//! the context lives: [`GlContext`] owns it.

use std::ffi::{c_char, c_int, c_uint, c_void};

use crate::render::RenderError;

/// Environment variable that picks the OpenGL platform: `egl` or `osmesa`.
pub const GL_ENV_VAR: &str = "APO_GL";

type EglDisplay = *mut c_void;
type EglConfig = *mut c_void;
type EglContext = *mut c_void;
type EglSurface = *mut c_void;

const EGL_NONE: i32 = 0x3038;
const EGL_RED_SIZE: i32 = 0x3024;
const EGL_GREEN_SIZE: i32 = 0x3023;
const EGL_BLUE_SIZE: i32 = 0x3022;
const EGL_ALPHA_SIZE: i32 = 0x3021;
const EGL_DEPTH_SIZE: i32 = 0x3025;
const EGL_STENCIL_SIZE: i32 = 0x3026;
const EGL_RENDERABLE_TYPE: i32 = 0x3040;
const EGL_OPENGL_BIT: i32 = 0x0008;
const EGL_SURFACE_TYPE: i32 = 0x3033;
const EGL_PBUFFER_BIT: i32 = 0x0001;
const EGL_WIDTH: i32 = 0x3057;
const EGL_HEIGHT: i32 = 0x3056;
const EGL_OPENGL_API: c_uint = 0x30A2;
const EGL_PLATFORM_DEVICE_EXT: c_uint = 0x313F;
const EGL_PLATFORM_SURFACELESS_MESA: c_uint = 0x31DD;

const OSMESA_RGBA: c_uint = 0x1908;
const GL_UNSIGNED_BYTE: c_uint = 0x1401;

type GetProc = unsafe extern "C" fn(*const c_char) -> *mut c_void;
type GetPlatformDisplay = unsafe extern "C" fn(c_uint, *mut c_void, *const i32) -> EglDisplay;
type QueryDevices = unsafe extern "C" fn(c_int, *mut *mut c_void, *mut c_int) -> c_uint;

/// The EGL functions used here (EGL 1.4 core plus two extensions).
struct Egl {
    initialize: unsafe extern "C" fn(EglDisplay, *mut c_int, *mut c_int) -> c_uint,
    choose_config:
        unsafe extern "C" fn(EglDisplay, *const i32, *mut EglConfig, c_int, *mut c_int) -> c_uint,
    bind_api: unsafe extern "C" fn(c_uint) -> c_uint,
    create_context:
        unsafe extern "C" fn(EglDisplay, EglConfig, EglContext, *const i32) -> EglContext,
    create_pbuffer: unsafe extern "C" fn(EglDisplay, EglConfig, *const i32) -> EglSurface,
    make_current: unsafe extern "C" fn(EglDisplay, EglSurface, EglSurface, EglContext) -> c_uint,
    destroy_context: unsafe extern "C" fn(EglDisplay, EglContext) -> c_uint,
    destroy_surface: unsafe extern "C" fn(EglDisplay, EglSurface) -> c_uint,
    get_error: unsafe extern "C" fn() -> c_int,
    get_proc: GetProc,
}

/// The OSMesa functions used here.
struct OsMesa {
    create: unsafe extern "C" fn(c_uint, c_int, c_int, c_int, *mut c_void) -> *mut c_void,
    make_current: unsafe extern "C" fn(*mut c_void, *mut c_void, c_uint, c_int, c_int) -> c_uint,
    destroy: unsafe extern "C" fn(*mut c_void),
}

enum Platform {
    Egl {
        api: Egl,
        display: EglDisplay,
        context: EglContext,
        surface: EglSurface,
    },
    OsMesa {
        api: OsMesa,
        context: *mut c_void,
        buffer: Vec<u8>,
    },
}

/// An OpenGL context with an off-screen buffer of `width × height` pixels.
pub(crate) struct GlContext {
    platform: Platform,
    width: u32,
    height: u32,
    /// Keeps the platform library loaded (MuJoCo calls into it).
    _library: libloading::Library,
}

// SAFETY: the context is only used between `make_current` and `release` on one thread at a
// time (`&mut self` methods), which is what EGL and OSMesa allow; its handles are plain
// pointers owned by this value.
unsafe impl Send for GlContext {}

impl GlContext {
    /// A context of `width × height` pixels from the first platform that works (see the
    /// module doc); made current on this thread.
    pub(crate) fn new(width: u32, height: u32) -> Result<GlContext, RenderError> {
        let choice = std::env::var(GL_ENV_VAR).unwrap_or_default();
        let order: &[&str] = match choice.as_str() {
            "egl" => &["egl"],
            "osmesa" => &["osmesa"],
            "" => &["egl", "osmesa"],
            other => {
                return Err(RenderError::UnknownGl {
                    value: other.to_string(),
                })
            }
        };
        let mut reasons = Vec::new();
        for name in order {
            let made = match *name {
                "egl" => egl(width, height),
                _ => osmesa(width, height),
            };
            match made {
                Ok(context) => return Ok(context),
                Err(reason) => reasons.push(format!("{name}: {reason}")),
            }
        }
        Err(RenderError::NoDisplay {
            tried: order.join(", "),
            reason: reasons.join("; "),
        })
    }

    /// The buffer's size.
    pub(crate) fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Makes the context current on this thread.
    pub(crate) fn make_current(&mut self) -> Result<(), RenderError> {
        // SAFETY: the handles were made by these libraries and are alive; the OSMesa buffer
        // has `4 · width · height` bytes, which OSMesa needs for RGBA unsigned bytes.
        let ok = unsafe {
            match &mut self.platform {
                Platform::Egl {
                    api,
                    display,
                    context,
                    surface,
                } => (api.make_current)(*display, *surface, *surface, *context) != 0,
                Platform::OsMesa {
                    api,
                    context,
                    buffer,
                } => {
                    (api.make_current)(
                        *context,
                        buffer.as_mut_ptr().cast(),
                        GL_UNSIGNED_BYTE,
                        self.width as c_int,
                        self.height as c_int,
                    ) != 0
                }
            }
        };
        if ok {
            Ok(())
        } else {
            Err(RenderError::Failed(
                "cannot make the OpenGL context current".into(),
            ))
        }
    }

    /// Releases the context from this thread (EGL; OSMesa contexts need not be released).
    pub(crate) fn release(&mut self) {
        if let Platform::Egl { api, display, .. } = &self.platform {
            // SAFETY: releasing the current context of a live display.
            unsafe {
                (api.make_current)(
                    *display,
                    std::ptr::null_mut(),
                    std::ptr::null_mut(),
                    std::ptr::null_mut(),
                );
            }
        }
    }
}

impl Drop for GlContext {
    fn drop(&mut self) {
        // SAFETY: the handles are alive and owned by this value; the display itself is shared
        // by the process's contexts and is not terminated.
        unsafe {
            match &self.platform {
                Platform::Egl {
                    api,
                    display,
                    context,
                    surface,
                } => {
                    (api.make_current)(
                        *display,
                        std::ptr::null_mut(),
                        std::ptr::null_mut(),
                        std::ptr::null_mut(),
                    );
                    (api.destroy_surface)(*display, *surface);
                    (api.destroy_context)(*display, *context);
                }
                Platform::OsMesa { api, context, .. } => (api.destroy)(*context),
            }
        }
    }
}

/// `library`'s symbol `name` as a value of type `T` (a function pointer).
///
/// # Safety
/// `T` must be the symbol's C type.
unsafe fn symbol<T: Copy>(library: &libloading::Library, name: &[u8]) -> Result<T, String> {
    // SAFETY: guaranteed by the caller.
    unsafe {
        library
            .get::<T>(name)
            .map(|s| *s)
            .map_err(|e| e.to_string())
    }
}

fn egl(width: u32, height: u32) -> Result<GlContext, String> {
    // SAFETY: opening libEGL runs its initialisers only.
    let library = unsafe { libloading::Library::new("libEGL.so.1") }.map_err(|e| e.to_string())?;
    // SAFETY: the types are the EGL 1.5 prototypes (EGL/egl.h).
    let api = unsafe {
        Egl {
            initialize: symbol(&library, b"eglInitialize\0")?,
            choose_config: symbol(&library, b"eglChooseConfig\0")?,
            bind_api: symbol(&library, b"eglBindAPI\0")?,
            create_context: symbol(&library, b"eglCreateContext\0")?,
            create_pbuffer: symbol(&library, b"eglCreatePbufferSurface\0")?,
            make_current: symbol(&library, b"eglMakeCurrent\0")?,
            destroy_context: symbol(&library, b"eglDestroyContext\0")?,
            destroy_surface: symbol(&library, b"eglDestroySurface\0")?,
            get_error: symbol(&library, b"eglGetError\0")?,
            get_proc: symbol(&library, b"eglGetProcAddress\0")?,
        }
    };
    // SAFETY: every call below follows EGL's contract: the extension functions are looked up
    // by name and checked for null, attribute lists end with EGL_NONE, and every handle is
    // checked before use.
    unsafe {
        let lookup = |name: &[u8]| (api.get_proc)(name.as_ptr().cast());
        let platform_display = lookup(b"eglGetPlatformDisplayEXT\0");
        if platform_display.is_null() {
            return Err("EGL lacks eglGetPlatformDisplayEXT".into());
        }
        let platform_display: GetPlatformDisplay = std::mem::transmute(platform_display);
        let mut displays = Vec::new();
        let query = lookup(b"eglQueryDevicesEXT\0");
        if !query.is_null() {
            let query: QueryDevices = std::mem::transmute(query);
            let mut device = std::ptr::null_mut();
            let mut count = 0;
            if query(1, &mut device, &mut count) != 0 && count > 0 {
                displays.push(platform_display(
                    EGL_PLATFORM_DEVICE_EXT,
                    device,
                    std::ptr::null(),
                ));
            }
        }
        displays.push(platform_display(
            EGL_PLATFORM_SURFACELESS_MESA,
            std::ptr::null_mut(),
            std::ptr::null(),
        ));
        let mut reason = String::from("no EGL display");
        for display in displays.into_iter().filter(|d| !d.is_null()) {
            let (mut major, mut minor) = (0, 0);
            if (api.initialize)(display, &mut major, &mut minor) == 0 {
                reason = format!("eglInitialize failed (error {:#x})", (api.get_error)());
                continue;
            }
            let attributes = [
                EGL_RED_SIZE,
                8,
                EGL_GREEN_SIZE,
                8,
                EGL_BLUE_SIZE,
                8,
                EGL_ALPHA_SIZE,
                8,
                EGL_DEPTH_SIZE,
                24,
                EGL_STENCIL_SIZE,
                8,
                EGL_RENDERABLE_TYPE,
                EGL_OPENGL_BIT,
                EGL_SURFACE_TYPE,
                EGL_PBUFFER_BIT,
                EGL_NONE,
            ];
            let (mut config, mut found) = (std::ptr::null_mut(), 0);
            if (api.choose_config)(display, attributes.as_ptr(), &mut config, 1, &mut found) == 0
                || found < 1
            {
                reason = "no EGL configuration with OpenGL and a pbuffer".into();
                continue;
            }
            if (api.bind_api)(EGL_OPENGL_API) == 0 {
                reason = "EGL has no desktop OpenGL".into();
                continue;
            }
            let context =
                (api.create_context)(display, config, std::ptr::null_mut(), [EGL_NONE].as_ptr());
            if context.is_null() {
                reason = format!("eglCreateContext failed (error {:#x})", (api.get_error)());
                continue;
            }
            let size = [EGL_WIDTH, width as i32, EGL_HEIGHT, height as i32, EGL_NONE];
            let surface = (api.create_pbuffer)(display, config, size.as_ptr());
            if surface.is_null() {
                reason = format!(
                    "eglCreatePbufferSurface failed (error {:#x})",
                    (api.get_error)()
                );
                (api.destroy_context)(display, context);
                continue;
            }
            let mut gl = GlContext {
                platform: Platform::Egl {
                    api,
                    display,
                    context,
                    surface,
                },
                width,
                height,
                _library: library,
            };
            gl.make_current().map_err(|e| e.to_string())?;
            return Ok(gl);
        }
        Err(reason)
    }
}

fn osmesa(width: u32, height: u32) -> Result<GlContext, String> {
    // SAFETY: opening libOSMesa runs its initialisers only.
    let library =
        unsafe { libloading::Library::new("libOSMesa.so.8") }.map_err(|e| e.to_string())?;
    // SAFETY: the types are the prototypes of GL/osmesa.h.
    let api = unsafe {
        OsMesa {
            create: symbol(&library, b"OSMesaCreateContextExt\0")?,
            make_current: symbol(&library, b"OSMesaMakeCurrent\0")?,
            destroy: symbol(&library, b"OSMesaDestroyContext\0")?,
        }
    };
    // SAFETY: a context with 24 depth and 8 stencil bits, no shared lists.
    let context = unsafe { (api.create)(OSMESA_RGBA, 24, 8, 0, std::ptr::null_mut()) };
    if context.is_null() {
        return Err("OSMesaCreateContextExt failed".into());
    }
    let buffer = vec![0u8; 4 * width as usize * height as usize];
    let mut gl = GlContext {
        platform: Platform::OsMesa {
            api,
            context,
            buffer,
        },
        width,
        height,
        _library: library,
    };
    gl.make_current().map_err(|e| e.to_string())?;
    Ok(gl)
}
