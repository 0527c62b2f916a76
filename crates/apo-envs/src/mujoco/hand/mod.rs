//! The Shadow Dexterous Hand tasks of Gymnasium-Robotics with dense rewards, on MuJoCo 2.2:
//! `HandReachDense-v3`, `HandManipulateBlockDense-v1` and `HandManipulateEggDense-v1`
//! (Plappert et al. 2018, "Multi-Goal Reinforcement Learning: Challenging Robotics Environments
//! and Request for Research").
//!
//! - [`HandTask::Reach`]: bring the thumb and a random finger together above the palm (or keep
//!   the start pose). Reward `−‖achieved − desired‖` over the 15 fingertip coordinates; 50-step
//!   episodes.
//! - [`HandTask::Block`], [`HandTask::Egg`]: move and turn the object lying on the palm to a
//!   random pose (Gymnasium's `Full` variants: `target_position="random"`,
//!   `target_rotation="xyz"`). Reward `−(10·d_pos + d_rot)`; 100-step episodes.
//!
//! Every task has 20 actions in `[−1, 1]` (absolute joint targets: each maps linearly onto its
//! actuator's control range) and 20 simulator steps of 0.002 s per action (25 Hz). Episodes
//! never end by themselves (the registry adds the time limit), except when the simulator becomes
//! unstable. Success (`is_success` in Gymnasium's `info`) is [`HandEnv::is_success`], since
//! [`crate::Transition`] carries no info dictionary.
//!
//! Gymnasium's observation is a dictionary (`observation`, `achieved_goal`, `desired_goal`);
//! [`HandObservation`] says what the flat observation holds:
//!
//! | registered name | observation | width | episode |
//! |---|---|---|---|
//! | `HandReachDense-v3` | `observation` | 63 | 50 |
//! | `HandReachDenseGoal-v3` | `observation ‖ desired_goal` | 78 | 50 |
//! | `HandManipulateBlockDense-v1` | `observation` | 61 | 100 |
//! | `HandManipulateBlockDenseGoal-v1` | `observation ‖ desired_goal` | 68 | 100 |
//! | `HandManipulateEggDense-v1` | `observation` | 61 | 100 |
//! | `HandManipulateEggDenseGoal-v1` | `observation ‖ desired_goal` | 68 | 100 |
//!
//! The paper's runs reset every episode with the run's seed, so that every episode has the same
//! start and goal: that is apo's [`FixedReset`](crate::FixedReset) wrapper, chosen in a run's
//! configuration with `episode_reset = "run_seed"` (or [`crate::MakeOptions::fixed_reset_seed`]).
//!
//! The models are this project's own MJCF files under `assets/hand/`. `docs/hand.md` lists every
//! fact used here (model, control, resets, goals, rewards, observations) with its source.

mod env;
mod quat;

pub use env::{
    HandEnv, ACTIONS, ACTUATORS, DISTANCE_THRESHOLD, FINGERTIPS, INITIAL_GOAL_PROBABILITY, JOINTS,
    MEETING_GAP, MEETING_NOISE, MEETING_OFFSET, PALM_HEIGHT, POSITION_NOISE, POSITION_WEIGHT,
    REACH_INITIAL_QPOS, RESET_TRIES, ROBOT_JOINTS, ROTATION_THRESHOLD, SETTLE_ACTIONS, SUBSTEPS,
    TARGET_POSITION_RANGE,
};

use crate::env::Env;
use crate::error::EnvError;
use crate::family::{Family, Spaces};
use crate::space::Space;

/// One of the three hand tasks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HandTask {
    /// HandReach: the fingertips reach a 15-coordinate goal (Gymnasium v3).
    Reach,
    /// HandManipulateBlock (`Full`): the cube reaches a goal position and orientation
    /// (Gymnasium v1).
    Block,
    /// HandManipulateEgg (`Full`): the egg reaches a goal position and orientation
    /// (Gymnasium v1).
    Egg,
}

impl HandTask {
    /// Every task.
    pub const ALL: [HandTask; 3] = [HandTask::Reach, HandTask::Block, HandTask::Egg];

