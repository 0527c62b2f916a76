//! `Pendulum-v1`: swing up an inverted pendulum and keep it upright.

use std::f64::consts::PI;

use rand::Rng;

use super::continuous_action;
use crate::env::{Action, Env, StepInfo, Transition};
use crate::rng::{entropy_rng, reseed, EnvRng};
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
    state: [f64; 2],
    rng: EnvRng,
    observation_space: Space,
    action_space: Space,
}

impl Pendulum {
    /// A pendulum with an entropy-seeded RNG and a random initial state; call [`Env::reset`]
    /// to start an episode.
    pub fn new() -> Self {
        let high = [1.0, 1.0, MAX_SPEED as f32];
        let mut env = Self {
            state: [0.0; 2],
            rng: entropy_rng(),
            observation_space: Space::Box {
                low: high.iter().map(|h| -h).collect(),
                high: high.to_vec(),
            },
            action_space: Space::uniform_box(1, -MAX_TORQUE as f32, MAX_TORQUE as f32),
        };
        env.sample_state();
        env
    }

    /// The physical state `[θ, θ̇]`.
    pub fn state(&self) -> [f64; 2] {
        self.state
    }

    /// Sets the physical state `[θ, θ̇]` (for tests and demonstrations).
    pub fn set_state(&mut self, state: [f64; 2]) {
        self.state = state;
    }

    fn sample_state(&mut self) {
        self.state = [
            self.rng.random_range(-PI..PI),
            self.rng.random_range(-1.0..1.0),
        ];
    }

    fn write_obs(&self, obs: &mut [f32]) {
        let [theta, theta_dot] = self.state;
        let values = [theta.cos(), theta.sin(), theta_dot];
        for (o, v) in obs.iter_mut().zip(values) {
            *o = v as f32;
        }
    }
}

impl Default for Pendulum {
    fn default() -> Self {
        Self::new()
    }
}

/// `x` wrapped into `[-π, π)` (Gymnasium's `angle_normalize`).
fn angle_normalize(x: f64) -> f64 {
    (x + PI).rem_euclid(2.0 * PI) - PI
}

impl Env for Pendulum {
    fn observation_space(&self) -> &Space {
        &self.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.action_space
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        reseed(&mut self.rng, seed);
        self.sample_state();
        self.write_obs(obs);
    }

    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let u =
            f64::from(continuous_action(action, 1, "Pendulum")[0]).clamp(-MAX_TORQUE, MAX_TORQUE);
        let [theta, theta_dot] = self.state;
        let cost = angle_normalize(theta).powi(2) + 0.1 * (theta_dot * theta_dot) + 0.001 * (u * u);
        let new_theta_dot = (theta_dot
            + (3.0 * GRAVITY / (2.0 * LENGTH) * theta.sin() + 3.0 / (MASS * LENGTH * LENGTH) * u)
                * DT)
            .clamp(-MAX_SPEED, MAX_SPEED);
        self.state = [theta + new_theta_dot * DT, new_theta_dot];
        let unstable = !self.state.iter().all(|s| s.is_finite());
        self.write_obs(obs);
        Transition {
            reward: -cost,
            terminated: unstable,
            truncated: false,
            info: StepInfo { unstable },
        }
    }
}
