//! A line of the environment registry's static tables ([`crate::registry`]): what a family
//! of environments (classic control, MuJoCo) states about each of its environments.

use crate::env::Env;
use crate::error::EnvError;

/// The action space of a registry entry, in a form a static table can hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Act {
    /// `n` discrete actions.
    Discrete(usize),
    /// A box of this dimension, presented to the policy as `[-1, 1]^d`.
    Continuous(usize),
}

/// A constructor of a bare environment (no time limit, actions in the environment's bounds).
pub(crate) type Build = fn() -> Result<Box<dyn Env>, EnvError>;

/// One registered environment.
#[derive(Debug)]
pub(crate) struct Entry {
    pub(crate) name: &'static str,
    pub(crate) observation_dim: usize,
    pub(crate) action: Act,
    pub(crate) max_episode_steps: usize,
    pub(crate) build: Build,
}

/// A table line: `entry(name, observation_dim, action, max_episode_steps, constructor)`.
pub(crate) const fn entry(
    name: &'static str,
    observation_dim: usize,
    action: Act,
    max_episode_steps: usize,
    build: Build,
) -> Entry {
    Entry {
        name,
        observation_dim,
        action,
        max_episode_steps,
        build,
    }
}
