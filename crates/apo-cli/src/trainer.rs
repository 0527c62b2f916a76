//! The training loop: collect `steps_per_epoch` transitions with the current policy,
//! update, log the epoch's metrics, checkpoint.
//!
//! # Rollout
//!
//! The epoch's steps are split over `num_envs` environments (rounded up to a multiple of
//! `num_envs`), stepped together by a [`VecEnv`]. The policy and critic act through host
//! copies ([`HostPolicy`], [`HostValue`]) synchronized after every update, whatever the
//! update backend: a GPU is slow at batch-1 inference, and a host MLP call costs a few
//! microseconds. At the start of epoch `e` every environment is reset with a seed derived
//! from `(seed, e)` and the action-sampling RNG is reseeded the same way (as SpinningUp
//! resets its environment when an epoch ends), so an epoch depends only on the seed and the
//! networks: a resumed run reproduces an uninterrupted one.
//!
//! # Bootstrapping
//!
//! A path ending by termination bootstraps from 0; one truncated by the time limit from
//! `V(final observation)`; one cut by the end of the epoch from `V(current observation)`.
//! An episode ended by a simulator instability is treated as terminated, counted in
//! `unstable_episodes`, and left out of the return statistics.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{bail, Context};
use apo_core::inference::{ActBuffers, HostPolicy, HostValue};
use apo_core::{
    ActionKind, BufferLayout, EpisodeStats, Learner, MlpPolicyConfig, RolloutBuffer, UpdateReport,
    ValueConfig,
};
use apo_envs::{RunningMeanStd, Space, VecEnv, VecStep};
use burn::backend::NdArray;
use burn::tensor::backend::Backend;
use rand::rngs::StdRng;
use rand::SeedableRng;

use crate::checkpoint::{self, Shapes, TrainState, Which};
use crate::config::RunConfig;
use crate::progress::{self, EpochTimes, ProgressRow};
use crate::tensorboard::{row_scalars, EventWriter};

