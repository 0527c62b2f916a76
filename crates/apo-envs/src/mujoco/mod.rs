//! MuJoCo 2.2 physics and the Gym MuJoCo locomotion suite.
//!
//! - [`Model`] / [`Data`]: a small safe wrapper over FFI bindings to Debian's MuJoCo 2.2.2
//!   (`libmujoco-dev`), which is opened at run time (see [`check_library`]): binaries
//!   build and run without MuJoCo, and only MuJoCo environments then fail, with an error
//!   that says how to install it.
//! - [`MujocoEnv`]: the shared machinery of the environments (frame skip, reset noise,
//!   instability check), and [`tasks`]: the ten Gymnasium v4 tasks, registered in
//!   [`crate::registry`] as `Hopper-v4` etc. (`Hopper` resolves too). Their MJCF models are
//!   this project's own, embedded.
//! - [`steps_per_second`], [`vector_steps_per_second`]: the `apo bench env` measurements.
//!
//! See `docs/mujoco.md` for the design, the Send/Sync story and the benchmarks.

mod bench;
mod env;
mod error;
#[allow(
    dead_code,
    non_camel_case_types,
    non_snake_case,
    non_upper_case_globals,
    clippy::all
)]
mod ffi;
mod library;
mod model;
pub mod tasks;

pub use bench::{steps_per_second, vector_steps_per_second};
pub use env::{MujocoEnv, ResetNoise, Sizes, StepContext, Task};
pub use error::MujocoError;
pub use library::{check_library, EXPECTED_VERSION, LIBRARY_ENV_VAR};
pub use model::{ContactForce, Data, Model, ObjKind, Warning};

use crate::entry::{entry, Act, Entry};
use crate::env::Env;
use crate::error::EnvError;
use tasks::{
    Ant, HalfCheetah, Hopper, Humanoid, HumanoidStandup, InvertedDoublePendulum, InvertedPendulum,
    Reacher, Swimmer, Walker2d,
};

/// Builds the bare environment of task `T` for the registry.
fn build<T: Task>() -> Result<Box<dyn Env>, EnvError> {
    match MujocoEnv::<T>::make() {
        Ok(env) => Ok(Box::new(env)),
        Err(err) => Err(EnvError::Init {
            name: T::NAME.to_owned(),
            reason: err.to_string(),
        }),
    }
}

/// Registry lines of the MuJoCo suite, with Gymnasium v4's names and time limits.
pub(crate) static ENTRIES: &[Entry] = &[
    entry(
        "InvertedPendulum-v4",
        4,
        Act::Continuous(1),
        1000,
        build::<InvertedPendulum>,
    ),
    entry(
        "InvertedDoublePendulum-v4",
        11,
        Act::Continuous(1),
        1000,
        build::<InvertedDoublePendulum>,
    ),
    entry("Reacher-v4", 11, Act::Continuous(2), 50, build::<Reacher>),
    entry("Swimmer-v4", 8, Act::Continuous(2), 1000, build::<Swimmer>),
    entry("Hopper-v4", 11, Act::Continuous(3), 1000, build::<Hopper>),
    entry(
        "HalfCheetah-v4",
        17,
        Act::Continuous(6),
        1000,
        build::<HalfCheetah>,
    ),
    entry(
        "Walker2d-v4",
        17,
        Act::Continuous(6),
        1000,
        build::<Walker2d>,
    ),
    entry("Ant-v4", 27, Act::Continuous(8), 1000, build::<Ant>),
    entry(
        "Humanoid-v4",
        376,
        Act::Continuous(17),
        1000,
        build::<Humanoid>,
    ),
    entry(
        "HumanoidStandup-v4",
        376,
        Act::Continuous(17),
        1000,
        build::<HumanoidStandup>,
    ),
];
