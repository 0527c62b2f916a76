//! Errors of the MuJoCo layer.

use thiserror::Error;

/// An error from loading the MuJoCo library, a model, or building an environment on it.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MujocoError {
    /// The MuJoCo shared library could not be opened or lacks a function we need.
    #[error(
        "cannot load the MuJoCo 2.2.2 library (tried {tried}): {reason}; \
         install it with `apt-get install libmujoco-dev` or point APO_MUJOCO_LIB at libmujoco.so.2.2.2"
    )]
    Library {
        /// The library names or paths that were tried, comma separated.
        tried: String,
        /// Why the last attempt failed.
        reason: String,
    },
    /// The library loaded but reports a version other than 2.2.2.
    #[error(
        "the MuJoCo library reports version {found} (mj_version() = {raw}) but apo's bindings are for 2.2.2 (222); \
         install Debian's `libmujoco-dev` 2.2.2 or point APO_MUJOCO_LIB at libmujoco.so.2.2.2"
    )]
    Version {
        /// The version as `major.minor.patch`.
        found: String,
        /// The value of `mj_version()`.
        raw: i32,
    },
    /// The chosen physics backend cannot be used: it is not in this build (MuJoCo 3 needs the
    /// cargo feature `mujoco3`), or the library it is linked to is not the version its bindings
    /// are for.
    #[error("MuJoCo physics `{physics}` is unavailable: {reason}")]
    Unavailable {
        /// The backend, as [`super::Physics`] names it (`mujoco2`, `mujoco3`).
        physics: &'static str,
        /// Why, and what to do about it.
        reason: String,
    },
    /// MuJoCo's parser or compiler rejected a model; `message` is MuJoCo's own text.
    #[error("MuJoCo could not load the model {source_name}: {message}")]
    Model {
        /// The file path, or `<string>` for a model given as text.
        source_name: String,
        /// MuJoCo's error message.
        message: String,
    },
    /// A string passed to MuJoCo contains a NUL byte, or a model text is too large.
    #[error("invalid input for MuJoCo: {0}")]
    InvalidInput(String),
    /// MuJoCo could not allocate `mjData` for a model.
    #[error("MuJoCo could not allocate simulation data (mj_makeData returned null)")]
    Allocation,
    /// A named object does not exist in the model.
    #[error("the model has no {kind} named `{name}`")]
    UnknownName {
        /// The kind of object (`body`, `joint`, ...).
        kind: &'static str,
        /// The name that was looked up.
        name: String,
    },
    /// A model does not have the sizes an environment expects.
    #[error("model for {env} has {what} = {found}, expected {expected}")]
    Shape {
        /// The environment.
        env: &'static str,
        /// The size that differs (`nq`, `nu`, ...).
        what: &'static str,
        /// The model's value.
        found: usize,
        /// The expected value.
        expected: usize,
    },
}
