//! Evaluation of a trained run: episodes with the checkpoint's policy.

use std::path::Path;

use anyhow::Context;
use apo_core::inference::{ActBuffers, HostPolicy};
use apo_core::Learner;
use apo_envs::{Env, RunningMeanStd};
use burn::backend::NdArray;
use rand::rngs::StdRng;

use crate::action_kind;
use crate::checkpoint::{self, Shapes, Which};
pub use crate::evaluation::Moment;
use crate::evaluation::Plays;
use crate::run_config::RunConfig;

/// Returns of evaluation episodes.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalResult {
    /// Undiscounted return of each episode.
    pub returns: Vec<f64>,
    /// Length of each episode.
    pub lengths: Vec<usize>,
    /// Whether each episode ended in success, for tasks that judge it (the hand tasks; the
    /// last step's `info.success`; an unstable episode is a failure), else `None`.
    pub success: Vec<Option<bool>>,
    /// Whether each episode was ended by a simulator instability (its return, up to that
    /// step, counts like any other).
    pub unstable: Vec<bool>,
}

impl EvalResult {
    /// The fraction of the judged episodes that ended in success; `None` when none was judged.
    pub fn success_rate(&self) -> Option<f64> {
        let (judged, succeeded) = self
            .success
            .iter()
            .flatten()
            .fold((0usize, 0usize), |(j, s), &ok| (j + 1, s + usize::from(ok)));
        (judged > 0).then(|| succeeded as f64 / judged as f64)
    }
}

/// Runs `episodes` episodes of the policy in checkpoint `which` of `run_dir` (on the CPU),
/// seeded by `seed`; with `deterministic` the policy takes the mean (Gaussian) or most likely
/// (categorical) action. Returns the results and the checkpoint's epoch.
pub fn evaluate(
    run_dir: &Path,
    which: &Which,
    episodes: usize,
    deterministic: bool,
    seed: u64,
) -> anyhow::Result<(EvalResult, usize)> {
    let mut run = LoadedRun::load(run_dir, which)?;
    let result = play_episodes(
        run.env.as_mut(),
        &mut run.policy,
        run.normalizer.as_ref(),
        &Episodes {
            count: episodes,
            deterministic,
            seed,
        },
        &mut |_, _| Ok(()),
    )?;
    Ok((result, run.epoch))
}

/// A run's policy loaded from one of its checkpoints, with an environment to play it on.
pub struct LoadedRun {
    /// The run's configuration.
    pub config: RunConfig,
    /// The run's environment, made with its action mapping and time limit, but reset only by
    /// the seeds the episodes are given.
    pub env: Box<dyn Env>,
    /// The checkpoint's policy, on the host.
    pub policy: HostPolicy,
    /// The checkpoint's observation normalizer, when the run normalizes observations.
    pub normalizer: Option<RunningMeanStd>,
    /// The checkpoint's epoch.
    pub epoch: usize,
}