    /// Gymnasium's name without the reward type and version (`HandReach`).
    pub fn name(self) -> &'static str {
        match self {
            HandTask::Reach => "HandReach",
            HandTask::Block => "HandManipulateBlock",
            HandTask::Egg => "HandManipulateEgg",
        }
    }

    /// Gymnasium's version of the task: 3 for Reach (the start pose is the documented one), 1
    /// for the manipulate tasks (the MuJoCo bindings).
    pub fn version(self) -> u32 {
        match self {
            HandTask::Reach => 3,
            HandTask::Block | HandTask::Egg => 1,
        }
    }

    /// Gymnasium's registered time limit: 50 (Reach), 100 (the manipulate tasks).
    pub fn max_episode_steps(self) -> usize {
        match self {
            HandTask::Reach => 50,
            HandTask::Block | HandTask::Egg => 100,
        }
    }

    /// Whether the task moves an object (Block, Egg).
    pub fn manipulates(self) -> bool {
        self != HandTask::Reach
    }

    /// The length of a goal: the 5 fingertip positions (15), or the object's position and
    /// quaternion `(w, x, y, z)` (7).
    pub fn goal_dim(self) -> usize {
        if self.manipulates() {
            7
        } else {
            15
        }
    }

    /// The observation length: robot `qpos` (24) and `qvel` (24), the object's `qvel` (6, the
    /// manipulate tasks), the achieved goal, then the desired goal with
    /// [`HandObservation::GoalConditioned`]: 63 / 78 (Reach), 61 / 68 (Block, Egg).
    pub fn observation_dim(self, observation: HandObservation) -> usize {
        let object = if self.manipulates() { 6 } else { 0 };
        let desired = match observation {
            HandObservation::Paper => 0,
            HandObservation::GoalConditioned => self.goal_dim(),
        };
        2 * ROBOT_JOINTS + object + self.goal_dim() + desired
    }

    /// The registered name: `HandReachDense-v3`, `HandManipulateBlockDenseGoal-v1`, ...
    pub fn registered_name(self, observation: HandObservation) -> String {
        format!(
            "{}Dense{}-v{}",
            self.name(),
            observation.suffix(),
            self.version()
        )
    }

    /// The MJCF text of the task's scene (embedded).
    pub fn mjcf(self) -> &'static str {
        match self {
            HandTask::Reach => include_str!("../../../assets/hand/reach.xml"),
            HandTask::Block => include_str!("../../../assets/hand/manipulate_block.xml"),
            HandTask::Egg => include_str!("../../../assets/hand/manipulate_egg.xml"),
        }
    }
}

/// What the flat observation holds of Gymnasium's observation dictionary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HandObservation {
    /// Only the dictionary's `observation` (robot state, object velocity, achieved goal), as the
    /// paper's runs fed it: the goal itself is not observed.
    Paper,
    /// `observation ‖ desired_goal`, for a goal-conditioned policy.
    GoalConditioned,
}

impl HandObservation {
    /// Both modes.
    pub const ALL: [HandObservation; 2] =
        [HandObservation::Paper, HandObservation::GoalConditioned];

    /// What the mode adds to the name before the version: nothing, or `Goal`.
    pub fn suffix(self) -> &'static str {
        match self {
            HandObservation::Paper => "",
            HandObservation::GoalConditioned => "Goal",
        }
    }
}

/// The registry's `hand` family: each task with both observations, with its sizes stated (listing
/// needs no MuJoCo).
pub(crate) fn family() -> Family {
    let mut family = Family::new("hand");
    for task in HandTask::ALL {
        for observation in HandObservation::ALL {
            let name = task.registered_name(observation);
            let spaces = Spaces {
                observation_dim: task.observation_dim(observation),
                // The environment's own action space, which RescaleAction leaves as it is.
                action_space: Space::uniform_box(ACTIONS, -1.0, 1.0),
            };
            let label = name.clone();
            family.add_sized(
                name,
                task.max_episode_steps(),
                Box::new(move || match HandEnv::new(task, observation) {
                    Ok(env) => Ok(Box::new(env) as Box<dyn Env>),
                    Err(err) => Err(EnvError::Init {
                        name: label.clone(),
                        reason: err.to_string(),
                    }),
                }),
                spaces,
            );
        }
    }
    family
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_widths_and_limits_are_gymnasium_roboticss() {
        let table: Vec<(String, usize, usize)> = HandTask::ALL
            .into_iter()
            .flat_map(|task| {
                HandObservation::ALL.into_iter().map(move |observation| {
                    (
                        task.registered_name(observation),
                        task.observation_dim(observation),
                        task.max_episode_steps(),
                    )
                })
            })
            .collect();
        let expected = [
            ("HandReachDense-v3", 63, 50),
            ("HandReachDenseGoal-v3", 78, 50),
            ("HandManipulateBlockDense-v1", 61, 100),
            ("HandManipulateBlockDenseGoal-v1", 68, 100),
            ("HandManipulateEggDense-v1", 61, 100),
            ("HandManipulateEggDenseGoal-v1", 68, 100),
        ];
        assert_eq!(table.len(), expected.len());
        for ((name, dim, steps), (want_name, want_dim, want_steps)) in table.iter().zip(expected) {
            assert_eq!(
                (name.as_str(), *dim, *steps),
                (want_name, want_dim, want_steps)
            );
        }
    }

    #[test]
    fn the_family_states_every_member() {
        let members = family().into_members();
        assert_eq!(members.len(), 6);
        for member in &members {
            assert_eq!(&*member.family, "hand");
        }
    }
}
