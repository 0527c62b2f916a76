//! Loading the MuJoCo shared library at run time.
//!
//! The library is opened with `dlopen` the first time a model is loaded (or when
//! [`check_library`] is called), once per process, so binaries built from this crate build,
//! link and run on machines without MuJoCo; only the MuJoCo environments then fail, with an
//! error that says how to install it.

use std::ffi::{c_char, CStr, OsStr, OsString};
use std::io::Write;
use std::sync::OnceLock;

use super::error::MujocoError;
use super::ffi::MujocoApi;

/// The only MuJoCo version the bindings are generated for, as `mj_version()` reports it.
pub const EXPECTED_VERSION: i32 = 222;

/// Environment variable that, when set, names the exact MuJoCo library file to open
/// instead of searching for `libmujoco.so.2.2.2` and then `libmujoco.so`.
pub const LIBRARY_ENV_VAR: &str = "APO_MUJOCO_LIB";

const CANDIDATES: [&str; 2] = ["libmujoco.so.2.2.2", "libmujoco.so"];

/// MuJoCo's global error and warning hooks (`mju_user_error`, `mju_user_warning`).
type Hook = Option<unsafe extern "C" fn(*const c_char)>;

static API: OnceLock<Result<MujocoApi, MujocoError>> = OnceLock::new();

/// The name the library was opened by (set once [`api`] succeeded).
static OPENED: OnceLock<OsString> = OnceLock::new();

/// The loaded library, opened and checked on first use.
pub(crate) fn api() -> Result<&'static MujocoApi, MujocoError> {
    API.get_or_init(load).as_ref().map_err(Clone::clone)
}

/// Opens the MuJoCo library if it is not open yet and checks that it is version 2.2.2.
///
/// Call it at start-up to fail early with a clear message; every model load calls it too.
pub fn check_library() -> Result<(), MujocoError> {
    api().map(|_| ())
}

fn load() -> Result<MujocoApi, MujocoError> {
    let candidates: Vec<OsString> = match std::env::var_os(LIBRARY_ENV_VAR) {
        Some(path) => vec![path],
        None => CANDIDATES.iter().map(OsString::from).collect(),
    };
    let tried = candidates
        .iter()
        .map(|c| c.to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join(", ");
    let mut reason = String::from("no candidate");
    for name in &candidates {
        // SAFETY: opening MuJoCo runs only its ELF initialisers (static tables, no I/O).
        let library = match unsafe { open(name) } {
            Ok(library) => library,
            Err(err) => {
                reason = err.to_string();
                continue;
            }
        };
        let api = from_library(library, &tried)?;
        let _ = OPENED.set(name.clone());
        return Ok(api);
    }
    Err(MujocoError::Library { tried, reason })
}

/// Opens the MuJoCo library `name` as `libloading::Library::new` does (`RTLD_LAZY |
/// RTLD_LOCAL`), plus, with glibc, `RTLD_DEEPBIND`: the library then binds the symbols it
/// defines itself before those of the global scope. Debian's `libmujoco.so.2.2.2` is not linked
/// with `-Bsymbolic`, so without this, in a binary built with the `mujoco3` feature (whose
/// global scope holds MuJoCo 3.17, linked by mujoco-rs), 2.2.2's calls to its own exported
/// functions and hooks (`mj_forward`, `mju_user_error`, ...) would bind to 3.17's and crash.
/// Harmless without MuJoCo 3. See `docs/mujoco.md`, "Two MuJoCo versions in one process".
///
/// # Safety
/// As for `libloading::Library::new`: the library's ELF initialisers run.
unsafe fn open(name: &OsStr) -> Result<libloading::Library, libloading::Error> {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        use libloading::os::unix::{Library, RTLD_LAZY, RTLD_LOCAL};
        // SAFETY: guaranteed by the caller; the flags are valid `dlopen` flags for glibc.
        unsafe { Library::open(Some(name), RTLD_LAZY | RTLD_LOCAL | libc::RTLD_DEEPBIND) }
            .map(libloading::Library::from)
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        // SAFETY: guaranteed by the caller.
        unsafe { libloading::Library::new(name) }
    }
}

/// Another handle of the MuJoCo library the physics loaded (the same library: `dlopen` of
/// an open file counts a reference), for the functions the bindings leave out (the renderer's).
pub(crate) fn open_again() -> Result<libloading::Library, MujocoError> {
    api()?;
    let name = OPENED.get().ok_or_else(|| MujocoError::Library {
        tried: String::new(),
        reason: "the MuJoCo library is not open".into(),
    })?;
    // SAFETY: the library is already open and initialised; this only counts a reference.
    unsafe { open(name) }.map_err(|err| MujocoError::Library {
        tried: name.to_string_lossy().into_owned(),
        reason: err.to_string(),
    })
}

fn from_library(library: libloading::Library, tried: &str) -> Result<MujocoApi, MujocoError> {
    let symbol_error = |err: libloading::Error| MujocoError::Library {
        tried: tried.to_owned(),
        reason: err.to_string(),
    };
    // SAFETY: both symbols are `void (*)(const char*)` variables in MuJoCo 2.2's API
    // (mujoco.h); the addresses stay valid while the library is loaded, which is for the
    // rest of the process because the `MujocoApi` that owns it lives in a static.
    let (error_hook, warning_hook) = unsafe {
        let error_hook = *library
            .get::<*mut Hook>(b"mju_user_error\0")
            .map_err(symbol_error)?;
        let warning_hook = *library
            .get::<*mut Hook>(b"mju_user_warning\0")
            .map_err(symbol_error)?;
        (error_hook, warning_hook)
    };
    // SAFETY: the function signatures in `MujocoApi` were generated from the 2.2.2 headers;
    // the version check below rejects any other library before a model is ever built.
    let api = unsafe { MujocoApi::from_library(library) }.map_err(symbol_error)?;
    // SAFETY: `mj_version` takes no arguments and only returns a constant.
    let raw = unsafe { api.mj_version() };
    if raw != EXPECTED_VERSION {
        let found = format!("{}.{}.{}", raw / 100, (raw / 10) % 10, raw % 10);
        return Err(MujocoError::Version { found, raw });
    }
    // SAFETY: plain stores of function pointers with the C signature MuJoCo expects, done
    // once, inside `OnceLock::get_or_init`, before any other MuJoCo call can run.
    unsafe {
        error_hook.write(Some(on_error));
        warning_hook.write(Some(on_warning));
    }
    Ok(api)
}

/// MuJoCo calls this on a fatal error (for example its arena overflowing) and requires that
/// it does not return. MuJoCo's default prints, waits for Enter and exits; we print and abort,
/// since unwinding a Rust panic through C frames would be undefined behaviour.
unsafe extern "C" fn on_error(message: *const c_char) {
    let text = if message.is_null() {
        "(no message)".into()
    } else {
        // SAFETY: MuJoCo passes a NUL-terminated string.
        unsafe { CStr::from_ptr(message) }.to_string_lossy()
    };
    let _ = writeln!(std::io::stderr(), "MuJoCo fatal error: {text}; aborting");
    std::process::abort();
}

/// Replaces MuJoCo's default warning printer, which writes `MUJOCO_LOG.TXT` into the
/// working directory. Simulator warnings are reported through `mjData.warning` instead
/// ([`super::Data::warning_count`], and `StepInfo::unstable` in the environments).
unsafe extern "C" fn on_warning(_message: *const c_char) {}
