//! `Acrobot-v1`: swing up a two-link pendulum actuated at the elbow (Sutton 1996).

use std::f64::consts::PI;

use rand::Rng;

use super::{discrete_action, symmetric_box, write_obs, Core};
use crate::env::{Action, Env, StepInfo, Transition};
use crate::render::{Camera, Frame, RenderError};
use crate::rng::EnvRng;
use crate::space::Space;

const DT: f64 = 0.2;
const LINK_LENGTH_1: f64 = 1.0;
const LINK_MASS_1: f64 = 1.0;
const LINK_MASS_2: f64 = 1.0;
const LINK_COM_POS_1: f64 = 0.5;
const LINK_COM_POS_2: f64 = 0.5;
const LINK_MOI: f64 = 1.0;
const GRAVITY: f64 = 9.8;
/// Bound of the first joint's angular velocity.
const MAX_VEL_1: f64 = 4.0 * PI;
/// Bound of the second joint's angular velocity.
const MAX_VEL_2: f64 = 9.0 * PI;
/// Torque applied at the elbow for actions 0, 1, 2.
const TORQUES: [f64; 3] = [-1.0, 0.0, 1.0];

/// `Acrobot-v1`: two links hanging down from a fixed pivot, torque applied at the joint between
/// them; the goal is to swing the tip above a line one link length above the pivot.
///
/// - State `[θ1, θ2, θ̇1, θ̇2]`: θ1 is the first link's angle from hanging down, θ2 the second
///   link's angle relative to the first.
/// - Observation `[cos θ1, sin θ1, cos θ2, sin θ2, θ̇1, θ̇2]` in `±[1, 1, 1, 1, 4π, 9π]`.
/// - Action `Discrete(3)`: torque −1, 0 or +1 at the elbow.
/// - Dynamics: the book version of the equations (Sutton & Barto), one classical RK4 step of
///   `dt = 0.2` s; angles then wrapped to `[-π, π]`, velocities clipped to `±4π` and `±9π`.
///   Links of 1 m and 1 kg, centres of mass at 0.5 m, moments of inertia 1, gravity 9.8.
/// - Reward −1 per step, 0 on the terminating step.
/// - Terminates when `−cos θ1 − cos(θ1 + θ2) > 1`; never truncates (use a time limit of 500).
/// - Reset: each state component uniform in `[-0.1, 0.1)`, rounded to `f32` as Gymnasium does.
#[derive(Debug, Clone)]
pub struct Acrobot {
    core: Core<4>,
}

impl Acrobot {
    /// An acrobot with an entropy-seeded RNG and a random initial state; call [`Env::reset`]
    /// to start an episode.
    pub fn new() -> Self {
        let high = [1.0, 1.0, 1.0, 1.0, MAX_VEL_1 as f32, MAX_VEL_2 as f32];
        Self {
            core: Core::new(symmetric_box(&high), Space::Discrete { n: 3 }, sample_state),
        }
    }

    /// The physical state `[θ1, θ2, θ̇1, θ̇2]`.
    pub fn state(&self) -> [f64; 4] {
        self.core.state
    }

    /// Sets the physical state `[θ1, θ2, θ̇1, θ̇2]` (for tests and demonstrations).
    pub fn set_state(&mut self, state: [f64; 4]) {
        self.core.state = state;
    }

    fn observe(&self, obs: &mut [f32]) {
        let [t1, t2, dt1, dt2] = self.core.state;
        write_obs(obs, [t1.cos(), t1.sin(), t2.cos(), t2.sin(), dt1, dt2]);
    }
}

impl Default for Acrobot {
    fn default() -> Self {
        Self::new()
    }
}

/// The reset distribution: each component uniform in `[-0.1, 0.1)`, rounded to `f32`.
fn sample_state(rng: &mut EnvRng) -> [f64; 4] {
    std::array::from_fn(|_| f64::from(rng.random_range(-0.1..0.1f64) as f32))
}

/// Time derivative of `[θ1, θ2, θ̇1, θ̇2]` under elbow torque `torque` (book dynamics).
fn derivative(s: [f64; 4], torque: f64) -> [f64; 4] {
    let (m1, m2, l1, lc1, lc2, i1, i2) = (
        LINK_MASS_1,
        LINK_MASS_2,
        LINK_LENGTH_1,
        LINK_COM_POS_1,
        LINK_COM_POS_2,
        LINK_MOI,
        LINK_MOI,
    );
    let [theta1, theta2, dtheta1, dtheta2] = s;
    let (sin2, cos2) = theta2.sin_cos();
    let d1 = m1 * lc1 * lc1 + m2 * (l1 * l1 + lc2 * lc2 + 2.0 * l1 * lc2 * cos2) + i1 + i2;
    let d2 = m2 * (lc2 * lc2 + l1 * lc2 * cos2) + i2;
    let phi2 = m2 * lc2 * GRAVITY * (theta1 + theta2 - PI / 2.0).cos();
    let phi1 = -m2 * l1 * lc2 * dtheta2 * dtheta2 * sin2
        - 2.0 * m2 * l1 * lc2 * dtheta2 * dtheta1 * sin2
        + (m1 * lc1 + m2 * l1) * GRAVITY * (theta1 - PI / 2.0).cos()
        + phi2;
    let ddtheta2 = (torque + d2 / d1 * phi1 - m2 * l1 * lc2 * dtheta1 * dtheta1 * sin2 - phi2)
        / (m2 * lc2 * lc2 + i2 - d2 * d2 / d1);
    let ddtheta1 = -(d2 * ddtheta2 + phi1) / d1;
    [dtheta1, dtheta2, ddtheta1, ddtheta2]
}

/// `y + h * k`, componentwise.
fn axpy(y: [f64; 4], h: f64, k: [f64; 4]) -> [f64; 4] {
    std::array::from_fn(|i| y[i] + h * k[i])
}

/// One classical Runge–Kutta step of length `DT`.
fn rk4(y: [f64; 4], torque: f64) -> [f64; 4] {
    let k1 = derivative(y, torque);
    let k2 = derivative(axpy(y, DT / 2.0, k1), torque);
    let k3 = derivative(axpy(y, DT / 2.0, k2), torque);
    let k4 = derivative(axpy(y, DT, k3), torque);
    std::array::from_fn(|i| y[i] + DT / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
}

/// Wraps `x` into `[-π, π]` by whole turns, as Gymnasium's `wrap`.
fn wrap_angle(mut x: f64) -> f64 {
    while x > PI {
        x -= 2.0 * PI;
    }
    while x < -PI {
        x += 2.0 * PI;
    }
    x
}

impl Env for Acrobot {
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
        let torque = TORQUES[discrete_action(action, 3, "Acrobot")];
        let [t1, t2, dt1, dt2] = rk4(self.core.state, torque);
        self.core.state = [
            wrap_angle(t1),
            wrap_angle(t2),
            dt1.clamp(-MAX_VEL_1, MAX_VEL_1),
            dt2.clamp(-MAX_VEL_2, MAX_VEL_2),
        ];
        let [t1, t2, ..] = self.core.state;
        let terminated = -t1.cos() - (t1 + t2).cos() > 1.0;
        self.observe(obs);
        Transition {
            reward: if terminated { 0.0 } else { -1.0 },
            terminated,
            truncated: false,
            info: StepInfo::default(),
        }
    }

    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        super::draw::acrobot(self.core.state, camera, frame)
    }
}
