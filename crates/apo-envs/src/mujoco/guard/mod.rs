//! GUARD: the Goal, Push and Chase tasks on seven robots, the paper's main continuous
//! benchmark, on MuJoCo 2.2.
//!
//! A suite is a [`TaskKind`] on a [`Robot`], registered as `<Task>_<Robot>` (`Goal_Point`,
//! `Push_Ant`, `Chase_Walker`, …) in the registry's `guard` family, with 1000-step episodes.
//! The 17 suites are generated from the task × robot grid ([`suites`]): Goal on all seven
//! robots, Push and Chase on the five floor robots.
//!
//! - [`GuardEnv`]: layouts, stepping, rewards and observations as GUARD's engine has them.
//! - [`sensing`]: the compass and the 2D and 3D pseudo-lidars as pure functions.
//! - The robots' models are this project's own MJCF files under `assets/guard/`.
//!
//! `docs/guard.md` lists every rule and constant with its source, and where we differ.

mod env;
mod layout;
mod robot;
pub mod sensing;

pub use env::{
    GuardEnv, BALL_RADIUS, CHASE_RANGE, GOAL_BONUS, GOAL_SIZE, GOAL_Z_2D, HAZARD3D_COUNT,
    HAZARD3D_RADIUS, REWARD_CLIP, ROBBER_COUNT, ROBBER_SPACING, ROBBER_SPEED, ROBBER_TRAVEL,
    SUBSTEPS, Z_RANGE_3D,
};
pub use robot::Robot;

use crate::error::EnvError;
use crate::family::{Family, Spaces};
use crate::space::Space;

/// GUARD's episode length.
pub const MAX_EPISODE_STEPS: usize = 1000;

/// What the robot must do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TaskKind {
    /// Reach goal after goal: reward the approach, +1 per goal reached.
    Goal,
    /// Push a ball to goal after goal: reward approaching the ball and the ball's approach to
    /// the goal, +1 per goal reached.
    Push,
    /// Catch the nearer of two fleeing robbers: reward closing the distance.
    Chase,
}

impl TaskKind {
    /// Every task.
    pub const ALL: [TaskKind; 3] = [TaskKind::Goal, TaskKind::Push, TaskKind::Chase];

    /// The name in suite names.
    pub fn name(self) -> &'static str {
        match self {
            TaskKind::Goal => "Goal",
            TaskKind::Push => "Push",
            TaskKind::Chase => "Chase",
        }
    }

    /// Whether the paper's benchmark has this task on `robot`: Goal on every robot, Push and
    /// Chase on the floor robots (not Arm3 or the Drone).
    pub fn has(self, robot: Robot) -> bool {
        self == TaskKind::Goal || !robot.goal_3d()
    }
}

/// A task on a robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Suite {
    /// The task.
    pub task: TaskKind,
    /// The robot.
    pub robot: Robot,
}

impl Suite {
    /// The registered name, `<Task>_<Robot>`.
    pub fn name(self) -> String {
        format!("{}_{}", self.task.name(), self.robot.name())
    }

    /// The observation length.
    pub fn observation_dim(self) -> usize {
        env::observation_dim(self)
    }

    /// The MJCF text of the suite's model: the robot's file, with the ball for Push (to look at
    /// it in MuJoCo's `simulate`, or to time it with `mujoco-testspeed`).
    pub fn mjcf(self) -> String {
        env::mjcf(self)
    }
}

/// The 17 suites of the task × robot grid, task-major.
pub fn suites() -> impl Iterator<Item = Suite> {
    TaskKind::ALL.into_iter().flat_map(|task| {
        Robot::ALL
            .into_iter()
            .filter(move |&robot| task.has(robot))
            .map(move |robot| Suite { task, robot })
    })
}

/// The registry's `guard` family: every suite, with its sizes stated (listing needs no MuJoCo).
pub(crate) fn family() -> Family {
    let mut family = Family::new("guard");
    for suite in suites() {
        let name = suite.name();
        let spaces = Spaces {
            observation_dim: suite.observation_dim(),
            action_space: Space::uniform_box(suite.robot.action_dim(), -1.0, 1.0),
        };
        family.add_sized(
            name.clone(),
            MAX_EPISODE_STEPS,
            Box::new(move || match GuardEnv::new(suite) {
                Ok(env) => Ok(Box::new(env) as Box<dyn crate::env::Env>),
                Err(err) => Err(EnvError::Init {
                    name: name.clone(),
                    reason: err.to_string(),
                }),
            }),
            spaces,
        );
    }
    family
}
