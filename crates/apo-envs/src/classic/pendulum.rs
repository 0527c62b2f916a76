//! `Pendulum-v1`: swing up an inverted pendulum and keep it upright.

use std::f64::consts::PI;

use rand::Rng;

use super::{continuous_action, symmetric_box, write_obs, Core};
use crate::env::{Action, Env, StepInfo, Transition};
use crate::render::{Camera, Frame, RenderError};
use crate::rng::EnvRng;
use crate::space::Space;

const MAX_SPEED: f64 = 8.0;
const MAX_TORQUE: f64 = 2.0;
const DT: f64 = 0.05;
const GRAVITY: f64 = 10.0;
const MASS: f64 = 1.0;
const LENGTH: f64 = 1.0;

/// `Pendulum-v1`: a frictionless pendulum of mass 1 and length 1 under gravity 10, torque at
/// the pivot; θ = 0 is upright.
///
/// - State `[θ, θ̇]`; observation `[cos θ, sin θ, θ̇]` in `±[1, 1, 8]`.
/// - Action `Box[-2, 2]` (one torque), clipped to the bounds before use.
/// - Dynamics (semi-implicit Euler, `dt = 0.05`):
///   `θ̇' = clip(θ̇ + (3g/(2l) sin θ + 3/(m l²) u) dt, −8, 8)`, `θ' = θ + θ̇' dt`.
/// - Reward `−(norm(θ)² + 0.1 θ̇² + 0.001 u²)` on the state before the step, with
///   `norm(θ)` the angle wrapped into `[-π, π)`.
/// - Never terminates nor truncates (use a time limit of 200). A non-finite action that makes
///   the state non-finite ends the episode with `terminated` and `info.unstable`.
/// - Reset: `θ ~ U(−π, π)`, `θ̇ ~ U(−1, 1)`.
#[derive(Debug, Clone)]
pub struct Pendulum {
    core: Core<2>,
}

impl Pendulum {
    /// A pendulum with an entropy-seeded RNG and a random initial state; call [`Env::reset`]
    /// to start an episode.
    pub fn new() -> Self {
        Self {
            core: Core::new(
                symmetric_box(&[1.0, 1.0, MAX_SPEED as f32]),
                Space::uniform_box(1, -MAX_TORQUE as f32, MAX_TORQUE as f32),
                sample_state,
            ),
        }
    }

    /// The physical state `[θ, θ̇]`.
    pub fn state(&self) -> [f64; 2] {
        self.core.state
    }

    /// Sets the physical state `[θ, θ̇]` (for tests and demonstrations).
    pub fn set_state(&mut self, state: [f64; 2]) {
        self.core.state = state;
    }

    fn observe(&self, obs: &mut [f32]) {
        let [theta, theta_dot] = self.core.state;
        write_obs(obs, [theta.cos(), theta.sin(), theta_dot]);
    }
}

impl Default for Pendulum {
    fn default() -> Self {
        Self::new()
    }
}

/// The reset distribution: `θ ~ U(−π, π)`, `θ̇ ~ U(−1, 1)`.
fn sample_state(rng: &mut EnvRng) -> [f64; 2] {
    [rng.random_range(-PI..PI), rng.random_range(-1.0..1.0)]
}

/// `x` wrapped into `[-π, π)` (Gymnasium's `angle_normalize`).
fn angle_normalize(x: f64) -> f64 {
    (x + PI).rem_euclid(2.0 * PI) - PI
}

impl Env for Pendulum {
    fn observation_space(&self) -> &Space {
        &self.core.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.core.action_space
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.core.reset(seed, sample_state);
        self.observe(obs);
    }

    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let u =
            f64::from(continuous_action(action, 1, "Pendulum")[0]).clamp(-MAX_TORQUE, MAX_TORQUE);
        let [theta, theta_dot] = self.core.state;
        let cost = angle_normalize(theta).powi(2) + 0.1 * (theta_dot * theta_dot) + 0.001 * (u * u);
        let new_theta_dot = (theta_dot
            + (3.0 * GRAVITY / (2.0 * LENGTH) * theta.sin() + 3.0 / (MASS * LENGTH * LENGTH) * u)
                * DT)
            .clamp(-MAX_SPEED, MAX_SPEED);
        self.core.state = [theta + new_theta_dot * DT, new_theta_dot];
        let unstable = !self.core.state.iter().all(|s| s.is_finite());
        self.observe(obs);
        Transition {
            reward: -cost,
            terminated: unstable,
            truncated: false,
            info: StepInfo {
                unstable,
                success: None,
            },
        }
    }

    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        super::draw::pendulum(self.core.state, camera, frame)
    }
}
