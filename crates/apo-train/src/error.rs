//! Errors of the training loop.

use apo_core::{ConfigError, PolicyError, ShapingError};
use apo_envs::EnvError;

/// Why training could not start or continue.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A setting is out of range.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The policy's distributions do not fit the environment's actions.
    #[error(transparent)]
    Policy(#[from] PolicyError),
    /// The epoch's batch does not record what the algorithm's risk shaping needs.
    #[error(transparent)]
    Shaping(#[from] ShapingError),
    /// The environments could not be made.
    #[error(transparent)]
    Env(#[from] EnvError),
    /// The update produced a non-finite loss, KL, entropy or parameter; the epoch's results
    /// were not kept.
    #[error("epoch {epoch}: the update produced {what}")]
    NonFinite {
        /// The epoch (from 1).
        epoch: usize,
        /// What was not finite, e.g. "a non-finite kl = NaN".
        what: String,
    },
    /// [`Trainer::epoch`](crate::Trainer::epoch) was called after the last epoch, or a
    /// restored state is past it.
    #[error("the run has {done} epochs done, more than epochs = {epochs}")]
    PastTheEnd {
        /// Epochs done.
        done: usize,
        /// The configured number of epochs.
        epochs: usize,
    },
}
