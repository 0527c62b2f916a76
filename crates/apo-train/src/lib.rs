//! # apo-train
//!
//! The training loop of apo as a library, for your own Rust programs (the `apo` command line
//! is a thin layer over it that adds run directories, checkpoints files, plots and printing):
//!
//! * [`config`] — [`TrainConfig`], a run's settings as a plain struct, with the paper's defaults;
//! * [`actor`] — how the rollout acts: the [`Act`] / [`Actor`] traits, the fast host MLP
//!   ([`HostActor`]) and any Burn [`Policy`](apo_core::Policy) module ([`BurnActor`]);
//! * [`rollout`] — [`Collector`]: steps a vector of environments with one batched actor call
//!   per step, bootstraps cut paths and fills the rollout buffers;
//! * [`metrics`] — [`ProgressRow`], one row of metrics per epoch;
//! * [`evaluation`] — [`Evaluator`]: evaluation episodes during training on their own
//!   environment and seeds (`eval_every`);
//! * [`trainer`] — [`Trainer`]: rollout → update → metrics, epoch after epoch, with the
//!   checkpoint schedule;
//! * [`seed`] — the seed streams of a run.
//!
//! ```no_run
//! use apo_core::Algorithm;
//! use apo_train::{TrainConfig, Trainer};
//! use std::sync::atomic::AtomicBool;
//!
//! let mut config = TrainConfig::defaults(Algorithm::Apo, "Hopper-v4");
//! config.epochs = 10;
//! let mut trainer = Trainer::<burn::backend::NdArray, _, _>::mlp(config, &Default::default(), 0)?;
//! let stop = AtomicBool::new(false);
//! while let Some(epoch) = trainer.epoch(&stop, &mut |_| {})? {
//!     println!("epoch {}: mean return {:?}", epoch.row.epoch, epoch.row.ep_ret_mean);
//! }
//! # Ok::<(), apo_train::TrainError>(())
//! ```

pub mod actor;
pub mod config;
pub mod error;
pub mod evaluation;
pub mod metrics;
pub mod rollout;
pub mod seed;
pub mod trainer;

pub use actor::{Act, Actor, BurnActor, HostActor};
pub use config::{ActionMapping, EpisodeReset, EvalMetric, TrainConfig};
pub use error::TrainError;
pub use evaluation::{Evaluation, Evaluator};
pub use metrics::{EpochTimes, ProgressRow};
pub use rollout::{action_kind, Collector, Rollout};
pub use seed::derive_seed;
pub use trainer::{Checkpoint, EpochReport, RunState, Trainer};