impl LoadedRun {
    /// Loads checkpoint `which` of `run_dir` (its shapes and checksums checked).
    ///
    /// # Errors
    /// Not a run directory, no such checkpoint, a damaged checkpoint, an unknown environment.
    pub fn load(run_dir: &Path, which: &Which) -> anyhow::Result<LoadedRun> {
        let config = crate::run_dir::load_config(run_dir)?;
        if crate::run_dir::check_resumable(run_dir).is_err() {
            anyhow::bail!(
                "{} holds a config.toml but no run (neither apo's marker nor a checkpoint): train one with \
                 `apo train --config {} --out <new folder>`",
                run_dir.display(),
                run_dir.join("config.toml").display()
            );
        }
        let from = checkpoint::locate(run_dir, which)?.with_context(|| {
            let recorded = crate::progress_csv::read_lenient(&run_dir.join("progress.csv"), true)
                .map_or(0, |p| p.rows.last().map_or(0, |r| r.epoch));
            if recorded > 0 && recorded <= checkpoint::first_due(&config.train) {
                format!(
                    "{} has no checkpoint yet: the run stopped after {recorded} epochs, before its first checkpoint \
                     (due at epoch {}); `apo train --resume {}` trains it again from epoch 0",
                    run_dir.display(),
                    checkpoint::first_due(&config.train),
                    run_dir.display()
                )
            } else if recorded > 0 {
                format!(
                    "{} has no checkpoint (checkpoints/latest and previous are missing), although its \
                     progress.csv records {recorded} epochs: the checkpoints were removed",
                    run_dir.display()
                )
            } else {
                format!(
                    "{} has no checkpoint yet: the run has not completed an epoch",
                    run_dir.display()
                )
            }
        })?;
        // the run's action mapping, but episodes seeded by the evaluation's own seeds
        let options = apo_envs::MakeOptions {
            fixed_reset_seed: None,
            ..config.train.make_options()
        };
        let env = apo_envs::make_with(&config.train.env, &options)?;
        let obs_dim = env.observation_space().flat_dim();
        let action = action_kind(env.action_space());
        let (policy_cfg, value_cfg) = (
            config.train.mlp_policy(obs_dim, action),
            config.train.value(obs_dim),
        );
        let device = Default::default();
        let mut learner = Learner::<NdArray, _>::new(
            policy_cfg,
            action,
            &value_cfg,
            config.train.algo.clone(),
            &device,
            0,
        )?;
        let state = checkpoint::load(
            &from,
            &mut learner,
            &Shapes::of(&config, obs_dim, action),
            &device,
        )?;
        if let Which::Epoch(epoch) = which {
            if state.run.epoch != *epoch {
                anyhow::bail!(
                    "{} holds the state of epoch {}, not of epoch {epoch}: the folder was renamed or replaced",
                    from.display(),
                    state.run.epoch
                );
            }
        }
        let policy = HostPolicy::new(&learner.policy_on::<NdArray>(&device), action);
        Ok(LoadedRun {
            config,
            env,
            policy,
            normalizer: state.run.normalizer,
            epoch: state.run.epoch,
        })
    }
}

/// Which episodes [`play_episodes`] plays.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Episodes {
    /// How many.
    pub count: usize,
    /// Act with the mean (Gaussian) or most likely (categorical) action.
    pub deterministic: bool,
    /// Episode `i` starts from `reset(seed + i)`; sampled actions draw from `StdRng(seed)`.
    pub seed: u64,
}

/// Plays `episodes` of `policy` on `env` ([`crate::evaluation::play_episodes`], the one
/// episode loop), normalizing observations with `normalizer` (not updated), calling `observe`
/// after each reset and each step. The episodes of [`evaluate`] with the same seed, for a
/// policy held in memory (the videos of a training run).
///
/// # Errors
/// The observer's, which stop the episodes.
pub fn play_episodes(
    env: &mut dyn Env,
    policy: &mut HostPolicy,
    normalizer: Option<&RunningMeanStd>,
    episodes: &Episodes,
    observe: &mut dyn FnMut(&mut dyn Env, &Moment) -> anyhow::Result<()>,
) -> anyhow::Result<EvalResult> {
    let plays = Plays {
        count: episodes.count,
        deterministic: episodes.deterministic,
        first_reset: episodes.seed,
        action_seed: episodes.seed,
    };
    let act = &mut |obs: &[f32], deterministic, rng: &mut StdRng, out: &mut ActBuffers| {
        policy.act(obs, 1, deterministic, rng, out)
    };
    let played = crate::evaluation::play_episodes(env, act, normalizer, &plays, observe)?;
    Ok(EvalResult {
        returns: played.iter().map(|e| e.ret).collect(),
        lengths: played.iter().map(|e| e.length).collect(),
        success: played.iter().map(|e| e.success).collect(),
        unstable: played.iter().map(|e| e.unstable).collect(),
    })
}
