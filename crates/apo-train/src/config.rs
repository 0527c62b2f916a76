//! A run's settings as a plain struct, with the paper's defaults and range checks.

use apo_core::{ActionKind, AlgoConfig, Algorithm, ConfigError, MlpPolicyConfig, ValueConfig};
use serde::{Deserialize, Serialize};

/// Upper bound of `steps_per_epoch` (far above the paper's; it keeps arithmetic in range).
pub const MAX_STEPS_PER_EPOCH: usize = 100_000_000;
/// Upper bound of `num_envs`.
pub const MAX_NUM_ENVS: usize = 65_536;

/// The most epochs a run may have (a billion: beyond any training budget, and far from the
/// overflow of the step counters).
pub const MAX_EPOCHS: usize = 1_000_000_000;
/// The largest `max_episode_steps` (a truncation longer than any epoch's steps is no
/// truncation).
pub const MAX_EPISODE_STEPS: usize = 1_000_000_000;
/// Upper bound of the number of hidden layers.
pub const MAX_LAYERS: usize = 64;
/// Upper bound of a hidden layer's width.
pub const MAX_WIDTH: usize = 1 << 20;

fn yes() -> bool {
    true
}

fn ten() -> usize {
    10
}

/// Upper bound of `eval_episodes`.
pub const MAX_EVAL_EPISODES: usize = 1_000_000;

/// The statistic of the evaluation episodes that picks the best checkpoint.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EvalMetric {
    /// The mean return.
    #[default]
    Mean,
    /// The worst return.
    Worst,
    /// The lower CVaR at 10 % of the returns.
    Cvar10,
}

/// How the policy's Gaussian actions reach the environment.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionMapping {
    /// The policy acts in `[-1, 1]^d`, mapped linearly to the action box and clipped
    /// ([`apo_envs::RescaleAction`]).
    #[default]
    Rescale,
    /// The sampled action goes to the environment as it is, in the box's own units and
    /// unclipped (the paper's code): a MuJoCo task clamps its controls, but its control
    /// cost sees the raw action.
    Raw,
}

/// How the episodes of a run start.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EpisodeReset {
    /// Each epoch reseeds its environments from the run's seed and the epoch; later episodes
    /// continue each environment's random stream (a different start every episode).
    #[default]
    Epoch,
    /// Every episode starts from `reset(seed)` with the run's seed: the same initial state
    /// every episode (the paper's code on the Gym MuJoCo tasks).
    RunSeed,
}

/// Everything the training loop needs to know about a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    /// Environment name (see `apo_envs::list`).
    pub env: String,
    /// Seed of everything random in the run.
    pub seed: u64,
    /// Number of epochs (paper: 200 continuous, 500 Atari).
    pub epochs: usize,
    /// Environment steps collected per epoch (paper: 30 000).
    pub steps_per_epoch: usize,
    /// Environments stepped together (the epoch's steps are split between them).
    pub num_envs: usize,
    /// Normalize observations with running statistics (saved in checkpoints).
    pub normalize_obs: bool,
    /// A checkpoint is due every this many epochs (and always at the end and on interrupt).
    pub checkpoint_every: usize,
    /// Also keep the checkpoint of every this many epochs (0: keep only the latest).
    #[serde(default)]
    pub keep_checkpoint_every: usize,
    /// Hidden layer sizes of the policy and value networks (paper: [64, 64]).
    pub hidden: Vec<usize>,
    /// Initial log standard deviation of Gaussian policies.
    pub init_log_std: f64,
    /// Bootstrap episodes truncated by the time limit from `V(final observation)` (the
    /// default); `false` treats them as terminated (value 0), as the paper's code did on the
    /// Gym MuJoCo tasks. Paths cut by the end of the epoch always bootstrap.
    #[serde(default = "yes")]
    pub bootstrap_time_limit: bool,
    /// How Gaussian actions reach the environment.
    #[serde(default)]
    pub actions: ActionMapping,
    /// How episodes are seeded.
    #[serde(default)]
    pub episode_reset: EpisodeReset,
    /// Truncate episodes after this many steps (the paper's maximum trajectory length L);
    /// 0 (default): the environment's registered limit.
    #[serde(default)]
    pub max_episode_steps: usize,
    /// The physics of MuJoCo environments: MuJoCo 2.2.2 (default) or 3.17 (builds with the
    /// `mujoco3` feature).
    #[serde(default)]
    pub physics: apo_envs::mujoco::Physics,
    /// Evaluate the policy every this many epochs, on its own environment and seeds (never the
    /// training stream: training is the same with or without it); 0 (default): never.
    #[serde(default)]
    pub eval_every: usize,
    /// Episodes of each evaluation.
    #[serde(default = "ten")]
    pub eval_episodes: usize,
    /// Evaluate with the most likely action (a Gaussian's mean, a categorical's arg max)
    /// instead of sampling.
    #[serde(default = "yes")]
    pub eval_deterministic: bool,
    /// The evaluation statistic that picks the best checkpoint (`checkpoints/best`).
    #[serde(default)]
    pub eval_best: EvalMetric,
    /// Overlap each epoch's value fit with the next epoch's rollout (the default): the
    /// rollout acts with the new policy while the critic is fitted, then the new batch's values
    /// come from the fitted critic in one batched call. The results are bit-identical to the
    /// sequential epoch (`false`); only the time columns change.
    #[serde(default = "yes")]
    pub pipeline: bool,
    /// The algorithm's hyperparameters.
    pub algo: AlgoConfig,
}

