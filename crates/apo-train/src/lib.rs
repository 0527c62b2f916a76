#![warn(missing_docs)]
//! # apo-train
//!
//! A training run of apo as a library, for your own Rust programs: the epoch loop, and a run in
//! a directory with everything the `apo` command line keeps of it (the command line adds
//! argument parsing, printing, plots, reports and sweeps):
//!
//! * [`run`] — [`Run`]: a run in a directory — created, trained epoch by epoch, checkpointed,
//!   resumed bit-exactly from its files — with the built-in MLP or your own policy (story 4);
//! * [`run_config`] — [`RunConfig`]: the whole run's settings (TOML, `key=value` overrides,
//!   presets, every key documented with its range, the memory estimate);
//! * [`run_dir`], [`checkpoint`], [`progress_csv`], [`episodes_csv`], [`tensorboard`],
//!   [`video`] — the files of a run: its directory (ownership marker, lock, the one removal
//!   rule), verified atomic checkpoints, the per-epoch and per-episode records, TensorBoard
//!   events, epoch videos; [`atomic`], [`removal`] and [`input`] are the rules they write,
//!   remove and read files by;
//! * [`playback`] — a run's policy loaded from a checkpoint and played for episodes;
//! * [`backend`] — [`BackendKind`] and the one dispatch from it to a Burn backend type;
//! * [`config`] — [`TrainConfig`], the training loop's settings as a plain struct, with the
//!   paper's defaults;
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
//! The backend type `B` is a plain Burn backend (`NdArray`, `Wgpu`), not `Autodiff<B>`: the
//! learner adds autodiff itself. A first build compiles Burn's dependency tree, which is much
//! of its time (minutes on 2 cores); keep it down by turning on only the backend
//! features you use (`burn = { version = "0.21", default-features = false,
//! features = ["std", "autodiff", "ndarray"] }`), and make debug builds fast to run with
//! `[profile.dev.package."*"] opt-level = 2` (dependencies optimized, your crate not).
//!
//! # 1. A registered environment with the built-in MLP
//!
//! ```
//! use apo_core::Algorithm;
//! use apo_train::{TrainConfig, Trainer};
//! use burn::backend::NdArray;
//! use std::sync::atomic::AtomicBool;
//!
//! let mut config = TrainConfig::defaults(Algorithm::Apo, "Pendulum-v1");
//! config.epochs = 2;
//! config.steps_per_epoch = 400; // the paper: 30 000
//! // the built-in (64, 64) tanh MLP, acting through its fast host copy; 1 thread
//! let mut trainer = Trainer::<NdArray, _, _>::mlp(config, &Default::default(), 1)?;
//! let stop = AtomicBool::new(false); // set it (e.g. from a signal handler) to stop cleanly
//! while let Some(epoch) = trainer.epoch(&stop, &mut |_| {})? {
//!     println!("epoch {}: mean return {:?}", epoch.row.epoch, epoch.row.ep_ret_mean);
//! }
//! assert_eq!(trainer.state().env_steps, 800);
//! # Ok::<(), apo_train::TrainError>(())
//! ```
//!
//! # 2. Your own `burn::nn` policy
//!
//! Any module that implements [`apo_core::Policy`], built by an [`apo_core::PolicyFamily`]
//! (see apo-core's crate docs). The family closure gets the config, the environment's
//! observation size and its [`apo_core::ActionKind`]; the actor defaults to [`BurnActor`].
//!
//! ```
//! use apo_core::{ActionKind, Algorithm, DistParams, Policy, PolicyFamily};
//! use apo_train::{TrainConfig, Trainer};
//! use burn::backend::NdArray;
//! use burn::module::Module;
//! use burn::nn::{Linear, LinearConfig};
//! use burn::tensor::backend::Backend;
//! use burn::tensor::Tensor;
//! use std::sync::atomic::AtomicBool;
//!
//! /// Logits of a categorical policy from one `nn::Linear` layer.
//! #[derive(Module, Debug)]
//! struct Logits<B: Backend> {
//!     layer: Linear<B>,
//! }
//!
//! impl<B: Backend> Policy<B> for Logits<B> {
//!     fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
//!         DistParams::Categorical { logits: self.layer.forward(obs) } // [batch, n]
//!     }
//! }
//!
//! #[derive(Debug, Clone)]
//! struct LogitsConfig {
//!     obs: usize,
//!     actions: usize,
//! }
//!
//! impl PolicyFamily for LogitsConfig {
//!     type Policy<B: Backend> = Logits<B>;
//!     fn init<B: Backend>(&self, device: &B::Device) -> Logits<B> {
//!         Logits { layer: LinearConfig::new(self.obs, self.actions).init(device) }
//!     }
//! }
//!
//! let mut config = TrainConfig::defaults(Algorithm::Trpo, "CartPole-v1");
//! config.epochs = 2;
//! config.steps_per_epoch = 200;
//! let family = |_: &TrainConfig, obs: usize, action: ActionKind| LogitsConfig {
//!     obs,
//!     actions: action.width(),
//! };
//! let mut trainer = Trainer::<NdArray, _>::new(config, &Default::default(), 1, family)?;
//! let before = trainer.learner().policy_params();
//! while trainer.epoch(&AtomicBool::new(false), &mut |_| {})?.is_some() {}
//! assert_ne!(trainer.learner().policy_params(), before);
//! # Ok::<(), apo_train::TrainError>(())
//! ```
//!
//! # 3. Your own environment
//!
//! Any [`apo_envs::Env`] (apo-envs' crate docs show one), as a [`apo_envs::VecEnv`] given to
//! [`Trainer::from_envs`], which steps the environments as they are: the config keys that
//! [`Trainer::new`] applies by wrapping the environments it makes (`max_episode_steps`,
//! `episode_reset`, `actions = rescale` on a box other than `[-1, 1]`, `physics`) are refused
//! by name unless they are no-ops — wrap yours in [`apo_envs::TimeLimit`],
//! [`apo_envs::FixedReset`] or [`apo_envs::RescaleAction`] instead.
//!
//! ```
//! use apo_core::Algorithm;
//! use apo_envs::{RescaleAction, VecEnv};
//! use apo_train::{HostActor, TrainConfig, Trainer};
//! use burn::backend::NdArray;
//! use std::sync::atomic::AtomicBool;
//!
//! // stand-ins for your own environments: Pendulum, its torque box [-2, 2] mapped from the
//! // policy's [-1, 1] by RescaleAction (registered environments come with it already)
//! let envs = (0..2)
//!     .map(|_| {
//!         let options = apo_envs::MakeOptions { rescale_actions: false, ..Default::default() };
//!         let env = apo_envs::make_with("Pendulum-v1", &options)?;
//!         Ok(Box::new(RescaleAction::new(env)?) as Box<dyn apo_envs::Env>)
//!     })
//!     .collect::<Result<Vec<_>, apo_envs::EnvError>>()?;
//! let mut config = TrainConfig::defaults(Algorithm::Apo, "my-pendulum"); // a label only
//! config.epochs = 1;
//! config.steps_per_epoch = 200;
//! let mut trainer = Trainer::<NdArray, _, HostActor>::from_envs(
//!     config,
//!     VecEnv::new(envs)?,
//!     &Default::default(),
//!     |config, obs, action| config.mlp_policy(obs, action),
//! )?;
//! let epoch = trainer.epoch(&AtomicBool::new(false), &mut |_| {})?.expect("one epoch");
//! assert_eq!(epoch.row.env_steps, 200);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # 4. A run in a directory: stop, drop everything, resume
//!
//! [`Run`] keeps a run's files in a directory; a run stopped after any epoch (a stop flag, a
//! crash, a killed process) continues from the directory alone, and ends exactly where the
//! run that never stopped ends. With your own policy family, [`Run::create_with`] and
//! [`Run::resume_with`] take the function that makes the [`Trainer`] (e.g. `|config, threads|
//! Trainer::new(config, &device, threads, family)`).
//!
//! ```
//! use apo_core::Algorithm;
//! use apo_train::{Launch, Run, RunConfig};
//! use burn::backend::NdArray;
//! use std::sync::atomic::AtomicBool;
//!
//! let dir = std::env::temp_dir().join(format!("apo-doc-run-{}", std::process::id()));
//! let mut config = RunConfig::defaults(Algorithm::Apo, "CartPole-v1");
//! config.train.epochs = 4;
//! config.train.steps_per_epoch = 200;
//! let (device, launch, stop) = (Default::default(), Launch::new(1), AtomicBool::new(false));
//!
//! let mut run = Run::<NdArray>::create(&dir, config, &launch, &device, false)?;
//! run.epoch(&stop, &mut |_| {})?; // epoch 1
//! run.epoch(&stop, &mut |_| {})?; // epoch 2
//! run.checkpoint()?;
//! drop(run); // or the process ends
//!
//! let mut run = Run::<NdArray>::resume(&dir, &launch, &device, None)?;
//! while let Some(row) = run.epoch(&stop, &mut |_| {})? {
//!     println!("epoch {}: worst return {:?}", row.epoch, row.ep_ret_min);
//! }
//! assert!(run.finished() && run.epochs_done() == 4);
//! # drop(run);
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), anyhow::Error>(())
//! ```
//!
//! `tests/run.rs` checks that the resumed run's networks, `progress.csv` and `episodes.csv`
//! equal those of a run that never stopped, and the workspace's outside crate
//! (`tests/external-user`) does the same with the built-in MLP and with a `burn::nn` policy.
//!
//! A program that picks the backend at run time from the config (`backend = "wgpu"`) opens
//! the run as an [`AnyRun`] (`AnyRun::create(&dir, config, &launch, false)`, the same methods),
//! which compiles the training loop once per backend here rather than in the program's crates;
//! the `apo` binary trains that way.

