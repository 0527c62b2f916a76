//! Classic-control environments in pure Rust, matching Gymnasium's published dynamics,
//! rewards, termination rules, reset distributions and observation layouts.
//!
//! | environment | observation | action | reward | ends when |
//! | --- | --- | --- | --- | --- |
//! | [`CartPole`] (`CartPole-v1`) | 4 | `Discrete(2)` | 1 per step, the terminating one included | pole past 12° or cart past 2.4 |
//! | [`Acrobot`] (`Acrobot-v1`) | 6 | `Discrete(3)` | −1, 0 on the terminating step | tip above the bar |
//! | [`Pendulum`] (`Pendulum-v1`) | 3 | `Box[-2, 2]` | −(θ² + 0.1 θ̇² + 0.001 u²) | never |
//! | [`MountainCarContinuous`] (`MountainCarContinuous-v0`) | 2 | `Box[-1, 1]` | −0.1 a², +100 at the goal | position ≥ 0.45 with velocity ≥ 0 |
//!
//! The environments never truncate: time limits come from [`crate::wrappers::TimeLimit`]
//! (the registry in [`crate::registry`] applies Gymnasium's limits). The state is kept in `f64`
//! and the observation written as `f32`. Each environment owns an [`crate::rng::EnvRng`]:
//! `reset(Some(seed), …)` gives the same episode for the same seed.

mod acrobot;
mod cartpole;
mod draw;
mod mountain_car;
mod pendulum;

pub use acrobot::Acrobot;
pub use cartpole::CartPole;
pub use mountain_car::MountainCarContinuous;
pub use pendulum::Pendulum;

use crate::env::Action;
use crate::family::Family;
use crate::rng::{entropy_rng, reseed, EnvRng};
use crate::space::Space;

/// The registry's `classic` family, with Gymnasium's names and time limits.
pub(crate) fn family() -> Family {
    let mut family = Family::new("classic");
    family
        .add("CartPole-v1", 500, || Ok(Box::new(CartPole::new())))
        .add("Acrobot-v1", 500, || Ok(Box::new(Acrobot::new())))
        .add("Pendulum-v1", 200, || Ok(Box::new(Pendulum::new())))
        .add("MountainCarContinuous-v0", 999, || {
            Ok(Box::new(MountainCarContinuous::new()))
        });
    family
}

/// What every classic-control environment owns besides its own flags: the physical state,
/// the RNG and the two spaces. The reset distribution is the environment's `sample` function.
#[derive(Debug, Clone)]
struct Core<const N: usize> {
    /// The physical state.
    state: [f64; N],
    rng: EnvRng,
    observation_space: Space,
    action_space: Space,
}

impl<const N: usize> Core<N> {
    /// A core with an entropy-seeded RNG and an initial state drawn by `sample`.
    fn new(
        observation_space: Space,
        action_space: Space,
        sample: fn(&mut EnvRng) -> [f64; N],
    ) -> Self {
        let mut rng = entropy_rng();
        Core {
            state: sample(&mut rng),
            rng,
            observation_space,
            action_space,
        }
    }

    /// The state part of [`crate::Env::reset`]: applies `seed` (see [`reseed`]) and draws a
    /// new state with `sample`.
    fn reset(&mut self, seed: Option<u64>, sample: fn(&mut EnvRng) -> [f64; N]) {
        reseed(&mut self.rng, seed);
        self.state = sample(&mut self.rng);
    }
}

/// The box `[-high, high]`.
fn symmetric_box(high: &[f32]) -> Space {
    Space::Box {
        low: high.iter().map(|h| -h).collect(),
        high: high.to_vec(),
        shape: vec![high.len()],
    }
}

/// Writes `values` into the observation buffer `obs` as `f32`.
fn write_obs(obs: &mut [f32], values: impl IntoIterator<Item = f64>) {
    for (o, v) in obs.iter_mut().zip(values) {
        *o = v as f32;
    }
}

/// The index of a discrete `action` for an environment with `n` actions.
///
/// # Panics
/// If `action` is not `Action::Discrete(i)` with `i < n`: passing an action outside the
/// action space breaks the [`crate::Env::step`] contract.
pub(crate) fn discrete_action(action: Action<'_>, n: usize, env: &str) -> usize {
    match action {
        Action::Discrete(i) if i < n => i,
        other => panic!("{env}: expected a discrete action in 0..{n}, got {other:?}"),
    }
}

/// The slice of a continuous `action` of dimension `dim`.
///
/// # Panics
/// If `action` is not `Action::Continuous` of length `dim`.
pub(crate) fn continuous_action<'a>(action: Action<'a>, dim: usize, env: &str) -> &'a [f32] {
    match action {
        Action::Continuous(a) if a.len() == dim => a,
        other => panic!("{env}: expected a continuous action of dimension {dim}, got {other:?}"),
    }
}
