//! [`Family`]: environments registered together in [`crate::registry`], each a name, a time
//! limit and a builder. The sizes a registry entry reports are never written here: they come
//! from the environment (built once and remembered), or from constants its type states
//! (MuJoCo tasks, `Family::add_task`).

use std::fmt;
use std::sync::{Arc, OnceLock};

use crate::env::Env;
use crate::error::EnvError;
use crate::space::Space;
use crate::wrappers::{FixedReset, RescaleAction, TimeLimit};

/// A builder of a bare environment: no time limit, actions in the environment's own bounds.
pub(crate) type Build = dyn Fn() -> Result<Box<dyn Env>, EnvError> + Send + Sync;

/// What the policy sees of a registered environment: the sizes its spec reports.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Spaces {
    /// The length of an observation.
    pub(crate) observation_dim: usize,
    /// The action space after [`wrap_for_policy`].
    pub(crate) action_space: Space,
}

impl Spaces {
    fn of(env: &dyn Env) -> Self {
        Spaces {
            observation_dim: env.observation_space().flat_dim(),
            action_space: env.action_space().clone(),
        }
    }
}

/// `env` as the policy acts on it: inside [`RescaleAction`] if its actions are a box.
fn wrap_for_policy(env: Box<dyn Env>) -> Result<Box<dyn Env>, EnvError> {
    Ok(match env.action_space() {
        Space::Box { .. } => Box::new(RescaleAction::new(env)?),
        Space::Discrete { .. } => env,
    })
}

/// One registered environment.
pub(crate) struct Member {
    pub(crate) name: String,
    pub(crate) family: Arc<str>,
    pub(crate) max_episode_steps: usize,
    build: Box<Build>,
    /// Set when the family states the sizes, else by the first successful build.
    spaces: OnceLock<Spaces>,
}

impl fmt::Debug for Member {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Member")
            .field("name", &self.name)
            .field("family", &self.family)
            .field("max_episode_steps", &self.max_episode_steps)
            .field("spaces", &self.spaces.get())
            .finish_non_exhaustive()
    }
}

impl Member {
    /// Builds the environment as the policy acts on it (no time limit) and remembers its sizes.
    fn build_for_policy(&self) -> Result<(Box<dyn Env>, &Spaces), EnvError> {
        let env = wrap_for_policy((self.build)()?)?;
        let spaces = self.spaces.get_or_init(|| Spaces::of(&*env));
        Ok((env, spaces))
    }

    /// The environment with [`RescaleAction`] (box actions, if `rescale_actions`),
    /// [`FixedReset`] (with `fixed_reset_seed`) and [`TimeLimit`].
    pub(crate) fn make(
        &self,
        rescale_actions: bool,
        fixed_reset_seed: Option<u64>,
    ) -> Result<Box<dyn Env>, EnvError> {
        let env = if rescale_actions {
            self.build_for_policy()?.0
        } else {
            (self.build)()?
        };
        let env: Box<dyn Env> = match fixed_reset_seed {
            Some(seed) => Box::new(FixedReset::new(env, seed)),
            None => env,
        };
        Ok(Box::new(TimeLimit::new(env, self.max_episode_steps)))
    }

    /// The sizes: stated by the family, remembered, or found by building the environment once.
    pub(crate) fn spaces(&self) -> Result<&Spaces, EnvError> {
        match self.spaces.get() {
            Some(spaces) => Ok(spaces),
            None => self.build_for_policy().map(|(_, spaces)| spaces),
        }
    }
}

/// A named group of environments, registered together with [`crate::registry::register`].
///
/// Each member is a registered name, the time limit [`crate::registry::make`] applies, and a
/// builder of the bare environment. Builders are closures, so a family can be generated in a
/// loop whose variables become the builders' arguments (a task × robot grid, a list of game
/// names). A member's observation and action sizes are not written down: the registry builds
/// the environment once when it is first asked for its spec and remembers what it has.
pub struct Family {
    name: Arc<str>,
    members: Vec<Member>,
}

impl fmt::Debug for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Family")
            .field("name", &self.name)
            .field(
                "members",
                &self.members.iter().map(|m| &m.name).collect::<Vec<_>>(),
            )
            .finish()
    }
}

impl Family {
    /// An empty family called `name` (reported as [`crate::registry::EnvSpec::family`]).
    pub fn new(name: impl Into<String>) -> Self {
        Family {
            name: Arc::from(name.into()),
            members: Vec::new(),
        }
    }

    /// The family's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Adds the environment `name`, built by `build` and truncated after `max_episode_steps`
    /// steps. `build` returns the bare environment: no time limit, actions in its own bounds
    /// ([`crate::registry::make`] adds [`RescaleAction`] and [`TimeLimit`]).
    pub fn add<F>(
        &mut self,
        name: impl Into<String>,
        max_episode_steps: usize,
        build: F,
    ) -> &mut Self
    where
        F: Fn() -> Result<Box<dyn Env>, EnvError> + Send + Sync + 'static,
    {
        self.push(name.into(), max_episode_steps, Box::new(build), None)
    }

    /// [`Family::add`] for an environment whose sizes its type states, so that listing it
    /// needs no build.
    pub(crate) fn add_sized(
        &mut self,
        name: String,
        max_episode_steps: usize,
        build: Box<Build>,
        spaces: Spaces,
    ) -> &mut Self {
        self.push(name, max_episode_steps, build, Some(spaces))
    }

    fn push(
        &mut self,
        name: String,
        max_episode_steps: usize,
        build: Box<Build>,
        spaces: Option<Spaces>,
    ) -> &mut Self {
        self.members.push(Member {
            name,
            family: Arc::clone(&self.name),
            max_episode_steps,
            build,
            spaces: spaces.map_or_else(OnceLock::new, OnceLock::from),
        });
        self
    }

    /// The members, in the order they were added.
    pub(crate) fn into_members(self) -> Vec<Member> {
        self.members
    }
}
