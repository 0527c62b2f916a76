//! The error type of this crate.

use crate::space::Space;

/// What can go wrong when building or configuring environments.
#[derive(Debug, thiserror::Error)]
pub enum EnvError {
    /// No registered environment has this name.
    #[error("unknown environment `{name}`; {}", hint(.suggestions, .registered))]
    Unknown {
        /// The name that was asked for.
        name: String,
        /// Registered names close to it, best first (may be empty).
        suggestions: Vec<String>,
        /// Every registered name (listed when nothing is close).
        registered: Vec<String>,
    },
    /// A family could not be registered: one of its names is taken (names are compared
    /// case-insensitively, as [`crate::registry::make`] matches them).
    #[error("cannot register `{name}` (family `{family}`): `{existing}` is already registered by family `{holder}`")]
    AlreadyRegistered {
        /// The name that was being registered.
        name: String,
        /// The family being registered.
        family: String,
        /// The registered name it collides with (equal to `name` up to ASCII case).
        existing: String,
        /// The family that holds `existing`.
        holder: String,
    },
    /// An environment could not be built (for example a model file failed to load).
    #[error("cannot build environment `{name}`: {reason}")]
    Init {
        /// The environment's name.
        name: String,
        /// Why it failed.
        reason: String,
    },
    /// A wrapper was put around an environment whose space it cannot handle.
    #[error("{wrapper} cannot wrap an environment with {what} space {space:?}: {reason}")]
    UnsupportedSpace {
        /// The wrapper's name.
        wrapper: &'static str,
        /// `"action"` or `"observation"`.
        what: &'static str,
        /// The offending space.
        space: Space,
        /// What the wrapper needs.
        reason: &'static str,
    },
    /// A vector of environments was built from no environments.
    #[error("a vector of environments needs at least one environment")]
    EmptyVector,
    /// The worker threads of a vector of environments could not be started.
    #[error("cannot start the environment worker threads: {0}")]
    Threads(String),
    /// An environment of a vector has other spaces than the first one.
    #[error("environment {index} of the vector has spaces {found:?}, expected those of environment 0: {expected:?}")]
    MismatchedSpaces {
        /// Index of the offending environment.
        index: usize,
        /// `(observation_space, action_space)` of environment 0.
        expected: Box<(Space, Space)>,
        /// `(observation_space, action_space)` of environment `index`.
        found: Box<(Space, Space)>,
    },
    /// Running statistics of one dimension were given where another was needed.
    #[error("running statistics have dimension {found}, expected {expected}")]
    DimensionMismatch {
        /// The dimension required.
        expected: usize,
        /// The dimension given.
        found: usize,
    },
}

/// The end of [`EnvError::Unknown`]'s message: the suggestions, or every registered name.
fn hint(suggestions: &[String], registered: &[String]) -> String {
    let quoted = |names: &[String]| {
        names
            .iter()
            .map(|n| format!("`{n}`"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    match suggestions {
        [] => format!("registered environments: {}", quoted(registered)),
        [one] => format!("did you mean `{one}`?"),
        many => format!("did you mean one of {}?", quoted(many)),
    }
}
