//! `CartPole-v1`: balance a pole on a cart (Barto, Sutton & Anderson 1983).

use rand::Rng;

use super::{discrete_action, symmetric_box, write_obs, Core};
use crate::env::{Action, Env, StepInfo, Transition};
use crate::render::{Camera, Frame, RenderError};
use crate::rng::EnvRng;
use crate::space::Space;

const GRAVITY: f64 = 9.8;
const MASS_CART: f64 = 1.0;
const MASS_POLE: f64 = 0.1;
const TOTAL_MASS: f64 = MASS_CART + MASS_POLE;
/// Half the pole's length.
const HALF_LENGTH: f64 = 0.5;
const POLE_MASS_LENGTH: f64 = MASS_POLE * HALF_LENGTH;
const FORCE_MAG: f64 = 10.0;
const TAU: f64 = 0.02;
/// The episode ends when the cart leaves `[-X_THRESHOLD, X_THRESHOLD]`.
const X_THRESHOLD: f64 = 2.4;
/// The episode ends when the pole leaves `[-THETA_THRESHOLD, THETA_THRESHOLD]` (12 degrees).
const THETA_THRESHOLD: f64 = 12.0 * 2.0 * std::f64::consts::PI / 360.0;

/// `CartPole-v1`: a pole hinged on a cart moving on a frictionless track.
///
/// - Observation `[x, ẋ, θ, θ̇]` in the box `±[4.8, f32::MAX, 24°, f32::MAX]`.
/// - Action `Discrete(2)`: 0 pushes the cart left with force 10 N, 1 pushes it right.
/// - Dynamics: explicit Euler with `tau = 0.02` s, gravity 9.8, cart 1 kg, pole 0.1 kg,
///   half-length 0.5 m.
/// - Reward 1 for every step, including the step that terminates (0 if stepped again after
///   termination without a reset, as in Gymnasium).
/// - Terminates when `|x| > 2.4` or `|θ| > 12°`; never truncates (use a time limit of 500).
/// - Reset: each state component uniform in `[-0.05, 0.05)`.
#[derive(Debug, Clone)]
pub struct CartPole {
    core: Core<4>,
    terminated: bool,
}

impl CartPole {
    /// A cart-pole with an entropy-seeded RNG and a random initial state; call
    /// [`Env::reset`] to start an episode.
    pub fn new() -> Self {
        let high = [
            (2.0 * X_THRESHOLD) as f32,
            f32::MAX,
            (2.0 * THETA_THRESHOLD) as f32,
            f32::MAX,
        ];
        Self {
            core: Core::new(symmetric_box(&high), Space::Discrete { n: 2 }, sample_state),
            terminated: false,
        }
    }

    /// The physical state `[x, ẋ, θ, θ̇]`.
    pub fn state(&self) -> [f64; 4] {
        self.core.state
    }

    /// Sets the physical state `[x, ẋ, θ, θ̇]` (for tests and demonstrations) and clears the
    /// terminated flag.
    pub fn set_state(&mut self, state: [f64; 4]) {
        self.core.state = state;
        self.terminated = false;
    }
}

/// The reset distribution: each component uniform in `[-0.05, 0.05)`.
fn sample_state(rng: &mut EnvRng) -> [f64; 4] {
    std::array::from_fn(|_| rng.random_range(-0.05..0.05))
}

impl Default for CartPole {
    fn default() -> Self {
        Self::new()
    }
}

impl Env for CartPole {
    fn observation_space(&self) -> &Space {
        &self.core.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.core.action_space
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.core.reset(seed, sample_state);
        self.terminated = false;
        write_obs(obs, self.core.state);
    }

    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let force = if discrete_action(action, 2, "CartPole") == 1 {
            FORCE_MAG
        } else {
            -FORCE_MAG
        };
        let [x, x_dot, theta, theta_dot] = self.core.state;
        let (sin, cos) = theta.sin_cos();
        let temp = (force + POLE_MASS_LENGTH * theta_dot * theta_dot * sin) / TOTAL_MASS;
        let theta_acc = (GRAVITY * sin - cos * temp)
            / (HALF_LENGTH * (4.0 / 3.0 - MASS_POLE * cos * cos / TOTAL_MASS));
        let x_acc = temp - POLE_MASS_LENGTH * theta_acc * cos / TOTAL_MASS;
        self.core.state = [
            x + TAU * x_dot,
            x_dot + TAU * x_acc,
            theta + TAU * theta_dot,
            theta_dot + TAU * theta_acc,
        ];
        let [x, _, theta, _] = self.core.state;
        let terminated = !(-X_THRESHOLD..=X_THRESHOLD).contains(&x)
            || !(-THETA_THRESHOLD..=THETA_THRESHOLD).contains(&theta);
        // Gymnasium pays 1 up to and including the terminating step, 0 for steps after it.
        let reward = if self.terminated { 0.0 } else { 1.0 };
        self.terminated |= terminated;
        write_obs(obs, self.core.state);
        Transition {
            reward,
            terminated,
            truncated: false,
            info: StepInfo::default(),
        }
    }

    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        super::draw::cartpole(self.core.state, camera, frame)
    }
}
