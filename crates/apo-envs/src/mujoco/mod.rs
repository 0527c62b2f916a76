//! MuJoCo 2.2 physics and the Gym MuJoCo locomotion suite.
//!
//! - [`Model`] / [`Data`]: a small safe wrapper over FFI bindings to Debian's MuJoCo 2.2.2
//!   (`libmujoco-dev`), which is opened at run time (see [`check_library`]): binaries
//!   build and run without MuJoCo, and only MuJoCo environments then fail, with an error
//!   that says how to install it.
//! - [`MujocoEnv`]: the shared machinery of the environments (frame skip, reset noise,
//!   instability check), and [`tasks`]: the ten Gymnasium v4 tasks, registered in
//!   [`crate::registry`] as `Hopper-v4` etc. (`Hopper` resolves too), in the family `mujoco`.
//!   Their MJCF models are this project's own, embedded. Another crate registers its own
//!   tasks with [`Family::add_task`], whose sizes are the task's constants.
//! - [`guard`]: the GUARD suites (`Goal_Point` … `Chase_Walker`), in the family `guard`.
//! - [`hand`]: the Shadow Dexterous Hand tasks of Gymnasium-Robotics (`HandReachDense-v3`,
//!   `HandManipulateBlockDense-v1`, `HandManipulateEggDense-v1`), in the family `hand`.
//!
//! See `docs/mujoco.md` for the design, the Send/Sync story and the benchmarks.

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
mod gl;
pub mod guard;
pub mod hand;
mod library;
mod mj2;
#[cfg(feature = "mujoco3")]
mod mj3;
mod model;
pub(crate) mod physics;
mod render;
#[cfg(feature = "mujoco3")]
mod render3;
mod scene;
pub mod tasks;

pub use env::{MujocoEnv, ResetNoise, Sizes, StepContext, Task};
pub use error::MujocoError;
pub use library::{check_library, EXPECTED_VERSION, LIBRARY_ENV_VAR};
pub use model::{ContactForce, Data, Dynamics, Model, ObjKind, Warning};
pub(crate) use physics::with_physics;
pub use physics::{default_physics, set_default_physics, Physics};
pub use scene::TrackView;

use crate::env::Env;
use crate::error::EnvError;
use crate::family::{Family, Spaces};
use crate::space::Space;
use tasks::{
    Ant, HalfCheetah, Hopper, Humanoid, HumanoidStandup, InvertedDoublePendulum, InvertedPendulum,
    Reacher, Swimmer, Walker2d,
};

impl Family {
    /// Adds the MuJoCo task `T` as the environment `name`, built with
    /// [`MujocoEnv::make`] and truncated after `max_episode_steps` steps.
    ///
    /// Its sizes are the task's own constants, `T::OBS_DIM` and the actuator count
    /// `T::SIZES.nu` (checked against the model when the environment is built), so the
    /// registry describes it without building it: [`crate::registry::list`] and
    /// [`crate::registry::spec`] work without the MuJoCo library.
    ///
    /// ```
    /// use apo_envs::mujoco::tasks::Hopper;
    /// use apo_envs::registry::{self, Family};
    ///
    /// let mut family = Family::new("short-hoppers");
    /// for steps in [100, 200] {
    ///     family.add_task::<Hopper>(format!("HopperShort{steps}-v0"), steps);
    /// }
    /// registry::register(family)?;
    /// let spec = registry::spec("HopperShort100")?;
    /// assert_eq!((spec.observation_dim, spec.action_space.flat_dim()), (11, 3));
    /// # Ok::<(), apo_envs::EnvError>(())
    /// ```
    pub fn add_task<T: Task>(
        &mut self,
        name: impl Into<String>,
        max_episode_steps: usize,
    ) -> &mut Self {
        let name = name.into();
        let label = name.clone();
        let spaces = Spaces {
            observation_dim: T::OBS_DIM,
            // What RescaleAction makes of the actuators' box.
            action_space: Space::uniform_box(T::SIZES.nu, -1.0, 1.0),
        };
        self.add_sized(
            name,
            max_episode_steps,
            Box::new(move || build::<T>(&label)),
            spaces,
        )
    }
}

/// Builds the bare environment of task `T`, registered as `name`.
fn build<T: Task>(name: &str) -> Result<Box<dyn Env>, EnvError> {
    match MujocoEnv::<T>::make() {
        Ok(env) => Ok(Box::new(env)),
        Err(err) => Err(EnvError::Init {
            name: name.to_owned(),
            reason: err.to_string(),
        }),
    }
}

/// Adds task `T` to `family` as `<T::NAME>-v4`.
fn v4<T: Task>(family: &mut Family, max_episode_steps: usize) {
    family.add_task::<T>(format!("{}-v4", T::NAME), max_episode_steps);
}

/// The registry's `mujoco` family: the suite with Gymnasium v4's names and time limits.
pub(crate) fn family() -> Family {
    let mut family = Family::new("mujoco");
    v4::<InvertedPendulum>(&mut family, 1000);
    v4::<InvertedDoublePendulum>(&mut family, 1000);
    v4::<Reacher>(&mut family, 50);
    v4::<Swimmer>(&mut family, 1000);
    v4::<Hopper>(&mut family, 1000);
    v4::<HalfCheetah>(&mut family, 1000);
    v4::<Walker2d>(&mut family, 1000);
    v4::<Ant>(&mut family, 1000);
    v4::<Humanoid>(&mut family, 1000);
    v4::<HumanoidStandup>(&mut family, 1000);
    family
}