/// A seed for stream `stream` of epoch `epoch` of a run seeded `seed` (SplitMix64 mixing).
pub fn derive_seed(seed: u64, epoch: u64, stream: u64) -> u64 {
    let mut z = seed
        ^ epoch.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The policy's action kind for an environment's action space.
pub fn action_kind(space: &Space) -> ActionKind {
    match space {
        Space::Box { low, .. } => ActionKind::Continuous { dim: low.len() },
        Space::Discrete { n } => ActionKind::Discrete { n: *n },
    }
}

/// The policy and value configs of a run for an environment.
pub fn networks(
    config: &RunConfig,
    observation_dim: usize,
    action: ActionKind,
) -> (MlpPolicyConfig, ValueConfig) {
    let policy = MlpPolicyConfig {
        observation_dim,
        action,
        hidden: config.hidden.clone(),
        init_log_std: config.init_log_std,
    };
    (
        policy,
        ValueConfig {
            observation_dim,
            hidden: config.hidden.clone(),
        },
    )
}

/// Host copies of a learner's networks, for acting.
pub struct Actor {
    /// The policy.
    pub policy: HostPolicy,
    /// The critic.
    pub value: HostValue,
}

impl Actor {
    /// Copies the learner's current networks to the host.
    pub fn sync<B: Backend>(
        learner: &Learner<B, MlpPolicyConfig>,
        value: &ValueConfig,
        action: ActionKind,
    ) -> Self {
        let device = Default::default();
        let policy = learner.policy_on::<NdArray>(&device);
        Self {
            policy: HostPolicy::new(&policy, action),
            value: HostValue::new(&learner.value_on::<NdArray>(value, &device)),
        }
    }
}

/// What one epoch's rollout produced.
pub struct Rollout {
    /// The transitions.
    pub batch: apo_core::Batch,
    /// Returns of the episodes that ended.
    pub returns: Vec<f64>,
    /// Their lengths.
    pub lengths: Vec<usize>,
    /// Episodes ended by a simulator instability.
    pub unstable: usize,
    /// Environment steps taken.
    pub steps: u64,
}

/// How often (in vector steps) [`Collector::collect`] reports its progress.
pub const PROGRESS_EVERY: usize = 256;

/// Collects the epoch's transitions; `None` when `stop` was raised mid-way.
pub struct Collector {
    envs: VecEnv,
    obs: Vec<f32>,
    obs_norm: Vec<f32>,
    env_actions: Vec<f32>,
    out: Vec<VecStep>,
    act: ActBuffers,
    values: Vec<f32>,
    buffers: Vec<RolloutBuffer>,
    normalizer: Option<RunningMeanStd>,
    steps_per_env: usize,
}

impl Collector {
    /// A collector for `config` (its environments are made here), stepping them on `threads`
    /// worker threads (0: the cores available; the results do not depend on it).
    pub fn new(
        config: &RunConfig,
        normalizer: Option<RunningMeanStd>,
        threads: usize,
    ) -> anyhow::Result<Self> {
        let envs = VecEnv::make(&config.env, config.num_envs)?.with_threads(threads)?;
        Ok(Self::from_envs(
            envs,
            config.steps_per_epoch,
            config.algo.gamma,
            config.algo.lambda,
            normalizer,
        ))
    }

    /// A collector of `steps_per_epoch` steps (rounded up to whole vector steps) from `envs`,
    /// with discount `gamma` and GAE `lambda`.
    pub fn from_envs(
        envs: VecEnv,
        steps_per_epoch: usize,
        gamma: f64,
        lambda: f64,
        normalizer: Option<RunningMeanStd>,
    ) -> Self {
        let n = envs.num_envs();
        let obs_dim = envs.obs_dim();
        let action = action_kind(envs.action_space());
        let dist_width = match action {
            ActionKind::Continuous { dim } => 2 * dim,
            ActionKind::Discrete { n } => n,
        };
        let steps_per_env = steps_per_epoch.div_ceil(n);
        let layout = BufferLayout {
            observation_dim: obs_dim,
            action_width: action.width(),
            dist_width,
        };
        Self {
            obs: vec![0.0; n * obs_dim],
            obs_norm: vec![0.0; n * obs_dim],
            env_actions: Vec::with_capacity(n * envs.act_dim()),
            out: vec![VecStep::default(); n],
            act: ActBuffers::default(),
            values: Vec::with_capacity(n),
            buffers: (0..n)
                .map(|_| RolloutBuffer::new(layout, gamma, lambda, steps_per_env))
                .collect(),
            normalizer,
            steps_per_env,
            envs,
        }
    }

    /// The observation dimension.
    pub fn observation_dim(&self) -> usize {
        self.envs.obs_dim()
    }

    /// The policy's action kind.
    pub fn action(&self) -> ActionKind {
        action_kind(self.envs.action_space())
    }

    /// The observation normalizer's statistics.
    pub fn normalizer(&self) -> Option<&RunningMeanStd> {
        self.normalizer.as_ref()
    }

    /// Restores the observation normalizer's statistics.
    pub fn set_normalizer(&mut self, normalizer: Option<RunningMeanStd>) {
        self.normalizer = normalizer;
    }

    fn normalized(&self, raw: &[f32], out: &mut [f32]) {
        out.copy_from_slice(raw);
        if let Some(rms) = &self.normalizer {
            rms.normalize(out);
        }
    }

    /// Runs one epoch's rollout with `actor`, seeded by `seed`; `progress` is told the
    /// epoch's environment steps so far every [`PROGRESS_EVERY`] vector steps.
    pub fn collect(
        &mut self,
        actor: &mut Actor,
        seed: u64,
        stop: &AtomicBool,
        progress: &mut dyn FnMut(u64),
    ) -> Option<Rollout> {
        let n = self.envs.num_envs();
        let obs_dim = self.envs.obs_dim();
        let mut rng = StdRng::seed_from_u64(derive_seed(seed, 0, 1));
        self.envs
            .reset(Some(derive_seed(seed, 0, 0)), &mut self.obs);
        let (mut ep_ret, mut ep_len) = (vec![0.0f64; n], vec![0usize; n]);
        let mut rollout = Rollout {
            batch: Default::default(),
            returns: vec![],
            lengths: vec![],
            unstable: 0,
            steps: 0,
        };
        let mut row = vec![0.0f32; obs_dim];
        for t in 0..self.steps_per_env {
            if stop.load(Ordering::Relaxed) {
                return None;
            }
            if t % PROGRESS_EVERY == 0 {
                progress(rollout.steps);
            }
            if let Some(rms) = &mut self.normalizer {
                rms.update(&self.obs, n);
            }
            let mut obs_norm = std::mem::take(&mut self.obs_norm);
            self.normalized(&self.obs, &mut obs_norm);
            actor
                .policy
                .act(&obs_norm, n, false, &mut rng, &mut self.act);
            self.values.clear();
            self.values
                .extend_from_slice(actor.value.values(&obs_norm, n));
            self.env_actions.clear();
            self.env_actions.extend_from_slice(&self.act.env_actions);
            self.envs
                .step(&self.env_actions, &mut self.obs, &mut self.out);
            rollout.steps += n as u64;
            let (aw, dw) = (self.act.actions.len() / n, self.act.dist.len() / n);
            for i in 0..n {
                let step = self.out[i];
                self.buffers[i].store(
                    &obs_norm[i * obs_dim..(i + 1) * obs_dim],
                    &self.act.actions[i * aw..(i + 1) * aw],
                    self.act.logp[i],
                    &self.act.dist[i * dw..(i + 1) * dw],
                    self.values[i],
                    step.reward as f32,
                );
                ep_ret[i] += step.reward;
                ep_len[i] += 1;
                if !step.done() {
                    continue;
                }
                let last_value = if step.terminated || step.info.unstable {
                    0.0
                } else {
                    let final_obs = self
                        .envs
                        .final_obs(i)
                        .unwrap_or(&self.obs[i * obs_dim..(i + 1) * obs_dim]);
                    self.normalized(final_obs, &mut row);
                    actor.value.values(&row, 1)[0]
                };
                self.buffers[i].finish_path(last_value);
                if step.info.unstable {
                    rollout.unstable += 1;
                } else {
                    rollout.returns.push(ep_ret[i]);
                    rollout.lengths.push(ep_len[i]);
                }
                ep_ret[i] = 0.0;
                ep_len[i] = 0;
            }
            self.obs_norm = obs_norm;
        }
        for i in 0..n {
            if self.buffers[i].path_len() > 0 {
                self.normalized(&self.obs[i * obs_dim..(i + 1) * obs_dim], &mut row);
                let last_value = actor.value.values(&row, 1)[0];
                self.buffers[i].finish_path(last_value);
            }
        }
        rollout.batch = RolloutBuffer::take_all(&mut self.buffers);
        Some(rollout)
    }
}

/// How [`train`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrainEnd {
    /// All epochs ran.
    Finished,
    /// `stop` was raised; a checkpoint of the last completed epoch was written.
    Interrupted {
        /// Epochs completed.
        epoch: usize,
    },
}

