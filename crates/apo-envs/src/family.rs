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

/// How [`crate::registry::make_with`] builds an environment, beyond [`crate::registry::make`]'s defaults.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MakeOptions {
    /// Wrap box action spaces in [`RescaleAction`](crate::RescaleAction) (default). Without
    /// it the policy's actions reach the environment as they are: in its own bounds,
    /// unclipped (a MuJoCo task clamps the controls, but its control cost sees the raw action).
    pub rescale_actions: bool,
    /// Reset every episode with this seed ([`FixedReset`](crate::FixedReset)), so that all
    /// episodes start from the same state; `None` (default): seeds as the caller passes them.
    pub fixed_reset_seed: Option<u64>,
    /// Truncate episodes after this many steps instead of the environment's registered limit
    /// (`None`, default: the registered one).
    pub max_episode_steps: Option<usize>,
    /// The physics the MuJoCo environments are built on (`None`, default: the process default,
    /// [`default_physics`](crate::mujoco::default_physics), MuJoCo 2.2.2 unless changed).
    /// Other environments ignore it.
    pub physics: Option<crate::mujoco::physics::Physics>,
}

impl Default for MakeOptions {
    fn default() -> Self {
        Self {
            rescale_actions: true,
            fixed_reset_seed: None,
            max_episode_steps: None,
            physics: None,
        }
    }
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
    ///
    /// # Errors
    /// The builder's; [`EnvError::Init`] if the family stated sizes the environment does not
    /// have.
    fn build_for_policy(&self) -> Result<(Box<dyn Env>, &Spaces), EnvError> {
        let env = wrap_for_policy((self.build)()?)?;
        let built = Spaces::of(&*env);
        let spaces = self.spaces.get_or_init(|| built.clone());
        if *spaces != built {
            return Err(EnvError::Init {
                name: self.name.clone(),
                reason: format!(
                    "its family states {} observations and actions {:?}, but the environment \
                     has {} and {:?}",
                    spaces.observation_dim,
                    spaces.action_space,
                    built.observation_dim,
                    built.action_space
                ),
            });
        }
        Ok((env, spaces))
    }

    /// The environment with [`RescaleAction`] (box actions, if `options.rescale_actions`),
    /// [`FixedReset`] (with `options.fixed_reset_seed`) and [`TimeLimit`] (after
    /// `options.max_episode_steps`, else the member's own limit).
    pub(crate) fn make(&self, options: &MakeOptions) -> Result<Box<dyn Env>, EnvError> {
        let env = if options.rescale_actions {
            self.build_for_policy()?.0
        } else {
            (self.build)()?
        };
        let env: Box<dyn Env> = match options.fixed_reset_seed {
            Some(seed) => Box::new(FixedReset::new(env, seed)),
            None => env,
        };
        let limit = options.max_episode_steps.unwrap_or(self.max_episode_steps);
        Ok(Box::new(TimeLimit::new(env, limit)))
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

    /// [`Family::add`] for an environment with `observation_dim`-long observations and
    /// `Discrete { n: actions }` actions, stated here so that listing it or asking for its spec
    /// needs no build (a game whose ROM is missing is still listed). Building it checks the
    /// statement: a mismatch is an [`EnvError::Init`].
    pub fn add_discrete<F>(
        &mut self,
        name: impl Into<String>,
        max_episode_steps: usize,
        observation_dim: usize,
        actions: usize,
        build: F,
    ) -> &mut Self
    where
        F: Fn() -> Result<Box<dyn Env>, EnvError> + Send + Sync + 'static,
    {
        let spaces = Spaces {
            observation_dim,
            action_space: Space::Discrete { n: actions },
        };
        self.add_sized(name.into(), max_episode_steps, Box::new(build), spaces)
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
