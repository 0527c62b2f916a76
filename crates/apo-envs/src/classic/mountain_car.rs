//! `MountainCarContinuous-v0`: drive an under-powered car up a hill (Moore 1990).

use rand::Rng;

use super::{continuous_action, write_obs, Core};
use crate::env::{Action, Env, StepInfo, Transition};
use crate::render::{Camera, Frame, RenderError};
use crate::rng::EnvRng;
use crate::space::Space;

const MIN_ACTION: f64 = -1.0;
const MAX_ACTION: f64 = 1.0;
const MIN_POSITION: f64 = -1.2;
const MAX_POSITION: f64 = 0.6;
const MAX_SPEED: f64 = 0.07;
const GOAL_POSITION: f64 = 0.45;
const GOAL_VELOCITY: f64 = 0.0;
const POWER: f64 = 0.0015;

/// `MountainCarContinuous-v0`: a car in a valley whose engine is too weak to climb the right
/// hill directly; it must rock back and forth to reach the flag at position 0.45.
///
/// - Observation `[position, velocity]` in `[-1.2, 0.6] × [-0.07, 0.07]`.
/// - Action `Box[-1, 1]` (one force), clipped to the bounds for the dynamics.
/// - Dynamics: `v' = clip(v + a·0.0015 − 0.0025 cos(3x), ±0.07)`, `x' = clip(x + v', −1.2, 0.6)`,
///   and `v' = 0` when the car hits the left wall moving left. As in Gymnasium, the state is
///   stored at `f32` precision after each step.
/// - Reward `−0.1 a²` of the action as given (not clipped, as in Gymnasium), plus 100 on the
///   step that reaches the goal.
/// - Terminates when `x' ≥ 0.45` and `v' ≥ 0`; never truncates (use a time limit of 999).
///   A non-finite action ends the episode with `terminated` and `info.unstable`.
/// - Reset: `x ~ U(−0.6, −0.4)`, `v = 0`.
#[derive(Debug, Clone)]
pub struct MountainCarContinuous {
    core: Core<2>,
}

impl MountainCarContinuous {
    /// A mountain car with an entropy-seeded RNG and a random initial state; call
    /// [`Env::reset`] to start an episode.
    pub fn new() -> Self {
        Self {
            core: Core::new(
                Space::Box {
                    low: vec![MIN_POSITION as f32, -MAX_SPEED as f32],
                    high: vec![MAX_POSITION as f32, MAX_SPEED as f32],
                    shape: vec![2],
                },
                Space::uniform_box(1, MIN_ACTION as f32, MAX_ACTION as f32),
                sample_state,
            ),
        }
    }

    /// The physical state `[position, velocity]`.
    pub fn state(&self) -> [f64; 2] {
        self.core.state
    }

    /// Sets the physical state `[position, velocity]` (for tests and demonstrations).
    pub fn set_state(&mut self, state: [f64; 2]) {
        self.core.state = state;
    }
}

/// The reset distribution: `x ~ U(−0.6, −0.4)`, `v = 0`.
fn sample_state(rng: &mut EnvRng) -> [f64; 2] {
    [rng.random_range(-0.6..-0.4), 0.0]
}

impl Default for MountainCarContinuous {
    fn default() -> Self {
        Self::new()
    }
}

impl Env for MountainCarContinuous {
    fn observation_space(&self) -> &Space {
        &self.core.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.core.action_space
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.core.reset(seed, sample_state);
        write_obs(obs, self.core.state);
    }

    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let a = f64::from(continuous_action(action, 1, "MountainCarContinuous")[0]);
        let force = a.clamp(MIN_ACTION, MAX_ACTION);
        let [position, velocity] = self.core.state;
        let mut velocity = (velocity + (force * POWER - 0.0025 * (3.0 * position).cos()))
            .clamp(-MAX_SPEED, MAX_SPEED);
        let position = (position + velocity).clamp(MIN_POSITION, MAX_POSITION);
        if position == MIN_POSITION && velocity < 0.0 {
            velocity = 0.0;
        }
        let reached = position >= GOAL_POSITION && velocity >= GOAL_VELOCITY;
        let unstable = !(position.is_finite() && velocity.is_finite());
        let reward = if reached { 100.0 } else { 0.0 } - a * a * 0.1;
        self.core.state = [f64::from(position as f32), f64::from(velocity as f32)];
        write_obs(obs, self.core.state);
        Transition {
            reward,
            terminated: reached || unstable,
            truncated: false,
            info: StepInfo {
                unstable,
                success: None,
            },
        }
    }

    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        super::draw::mountain_car(
            self.core.state,
            [MIN_POSITION, MAX_POSITION],
            GOAL_POSITION,
            camera,
            frame,
        )
    }
}