impl TrainConfig {
    /// The paper's defaults for `algo` on `env`: 200 epochs of 30 000 steps, one environment,
    /// [64, 64] tanh networks, initial log-std −0.5, a checkpoint every epoch.
    pub fn defaults(algo: Algorithm, env: &str) -> Self {
        Self {
            env: env.to_string(),
            seed: 0,
            epochs: 200,
            steps_per_epoch: 30_000,
            num_envs: 1,
            normalize_obs: false,
            checkpoint_every: 1,
            keep_checkpoint_every: 0,
            hidden: vec![64, 64],
            init_log_std: -0.5,
            bootstrap_time_limit: true,
            actions: ActionMapping::Rescale,
            episode_reset: EpisodeReset::Epoch,
            max_episode_steps: 0,
            physics: apo_envs::mujoco::Physics::Mujoco2,
            eval_every: 0,
            eval_episodes: 10,
            eval_deterministic: true,
            eval_best: EvalMetric::Mean,
            pipeline: true,
            algo: AlgoConfig::paper_defaults(algo),
        }
    }

    /// Checks the range of every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let check = |ok: bool, field: &str, value: String, rule: &str| {
            if ok {
                Ok(())
            } else {
                Err(ConfigError::new(field, value, rule))
            }
        };
        check(
            self.epochs > 0,
            "epochs",
            self.epochs.to_string(),
            "must be ≥ 1",
        )?;
        check(
            self.epochs <= MAX_EPOCHS,
            "epochs",
            self.epochs.to_string(),
            &format!("must be ≤ {MAX_EPOCHS}"),
        )?;
        check(
            self.num_envs > 0,
            "num_envs",
            self.num_envs.to_string(),
            "must be ≥ 1",
        )?;
        check(
            self.num_envs <= MAX_NUM_ENVS,
            "num_envs",
            self.num_envs.to_string(),
            &format!("must be ≤ {MAX_NUM_ENVS}"),
        )?;
        check(
            self.steps_per_epoch >= self.num_envs,
            "steps_per_epoch",
            self.steps_per_epoch.to_string(),
            "must be ≥ num_envs",
        )?;
        check(
            (1..=MAX_EPOCHS).contains(&self.checkpoint_every),
            "checkpoint_every",
            self.checkpoint_every.to_string(),
            &format!("must be in 1..={MAX_EPOCHS}"),
        )?;
        check(
            self.keep_checkpoint_every <= MAX_EPOCHS,
            "keep_checkpoint_every",
            self.keep_checkpoint_every.to_string(),
            &format!("must be in 0..={MAX_EPOCHS}"),
        )?;
        check(
            self.max_episode_steps <= MAX_EPISODE_STEPS,
            "max_episode_steps",
            self.max_episode_steps.to_string(),
            &format!("must be in 0..={MAX_EPISODE_STEPS}"),
        )?;
        check(
            !self.hidden.is_empty() && !self.hidden.contains(&0),
            "hidden",
            format!("{:?}", self.hidden),
            "must be a non-empty list of positive sizes",
        )?;
        check(
            (-20.0..=2.0).contains(&self.init_log_std),
            "init_log_std",
            self.init_log_std.to_string(),
            "must be in [-20, 2]",
        )?;
        check(
            self.steps_per_epoch <= MAX_STEPS_PER_EPOCH,
            "steps_per_epoch",
            self.steps_per_epoch.to_string(),
            &format!("must be ≤ {MAX_STEPS_PER_EPOCH}"),
        )?;
        check(
            self.hidden.len() <= MAX_LAYERS && self.hidden.iter().all(|&h| h <= MAX_WIDTH),
            "hidden",
            format!("{:?}", self.hidden),
            &format!("must have at most {MAX_LAYERS} layers of at most {MAX_WIDTH} units"),
        )?;
        check(
            self.seed <= i64::MAX as u64,
            "seed",
            self.seed.to_string(),
            &format!(
                "must be in 0..={} (TOML integers are signed 64-bit)",
                i64::MAX
            ),
        )?;
        check(
            (1..=MAX_EVAL_EPISODES).contains(&self.eval_episodes),
            "eval_episodes",
            self.eval_episodes.to_string(),
            &format!("must be in 1..={MAX_EVAL_EPISODES}"),
        )?;
        check(
            self.eval_every <= MAX_EPOCHS,
            "eval_every",
            self.eval_every.to_string(),
            &format!("must be in 0..={MAX_EPOCHS}"),
        )?;
        self.algo.validate().map_err(|e| ConfigError {
            field: format!("algo.{}.{}", self.algo.algorithm(), e.field),
            ..e
        })
    }

    /// How [`apo_envs::make_with`] builds this run's environments.
    pub fn make_options(&self) -> apo_envs::MakeOptions {
        apo_envs::MakeOptions {
            rescale_actions: self.actions == ActionMapping::Rescale,
            fixed_reset_seed: (self.episode_reset == EpisodeReset::RunSeed).then_some(self.seed),
            max_episode_steps: (self.max_episode_steps > 0).then_some(self.max_episode_steps),
            physics: Some(self.physics),
        }
    }

    /// The built-in MLP policy for an environment with `observation_dim` and `action`.
    pub fn mlp_policy(&self, observation_dim: usize, action: ActionKind) -> MlpPolicyConfig {
        MlpPolicyConfig {
            observation_dim,
            action,
            hidden: self.hidden.clone(),
            init_log_std: self.init_log_std,
        }
    }

    /// The critic for an environment with `observation_dim`.
    pub fn value(&self, observation_dim: usize) -> ValueConfig {
        ValueConfig {
            observation_dim,
            hidden: self.hidden.clone(),
        }
    }
}
