//! Environments by name, built with Gymnasium's time limits and actions in `[-1, 1]`.
//!
//! [`make`] builds a registered environment wrapped as the trainer expects it:
//! [`RescaleAction`] around a box action space (the policy acts in `[-1, 1]^d`), then
//! [`TimeLimit`] with the environment's `max_episode_steps`. [`list`] describes every
//! registered environment without building it.
//!
//! Names match exactly, else case-insensitively (`pendulum-v1`), else without the version
//! suffix when that is unambiguous (`pendulum`). An unknown name gives
//! [`EnvError::Unknown`] with the closest registered names.
//!
//! # Adding environments
//!
//! Each environment is one line of a static table: name, observation dimension, action space
//! seen by the policy, time limit and a constructor of the bare environment. Classic control
//! lives in the table `CLASSIC` of this module; another family (MuJoCo) defines its own
//! `&[Entry]` table (lines built with `entry(…)`, `crate::entry`) and adds one line to `TABLES`.

use crate::classic::{Acrobot, CartPole, MountainCarContinuous, Pendulum};
use crate::entry::{entry, Act, Entry};
use crate::env::Env;
use crate::error::EnvError;
use crate::space::Space;
use crate::wrappers::{RescaleAction, TimeLimit};

/// The description of a registered environment, as built by [`make`].
#[derive(Debug, Clone, PartialEq)]
pub struct EnvSpec {
    /// The registered name, e.g. `"Pendulum-v1"`.
    pub name: &'static str,
    /// The length of an observation.
    pub observation_dim: usize,
    /// The action space the policy sees: `Discrete { n }`, or `[-1, 1]^d` for continuous actions.
    pub action_space: Space,
    /// Episodes are truncated after this many steps.
    pub max_episode_steps: usize,
}

/// The classic-control environments, with Gymnasium's time limits.
pub(crate) static CLASSIC: &[Entry] = &[
    entry("CartPole-v1", 4, Act::Discrete(2), 500, || {
        Ok(Box::new(CartPole::new()))
    }),
    entry("Acrobot-v1", 6, Act::Discrete(3), 500, || {
        Ok(Box::new(Acrobot::new()))
    }),
    entry("Pendulum-v1", 3, Act::Continuous(1), 200, || {
        Ok(Box::new(Pendulum::new()))
    }),
    entry(
        "MountainCarContinuous-v0",
        2,
        Act::Continuous(1),
        999,
        || Ok(Box::new(MountainCarContinuous::new())),
    ),
];

/// Every table of the registry, searched in order. Add one line per family.
pub(crate) static TABLES: &[&[Entry]] = &[CLASSIC, crate::mujoco::ENTRIES];

fn entries() -> impl Iterator<Item = &'static Entry> {
    TABLES.iter().flat_map(|table| table.iter())
}

impl Entry {
    fn spec(&self) -> EnvSpec {
        EnvSpec {
            name: self.name,
            observation_dim: self.observation_dim,
            action_space: match self.action {
                Act::Discrete(n) => Space::Discrete { n },
                Act::Continuous(d) => Space::uniform_box(d, -1.0, 1.0),
            },
            max_episode_steps: self.max_episode_steps,
        }
    }
}

/// Every registered environment, in registration order.
pub fn list() -> Vec<EnvSpec> {
    entries().map(Entry::spec).collect()
}

/// The description of the environment registered as `name` (matched as in [`make`]).
///
/// # Errors
/// [`EnvError::Unknown`] with suggestions if no environment matches.
pub fn spec(name: &str) -> Result<EnvSpec, EnvError> {
    lookup(name).map(Entry::spec)
}

/// Builds the environment registered as `name`: the bare environment, inside
/// [`RescaleAction`] if its actions are a box, inside [`TimeLimit`].
///
/// # Errors
/// [`EnvError::Unknown`] with suggestions if no environment matches; [`EnvError::Init`] if
/// the constructor fails or the environment does not match its registry line.
pub fn make(name: &str) -> Result<Box<dyn Env>, EnvError> {
    let entry = lookup(name)?;
    let env = (entry.build)()?;
    let env: Box<dyn Env> = match env.action_space() {
        Space::Box { .. } => Box::new(RescaleAction::new(env)?),
        Space::Discrete { .. } => env,
    };
    let spec = entry.spec();
    if env.observation_space().flat_dim() != spec.observation_dim
        || *env.action_space() != spec.action_space
    {
        return Err(EnvError::Init {
            name: entry.name.to_owned(),
            reason: format!(
                "the registry says observation dimension {} and actions {:?}, the environment has {} and {:?}",
                spec.observation_dim,
                spec.action_space,
                env.observation_space().flat_dim(),
                env.action_space()
            ),
        });
    }
    Ok(Box::new(TimeLimit::new(env, entry.max_episode_steps)))
}

/// `name` without a trailing version suffix `-v<digits>`.
fn unversioned(name: &str) -> &str {
    match name.rsplit_once("-v") {
        Some((base, version))
            if !version.is_empty() && version.bytes().all(|b| b.is_ascii_digit()) =>
        {
            base
        }
        _ => name,
    }
}

fn lookup(name: &str) -> Result<&'static Entry, EnvError> {
    if let Some(e) = entries().find(|e| e.name == name) {
        return Ok(e);
    }
    if let Some(e) = entries().find(|e| e.name.eq_ignore_ascii_case(name)) {
        return Ok(e);
    }
    let mut same_base = entries().filter(|e| unversioned(e.name).eq_ignore_ascii_case(name));
    if let (Some(e), None) = (same_base.next(), same_base.next()) {
        return Ok(e);
    }
    Err(EnvError::Unknown {
        name: name.to_owned(),
        suggestions: suggestions(name),
        registered: entries().map(|e| e.name.to_owned()).collect(),
    })
}

/// At most this many suggestions.
const MAX_SUGGESTIONS: usize = 3;
/// Registered names less similar than this (Jaro–Winkler, case-insensitive) are not suggested.
const MIN_SIMILARITY: f64 = 0.75;

/// Registered names close to `name`, best first.
fn suggestions(name: &str) -> Vec<String> {
    let query = name.to_lowercase();
    let mut scored: Vec<(f64, &str)> = entries()
        .map(|e| {
            let full = e.name.to_lowercase();
            let base = unversioned(&full);
            let score = if !query.is_empty() && full.contains(&query) {
                1.0
            } else {
                strsim::jaro_winkler(&query, &full).max(strsim::jaro_winkler(&query, base))
            };
            (score, e.name)
        })
        .filter(|(score, _)| *score >= MIN_SIMILARITY)
        .collect();
    scored.sort_by(|a, b| b.0.total_cmp(&a.0));
    scored
        .into_iter()
        .take(MAX_SUGGESTIONS)
        .map(|(_, n)| n.to_owned())
        .collect()
}
