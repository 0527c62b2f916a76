//! Evaluation of a trained run: episodes with the checkpoint's policy.

use std::path::Path;

use anyhow::Context;
use apo_core::inference::{ActBuffers, HostPolicy};
use apo_core::Learner;
use apo_envs::{Action, Space};
use burn::backend::NdArray;
use rand::rngs::StdRng;
use rand::SeedableRng;

use crate::checkpoint::{self, Which};
use crate::config::RunConfig;
use crate::trainer::shapes;
use apo_train::action_kind;

/// Returns of evaluation episodes.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalResult {
    /// Undiscounted return of each episode.
    pub returns: Vec<f64>,
    /// Length of each episode.
    pub lengths: Vec<usize>,
    /// Whether each episode ended in success, for tasks that judge it (the hand tasks; the
    /// last step's `info.success`), else `None`.
    pub success: Vec<Option<bool>>,
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
    let config = RunConfig::load(&run_dir.join("config.toml"))
        .with_context(|| format!("{} is not a run directory", run_dir.display()))?;
    // the run's action mapping, but episodes seeded by the evaluation's own seeds
    let options = apo_envs::MakeOptions {
        fixed_reset_seed: None,
        ..config.train.make_options()
    };
    let mut env = apo_envs::make_with(&config.train.env, &options)?;
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
    let from = checkpoint::locate(run_dir, which)?.with_context(|| {
        format!(
            "{} has no checkpoint yet: the run has not completed an epoch",
            run_dir.display()
        )
    })?;
    let state = checkpoint::load(
        &from,
        &mut learner,
        &shapes(&config, obs_dim, action),
        &device,
    )?;
    let mut policy = HostPolicy::new(&learner.policy_on::<NdArray>(&device), action);
    let mut rng = StdRng::seed_from_u64(seed);
    let mut obs = vec![0.0f32; obs_dim];
    let mut act = ActBuffers::default();
    let mut result = EvalResult {
        returns: vec![],
        lengths: vec![],
        success: vec![],
    };
    for episode in 0..episodes {
        env.reset(Some(seed.wrapping_add(episode as u64)), &mut obs);
        let (mut ret, mut len) = (0.0, 0);
        let success = loop {
            if let Some(rms) = &state.run.normalizer {
                rms.normalize(&mut obs);
            }
            policy.act(&obs, 1, deterministic, &mut rng, &mut act);
            let t = match env.action_space() {
                Space::Discrete { .. } => {
                    env.step(Action::Discrete(act.env_actions[0] as usize), &mut obs)
                }
                Space::Box { .. } => env.step(Action::Continuous(&act.env_actions), &mut obs),
            };
            ret += t.reward;
            len += 1;
            if t.done() {
                break t.info.success;
            }
        };
        result.returns.push(ret);
        result.lengths.push(len);
        result.success.push(success);
    }
    Ok((result, state.run.epoch))
}