/// Observes training progress (the CLI's progress bar).
pub trait Observer {
    /// Called during each epoch's rollout with the run's environment steps so far.
    fn steps(&mut self, _env_steps: u64) {}
    /// Called after each epoch with its row.
    fn epoch(&mut self, row: &ProgressRow, epochs: usize);
}

/// The shapes of `config`'s networks on an environment with `observation_dim` and `action`.
pub fn shapes(config: &RunConfig, observation_dim: usize, action: ActionKind) -> Shapes {
    Shapes {
        observation_dim,
        action,
        hidden: config.hidden.clone(),
        normalize_obs: config.normalize_obs,
    }
}

/// Trains (or, with `resume`, continues) the run in `run_dir` on backend `B`, the
/// environments stepped on `threads` threads (0: the cores available; results do not depend
/// on it).
///
/// Resuming checks that the checkpoint and `progress.csv` agree (rows of every completed epoch,
/// with matching step counts) and refuses with the reason when they don't. After every update
/// the losses, the KL and the parameters are checked: a non-finite value stops the run with
/// an error, before anything of that epoch is written, keeping the last good checkpoint.
pub fn train<B: Backend>(
    config: &RunConfig,
    run_dir: &Path,
    device: &B::Device,
    resume: bool,
    threads: usize,
    stop: &AtomicBool,
    observer: &mut dyn Observer,
) -> anyhow::Result<TrainEnd> {
    let start = Instant::now();
    let mut collector = Collector::new(config, None, threads)?;
    let (obs_dim, action) = (collector.observation_dim(), collector.action());
    let shapes = shapes(config, obs_dim, action);
    let (policy_cfg, value_cfg) = networks(config, obs_dim, action);
    let mut learner = Learner::<B, _>::new(
        policy_cfg,
        action,
        &value_cfg,
        config.algo.clone(),
        device,
        config.seed,
    )?;
    learner.set_kernels(config.kernels.resolve(config.backend));
    let progress_path = run_dir.join(crate::run_dir::PROGRESS);
    let mut state = TrainState::new(config.normalize_obs.then(|| RunningMeanStd::new(obs_dim)));
    let mut rows = Vec::new();
    if resume {
        let on_disk = if progress_path.exists() {
            progress::read(&progress_path)?
        } else {
            Vec::new()
        };
        match checkpoint::locate(run_dir, &Which::Latest)? {
            Some(from) => {
                state = checkpoint::load(&from, &mut learner, &shapes, device)?;
                check_rows(&on_disk, &state, &progress_path, &from)?;
                rows = on_disk;
                if rows.len() > state.epoch {
                    tracing::info!(
                        rows = rows.len(),
                        checkpoint_epoch = state.epoch,
                        "progress.csv has epochs after the checkpoint; they are run again (same seed, same rows)"
                    );
                    rows.truncate(state.epoch);
                }
                tracing::info!(epoch = state.epoch, checkpoint = %from.display(), "resumed from checkpoint");
            }
            None if on_disk.is_empty() => {
                tracing::info!("no checkpoint and no completed epoch: the run starts from epoch 0");
            }
            None => bail!(
                "{} has {} epoch rows but there is no checkpoint ({} is missing): the run cannot continue where it \
                 stopped. Its files are kept; restore the checkpoint, or start a new run with another --out",
                progress_path.display(),
                on_disk.len(),
                checkpoint::dir(run_dir).join("latest").join("state.json").display()
            ),
        }
    }
    if state.epoch > config.epochs {
        bail!(
            "the run has {} epochs done, more than epochs = {}; pass a larger --epochs",
            state.epoch,
            config.epochs
        );
    }
    collector.set_normalizer(state.normalizer.clone());
    let mut events = EventWriter::create(run_dir)?;
    let elapsed_before = state.elapsed_s;
    let mut checkpoint_epoch = state.epoch;
    let mut actor = Actor::sync(&learner, &value_cfg, action);
    for epoch in state.epoch..config.epochs {
        let epoch_start = Instant::now();
        let seed = derive_seed(config.seed, epoch as u64, 0);
        let steps_before = state.env_steps;
        let rollout_start = Instant::now();
        let Some(rollout) = collector.collect(&mut actor, seed, stop, &mut |steps| {
            observer.steps(steps_before + steps)
        }) else {
            checkpoint::save(run_dir, &learner, &state, &shapes, false)
                .context("writing the checkpoint after an interrupt")?;
            tracing::warn!(epoch = state.epoch, "interrupted; checkpoint written");
            return Ok(TrainEnd::Interrupted { epoch: state.epoch });
        };
        let rollout_s = rollout_start.elapsed().as_secs_f64();
        let mut rng = StdRng::seed_from_u64(derive_seed(seed, 0, 2));
        let report = learner.update(&rollout.batch, &mut rng);
        if let Some(what) = non_finite(&report, &learner) {
            let kept = if checkpoint_epoch > 0 {
                format!(
                    "The last good checkpoint (epoch {checkpoint_epoch}) is kept in {}.",
                    checkpoint::dir(run_dir).display()
                )
            } else {
                "No epoch had completed, so nothing was saved.".to_string()
            };
            bail!(
                "epoch {}: the update produced {what}; the run stopped without saving that epoch. {kept} Lower the \
                 learning rates (algo.policy_update.lr, algo.value_update.lr) or algo.trust_region.max_kl, or check \
                 the environment's rewards",
                epoch + 1
            );
        }
        actor = Actor::sync(&learner, &value_cfg, action);

        state.epoch = epoch + 1;
        state.env_steps += rollout.steps;
        state.elapsed_s = elapsed_before + start.elapsed().as_secs_f64();
        state.normalizer = collector.normalizer().cloned();
        let stats = EpisodeStats::from_episodes(&rollout.returns, &rollout.lengths, config.algo.k);
        let steps_per_s = rollout.steps as f64 / epoch_start.elapsed().as_secs_f64().max(1e-9);
        let row = ProgressRow::new(
            state.epoch,
            state.env_steps,
            stats.as_ref(),
            rollout.unstable,
            &report,
            EpochTimes {
                rollout_s,
                steps_per_s,
                time_s: state.elapsed_s,
            },
        );
        let shown = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v:.3}"));
        tracing::info!(
            epoch = row.epoch,
            env_steps = row.env_steps,
            episodes = row.episodes,
            ret_mean = %shown(row.ep_ret_mean),
            ret_min = %shown(row.ep_ret_min),
            kl = row.kl,
            line_search = %row.line_search.as_deref().unwrap_or("-"),
            "epoch done"
        );
        if rollout.unstable > 0 {
            tracing::warn!(
                epoch = row.epoch,
                episodes = rollout.unstable,
                "episodes ended by simulator instability"
            );
        }
        observer.epoch(&row, config.epochs);
        rows.push(row.clone());
        progress::write(&progress_path, &rows)?;
        events.scalars(row.env_steps, unix_time(), &row_scalars(&row))?;
        let interrupted = stop.load(Ordering::Relaxed);
        let keep = config.keep_checkpoint_every > 0
            && state.epoch.is_multiple_of(config.keep_checkpoint_every);
        if interrupted
            || keep
            || state.epoch.is_multiple_of(config.checkpoint_every)
            || state.epoch == config.epochs
        {
            checkpoint::save(run_dir, &learner, &state, &shapes, keep)?;
            checkpoint_epoch = state.epoch;
        }
        if interrupted {
            return Ok(TrainEnd::Interrupted { epoch: state.epoch });
        }
    }
    Ok(TrainEnd::Finished)
}