/// `eprintln!` that never panics: what cannot be written to standard error (a closed pipe, a
/// full device) is dropped, since there is nowhere left to report it.
#[macro_export]
macro_rules! warnln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($arg)*);
    }};
}

pub mod actor;
mod any_run;
pub mod atomic;
pub mod backend;
pub mod checkpoint;
pub mod config;
pub mod episodes_csv;
pub mod error;
pub mod evaluation;
pub mod input;
pub mod metrics;
#[cfg(feature = "mpi")]
pub mod mpi;
pub mod playback;
pub mod progress_csv;
pub mod removal;
pub mod rollout;
pub mod run;
pub mod run_config;
pub mod run_dir;
pub mod seed;
pub mod tensorboard;
pub mod trainer;
pub mod video;

pub use actor::{Act, Actor, BurnActor, HostActor};
pub use any_run::AnyRun;
pub use backend::{BackendKind, OnBackend};
pub use config::{ActionMapping, EpisodeReset, EvalMetric, TrainConfig};
pub use error::TrainError;
pub use evaluation::{Evaluation, Evaluator};
pub use metrics::{EpisodeRecord, EpochTimes, Phase, ProgressRow};
pub use rollout::{action_kind, episode_stats, Collector, Episode, Rollout};
pub use run::{Launch, Run};
pub use run_config::RunConfig;
pub use seed::derive_seed;
pub use trainer::{Checkpoint, EpochReport, RunState, Trainer};