/// Seconds since the Unix epoch.
fn unix_time() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// Checks that `rows` (from `progress.csv`) hold every epoch the checkpoint `state` completed.
fn check_rows(
    rows: &[ProgressRow],
    state: &TrainState,
    progress_path: &Path,
    from: &Path,
) -> anyhow::Result<()> {
    if rows.len() < state.epoch {
        bail!(
            "{} has {} epoch rows but the checkpoint in {} is at epoch {}: the rows of epochs {}..={} are missing \
             (was the file deleted, emptied or replaced?). Resuming would lose them; restore the file, or start a new \
             run with another --out",
            progress_path.display(),
            rows.len(),
            from.display(),
            state.epoch,
            rows.len() + 1,
            state.epoch
        );
    }
    for (i, row) in rows.iter().take(state.epoch).enumerate() {
        if row.epoch != i + 1 {
            bail!(
                "{}: row {} is epoch {}, expected epoch {}",
                progress_path.display(),
                i + 1,
                row.epoch,
                i + 1
            );
        }
    }
    if let Some(last) = state.epoch.checked_sub(1).map(|i| &rows[i]) {
        if last.env_steps != state.env_steps {
            bail!(
                "{} says {} environment steps after epoch {}, the checkpoint in {} says {}: they are from different runs",
                progress_path.display(),
                last.env_steps,
                state.epoch,
                from.display(),
                state.env_steps
            );
        }
    }
    Ok(())
}

/// What is not finite after an update, if anything: a loss, the KL, the entropy, or a parameter.
fn non_finite<B: Backend>(
    report: &UpdateReport,
    learner: &Learner<B, MlpPolicyConfig>,
) -> Option<String> {
    let scalars = [
        ("loss_pi", report.loss_pi),
        ("loss_v", report.loss_v),
        ("kl", report.kl),
        ("entropy", report.entropy),
        ("mean_surr", report.mean_surr),
    ];
    if let Some((name, value)) = scalars.iter().find(|(_, v)| !v.is_finite()) {
        return Some(format!("a non-finite {name} = {value}"));
    }
    if learner.policy_params().iter().any(|p| !p.is_finite()) {
        return Some("non-finite policy parameters".to_string());
    }
    if learner.value_params().iter().any(|p| !p.is_finite()) {
        return Some("non-finite value-network parameters".to_string());
    }
    None
}
