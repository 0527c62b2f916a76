//! The epoch loop: collect `steps_per_epoch` transitions with the current policy, update,
//! measure, and say when a checkpoint is due.
//!
//! A [`Trainer`] owns the learner, the collector and the actor. Each [`Trainer::epoch`] runs one
//! rollout (seeded from the run seed and the epoch number, see [`crate::seed`]), one update
//! (its update RNG seeded the same way), rebuilds the actor from the updated networks and
//! returns the epoch's [`ProgressRow`]. After every update the losses, the KL and the parameters
//! are checked: a non-finite value is an error and the epoch's counters are not advanced.
//! [`Trainer::checkpoint_due`] is the checkpoint schedule; writing checkpoints is the caller's
//! (the `apo` CLI writes them atomically into the run directory, and restores a run with
//! [`Trainer::learner_mut`] and [`Trainer::restore`]).
//!
//! [`Trainer::distribute`] makes the trainer one rank of a data-parallel run (MPI in the
//! `apo` CLI): each rank collects `steps_per_epoch / N` steps from its own seeds (rank 0's are
//! a one-process run's), the update is one update over the union of the ranks' batches
//! ([`apo_core::collective`]), and the epoch's episode statistics are over every rank's
//! episodes, so every rank returns the same [`ProgressRow`].

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use apo_core::ValueConfig;
use apo_core::{
    ActionKind, Batch, Comm, ConfigError, Learner, MlpPolicyConfig, PolicyFamily, UpdateReport,
};
use apo_envs::{RunningMeanStd, VecEnv};
use burn::backend::Autodiff;
use burn::module::AutodiffModule;
use burn::tensor::backend::Backend;
use rand::rngs::StdRng;
use rand::SeedableRng;
use serde::{Deserialize, Serialize};

use crate::actor::{Actor, BurnActor, HostActor};
use crate::config::{ActionMapping, EpisodeReset, TrainConfig};
use crate::error::TrainError;
use crate::evaluation::Evaluator;
use crate::metrics::{EpisodeRecord, EpochTimes, Phase, ProgressRow};
use crate::rollout::{action_kind, episode_stats, Collector, Episode};
use crate::seed::derive_seed;

/// The counters of a run: what a checkpoint must hold besides the networks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunState {
    /// Epochs completed.
    pub epoch: usize,
    /// Environment steps so far.
    pub env_steps: u64,
    /// Wall time of the run so far, seconds.
    pub elapsed_s: f64,
    /// Observation normalizer statistics, when the run normalizes observations.
    pub normalizer: Option<RunningMeanStd>,
}

/// A checkpoint the schedule asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Checkpoint {
    /// Also keep this epoch's checkpoint (every `keep_checkpoint_every` epochs).
    pub keep: bool,
}

/// What one epoch did.
#[derive(Debug, Clone, PartialEq)]
pub struct EpochReport {
    /// The epoch's metrics.
    pub row: ProgressRow,
    /// The update's full report.
    pub update: UpdateReport,
    /// Every episode that ended in the epoch's rollout, then those of its evaluation (if it
    /// evaluated): the rows of `episodes.csv`.
    pub episodes: Vec<EpisodeRecord>,
}

/// A rollout collected ahead, during the previous epoch's value fit, with the seconds it took.
struct Prefetched {
    rollout: crate::rollout::Rollout,
    seconds: f64,
}

/// The pipelined epoch (`pipeline = true`): after epoch k's policy step, epoch k's value fit
/// runs on a second thread while this thread collects epoch k+1's steps with the new policy;
/// when both are done, the fitted critic gives that rollout's values and advantages, and the
/// next epoch starts from it. It is exact, not approximate — the rollout's steps never call the
/// critic, the value fit continues the update's random stream, no policy step reads the critic,
/// and a checkpoint after epoch k takes what the sequential epoch has (`docs/architecture.md`,
/// "The pipelined epoch"). The test
/// `the_pipelined_epoch_is_the_sequential_epoch_bit_for_bit` (`tests/trainer.rs`) checks it.
#[derive(Default)]
struct Pipeline {
    /// The next epoch's rollout, collected during this epoch's value fit.
    prefetched: Option<Prefetched>,
    /// The threads the value fit runs its parallel parts on while the rollout is the longer
    /// of the two: all of rayon's but one, which is left to the rollout (made at the first
    /// pipelined epoch; `None` when it could not be made).
    fit_pool: Option<Option<rayon::ThreadPool>>,
    /// The threads the value fit runs on while it is the longer of the two: as many as
    /// rayon's, at the lowest priority (nice 19), so that they take only what the rollout's
    /// core leaves while it runs, and every core once it is done (made when first needed).
    yielding_pool: Option<Option<rayon::ThreadPool>>,
    /// Whether the last value fit outlasted its rollout: the next one then runs on the
    /// yielding pool (the results do not depend on the threads).
    fit_outlasts: bool,
}

/// Lowers the calling thread to the lowest priority (nice 19; on Linux a nice value is a
/// thread's own). Nothing happens where it cannot be set.
fn lowest_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: gettid and setpriority have no preconditions; a failure leaves the priority as it was
    unsafe {
        let tid = libc::gettid();
        libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, 19);
    }
}

impl Pipeline {
    /// Runs `fit` on a second thread while `collect` runs on this one; returns what `collect`
    /// returned and its seconds.
    fn fit_beside<R>(
        &mut self,
        fit: impl FnOnce() + Send,
        collect: impl FnOnce() -> R,
    ) -> (R, f64) {
        let pool = self.fit_pool.get_or_insert_with(|| {
            let threads = rayon::current_num_threads().saturating_sub(1).max(1);
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .thread_name(|i| format!("apo-value-fit-{i}"))
                .build()
                .ok()
        });
        let pool = if self.fit_outlasts {
            let yielding = self.yielding_pool.get_or_insert_with(|| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(rayon::current_num_threads())
                    .thread_name(|i| format!("apo-value-fit-low-{i}"))
                    .start_handler(|_| lowest_priority())
                    .build()
                    .ok()
            });
            yielding.as_ref()
        } else {
            pool.as_ref()
        };
        let start = Instant::now();
        let (collected, collect_s, fit_s) = std::thread::scope(|scope| {
            let fit = scope.spawn(move || {
                match pool {
                    Some(pool) => pool.install(fit),
                    None => fit(),
                }
                start.elapsed().as_secs_f64()
            });
            let collected = collect();
            let collect_s = start.elapsed().as_secs_f64();
            match fit.join() {
                Ok(fit_s) => (collected, collect_s, fit_s),
                Err(panic) => std::panic::resume_unwind(panic),
            }
        });
        self.fit_outlasts = fit_s > collect_s;
        (collected, collect_s)
    }
}

/// Trains a policy of family `F` with a learner on backend `B` (a plain backend such as
/// `NdArray` or `Wgpu`: the learner adds `Autodiff` itself), acting through `A` (by default
/// [`BurnActor<F>`], which runs any policy module; [`Trainer::mlp`] uses the faster
/// [`HostActor`] of the built-in MLP).
pub struct Trainer<B: Backend, F: PolicyFamily, A: Actor<B, F> = BurnActor<F>>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    config: TrainConfig,
    learner: Learner<B, F>,
    value: ValueConfig,
    collector: Collector,
    actor: A,
    state: RunState,
    /// When this process started training, and the run's elapsed time before it.
    started: (Instant, f64),
    /// The ranks of a data-parallel run.
    comm: Comm,
    /// The evaluation episodes, when the run evaluates.
    evaluator: Option<Evaluator>,
    /// The pipelined schedule's state: the next epoch's rollout, collected during this
    /// epoch's value fit (`pipeline`).
    pipeline: Pipeline,
}

impl<B: Backend> Trainer<B, MlpPolicyConfig, HostActor> {
    /// A trainer of the built-in MLP policy (`config.hidden`, tanh) acting through the host
    /// copies of its networks, with the environments stepped on `threads` threads (0: the
    /// cores available; the results do not depend on it).
    ///
    /// # Errors
    /// [`TrainError::Config`] for a setting out of range, [`TrainError::Env`] when the
    /// environments cannot be made.
    pub fn mlp(
        config: TrainConfig,
        device: &B::Device,
        threads: usize,
    ) -> Result<Self, TrainError> {
        Self::new(
            config,
            device,
            threads,
            |config, observation_dim, action| config.mlp_policy(observation_dim, action),
        )
    }
}

impl<B: Backend, F: PolicyFamily, A: Actor<B, F>> Trainer<B, F, A>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    /// A trainer of the policy family that `family(&config, observation_dim, action)` builds
    /// (the environment's flat observation size and its [`ActionKind`]), on
    /// `config.num_envs` copies of the registered environment
    /// `config.env` stepped on `threads` threads (0: the cores available; the results do not
    /// depend on it). The networks are initialized from `config.seed` on `device`.
    ///
    /// With `eval_every > 0` the policy is also evaluated every `eval_every` epochs on a
    /// further copy of the environment with its own seeds ([`crate::evaluation`]).
    ///
    /// # Errors
    /// [`TrainError::Config`] for a setting out of range, [`TrainError::Env`] when the
    /// environments cannot be made.
    pub fn new(
        config: TrainConfig,
        device: &B::Device,
        threads: usize,
        family: impl FnOnce(&TrainConfig, usize, ActionKind) -> F,
    ) -> Result<Self, TrainError> {
        config.validate()?;
        let envs = VecEnv::make_with(&config.env, config.num_envs, &config.make_options())?
            .with_threads(threads)?;
        let evaluator = Evaluator::new(&config)?;
        Self::build(config, envs, device, family, evaluator)
    }

    /// A trainer on the given vector of environments (any [`apo_envs::Env`], registered or
    /// not; `config.env` and `config.num_envs` are then only labels), stepped as given, with
    /// the policy family that `family(&config, observation_dim, action)` builds.
    ///
    /// The config keys that [`Trainer::new`] applies by wrapping the environments it makes are
    /// not applied to environments given here; each is refused unless it is a no-op:
    /// `max_episode_steps` must be 0 (wrap your environments in [`apo_envs::TimeLimit`]),
    /// `episode_reset` must be `epoch` (wrap them in [`apo_envs::FixedReset`]), `physics` must be
    /// the default (it chooses how registered MuJoCo tasks are built), and `actions = rescale`
    /// (the default) needs an action box of `[-1, 1]` in every dimension (wrap them in
    /// [`apo_envs::RescaleAction`], or set `actions = raw` to send the Gaussian's samples as they
    /// are). `eval_every` must be 0: the evaluation builds its own environment from the registry.
    ///
    /// The type of `A` defaults to [`BurnActor<F>`](crate::BurnActor), which runs any
    /// [`apo_core::Policy`] in the rollout: `Trainer::<NdArray, _>::from_envs(…)`.
    ///
    /// # Errors
    /// [`TrainError::Config`] naming the first setting above that cannot be honoured, or a
    /// setting out of range.
    pub fn from_envs(
        config: TrainConfig,
        envs: VecEnv,
        device: &B::Device,
        family: impl FnOnce(&TrainConfig, usize, ActionKind) -> F,
    ) -> Result<Self, TrainError> {
        check_given_envs(&config, &envs)?;
        Self::build(config, envs, device, family, None)
    }

    fn build(
        config: TrainConfig,
        envs: VecEnv,
        device: &B::Device,
        family: impl FnOnce(&TrainConfig, usize, ActionKind) -> F,
        evaluator: Option<Evaluator>,
    ) -> Result<Self, TrainError> {
        config.validate()?;
        let (observation_dim, action) = (envs.obs_dim(), action_kind(envs.action_space()));
        let normalizer = config
            .normalize_obs
            .then(|| RunningMeanStd::new(observation_dim));
        let collector = Collector::from_envs(
            envs,
            config.steps_per_epoch,
            config.algo.common().gamma,
            config.algo.common().lambda,
            normalizer.clone(),
        )
        .bootstrap_time_limit(config.bootstrap_time_limit);
        let value = config.value(observation_dim);
        let family = family(&config, observation_dim, action);
        let learner = Learner::new(
            family,
            action,
            &value,
            config.algo.clone(),
            device,
            config.seed,
        )?;
        let actor = A::from_learner(&learner, &value);
        Ok(Self {
            state: RunState {
                epoch: 0,
                env_steps: 0,
                elapsed_s: 0.0,
                normalizer,
            },
            started: (Instant::now(), 0.0),
            comm: Comm::default(),
            evaluator,
            pipeline: Pipeline::default(),
            config,
            learner,
            value,
            collector,
            actor,
        })
    }

    /// Makes this trainer rank `comm.rank()` of `comm.size()` of a data-parallel run (call it
    /// on every rank, before the first epoch): it collects `steps_per_epoch / N` steps per
    /// epoch, and every update, normalization and statistic spans all ranks.
    /// `minibatch_size` settings are per rank (the global minibatch is `N` times larger).
    ///
    /// # Errors
    /// [`TrainError::Config`] when `steps_per_epoch` is not a multiple of the number of ranks
    /// or leaves a rank fewer steps than `num_envs`.
    pub fn distribute(&mut self, comm: Comm) -> Result<(), TrainError> {
        let (ranks, steps) = (comm.size(), self.config.steps_per_epoch);
        if !steps.is_multiple_of(ranks) || steps / ranks < self.config.num_envs {
            return Err(TrainError::Config(ConfigError {
                field: "steps_per_epoch".into(),
                value: steps.to_string(),
                rule: format!(
                    "must be a multiple of the {ranks} ranks with at least num_envs = {} steps per rank",
                    self.config.num_envs
                ),
            }));
        }
        self.learner.set_comm(comm.clone());
        self.collector.distribute(comm.clone(), steps / ranks);
        self.comm = comm;
        Ok(())
    }

    /// The ranks of the run (one by default).
    pub fn comm(&self) -> &Comm {
        &self.comm
    }

    /// The run's settings.
    pub fn config(&self) -> &TrainConfig {
        &self.config
    }

    /// The learner (networks, optimizers, hyperparameters).
    pub fn learner(&self) -> &Learner<B, F> {
        &self.learner
    }

    /// The learner, to restore its networks from a checkpoint or change its kernels; call
    /// [`Trainer::restore`] afterwards so that the actor acts with the restored networks.
    pub fn learner_mut(&mut self) -> &mut Learner<B, F> {
        &mut self.learner
    }

    /// The critic's sizes.
    pub fn value_config(&self) -> &ValueConfig {
        &self.value
    }

    /// The environment's observation dimension.
    pub fn observation_dim(&self) -> usize {
        self.collector.observation_dim()
    }

    /// The policy's action kind.
    pub fn action(&self) -> ActionKind {
        self.collector.action()
    }

    /// The run's counters.
    pub fn state(&self) -> &RunState {
        &self.state
    }

    /// Continues a run from its counters (with the learner already restored through
    /// [`Trainer::learner_mut`]): sets them, the observation normalizer, and rebuilds the actor.
    ///
    /// # Errors
    /// [`TrainError::PastTheEnd`] when `state` has more epochs done than `config.epochs`.
    pub fn restore(&mut self, state: RunState) -> Result<(), TrainError> {
        if state.epoch > self.config.epochs {
            return Err(TrainError::PastTheEnd {
                done: state.epoch,
                epochs: self.config.epochs,
            });
        }
        self.collector.set_normalizer(state.normalizer.clone());
        self.pipeline.prefetched = None;
        self.started = (Instant::now(), state.elapsed_s);
        self.state = state;
        self.actor = A::from_learner(&self.learner, &self.value);
        Ok(())
    }

    /// Whether every epoch has run.
    pub fn finished(&self) -> bool {
        self.state.epoch >= self.config.epochs
    }

    /// Runs the next epoch: rollout, update, metrics. `progress` is told the run's environment
    /// steps every [`crate::rollout::PROGRESS_EVERY`] vector steps. Returns `None` when every
    /// epoch has run, or when `stop` was raised during the rollout (the epoch is then dropped:
    /// the counters stay at the last completed epoch).
    ///
    /// With `pipeline` (the default), the value fit runs on another thread while this thread
    /// collects the next epoch's rollout with the new policy; that rollout's values and
    /// advantages come from the fitted critic once both are done, and the next call starts
    /// from it. The results are the sequential epoch's, bit for bit: the rollout never calls
    /// the critic ([`Collector`]'s values are one batched call after the steps), the update's
    /// random stream is the same, and the networks, counters and observation statistics a
    /// checkpoint takes after this call are the sequential epoch's (a stop raised during the
    /// next rollout drops that rollout, not this epoch).
    ///
    /// # Errors
    /// [`TrainError::NonFinite`] when the update produced a non-finite loss, KL, entropy or
    /// parameter (the counters stay at the last completed epoch).
    pub fn epoch(
        &mut self,
        stop: &AtomicBool,
        progress: &mut dyn FnMut(u64),
    ) -> Result<Option<EpochReport>, TrainError> {
        if self.finished() {
            return Ok(None);
        }
        let start = Instant::now();
        let seed = self.epoch_seed(self.state.epoch);
        // collect: the rollout, its values and advantages (GAE)
        let Some(Prefetched { rollout, seconds }) = self.collect(seed, stop, progress, start)
        else {
            return Ok(None);
        };
        // the policy step
        let mut rng = StdRng::seed_from_u64(derive_seed(seed, 0, 2));
        // the risk shaping of MVPI, CVaR and return capping (none for the other algorithms)
        let shaping_before = *self.learner.shaping_state();
        let shaped = self.learner.shape(&rollout.batch)?;
        let (policy_batch, value_batch) = match &shaped {
            Some(s) => (&s.policy, s.value.as_ref().unwrap_or(&s.policy)),
            None => (&rollout.batch, &rollout.batch),
        };
        let mut update = match self.learner.update_policy(policy_batch, &mut rng) {
            Ok(update) => update,
            Err(e) => {
                self.learner.restore_shaping_state(shaping_before);
                return Err(e.into());
            }
        };
        if let Some(s) = &shaped {
            update.shaping = Some(s.report);
            tracing::info!(
                epoch = self.state.epoch + 1,
                level = s.report.level,
                kept = s.report.kept,
                "risk shaping"
            );
        }
        // the observation statistics after this epoch's rollout (the next one moves them)
        let normalizer = self.collector.normalizer().cloned();
        // the value fit, beside the next rollout when pipelined
        if self.config.pipeline && self.state.epoch + 1 < self.config.epochs {
            self.fit_value_beside_next_rollout(
                rollout.steps,
                value_batch,
                rng,
                &mut update,
                stop,
                progress,
            )?;
        } else {
            self.learner
                .update_value(value_batch, &mut rng, &mut update);
            self.check_finite(&update, value_batch)?;
            self.actor = A::from_learner(&self.learner, &self.value);
        }
        Ok(Some(self.close_epoch(rollout, seconds, update, normalizer)))
    }

    /// The epoch's rollout: the one collected beside the last epoch's value fit, or a new one
    /// (`None` when `stop` was raised during it).
    fn collect(
        &mut self,
        seed: u64,
        stop: &AtomicBool,
        progress: &mut dyn FnMut(u64),
        start: Instant,
    ) -> Option<Prefetched> {
        if let Some(prefetched) = self.pipeline.prefetched.take() {
            return Some(prefetched);
        }
        let (steps_before, ranks) = (self.state.env_steps, self.comm.size() as u64);
        let steps = self
            .collector
            .collect_steps(&mut self.actor, seed, stop, &mut |steps| {
                progress(steps_before + steps * ranks)
            });
        let rollout = self.finish_rollout(steps)?;
        Some(Prefetched {
            rollout,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The value fit on `rollout` on a second thread while this one collects the next epoch's
    /// steps with the new policy ([`Pipeline`]); the fitted critic then completes that rollout,
    /// which the next call takes. A stop during it drops it and its observation statistics.
    fn fit_value_beside_next_rollout(
        &mut self,
        rollout_steps: u64,
        value_batch: &Batch,
        mut rng: StdRng,
        update: &mut UpdateReport,
        stop: &AtomicBool,
        progress: &mut dyn FnMut(u64),
    ) -> Result<(), TrainError> {
        // the observation statistics after this epoch's rollout, restored if the next is dropped
        let normalizer = self.collector.normalizer().cloned();
        // the new policy; the critic is not called during the rollout's steps
        self.actor = A::from_learner(&self.learner, &self.value);
        let next_seed = self.epoch_seed(self.state.epoch + 1);
        let next_steps = self.state.env_steps + rollout_steps;
        let ranks = self.comm.size() as u64;
        let (learner, collector, actor) = (&mut self.learner, &mut self.collector, &mut self.actor);
        let (next, next_s) = self.pipeline.fit_beside(
            || learner.update_value(value_batch, &mut rng, update),
            || {
                collector.collect_steps(actor, next_seed, stop, &mut |steps| {
                    progress(next_steps + steps * ranks)
                })
            },
        );
        if let Err(e) = self.check_finite(update, value_batch) {
            if next.is_some() {
                self.collector.discard();
            }
            self.collector.set_normalizer(normalizer);
            return Err(e);
        }
        // the fitted critic gives the next rollout's values
        self.actor = A::from_learner(&self.learner, &self.value);
        let finish_start = Instant::now();
        match self.finish_rollout(next) {
            Some(rollout) => {
                self.pipeline.prefetched = Some(Prefetched {
                    rollout,
                    seconds: next_s + finish_start.elapsed().as_secs_f64(),
                })
            }
            // a stop during the next rollout drops it, and its observation statistics
            None => self.collector.set_normalizer(normalizer),
        }
        Ok(())
    }

    /// [`TrainError::NonFinite`] when the update left a loss or parameter non-finite.
    fn check_finite(&self, update: &UpdateReport, batch: &Batch) -> Result<(), TrainError> {
        match non_finite(update, &self.learner, batch) {
            Some(what) => Err(TrainError::NonFinite {
                epoch: self.state.epoch + 1,
                what,
            }),
            None => Ok(()),
        }
    }

    /// Counts the epoch in the run's state and makes its report: the metrics row, the
    /// update's report and the episodes, and the evaluation when one is due.
    fn close_epoch(
        &mut self,
        rollout: crate::rollout::Rollout,
        rollout_s: f64,
        update: UpdateReport,
        normalizer: Option<RunningMeanStd>,
    ) -> EpochReport {
        let state = &mut self.state;
        state.epoch += 1;
        state.env_steps += rollout.steps;
        state.elapsed_s = self.started.1 + self.started.0.elapsed().as_secs_f64();
        state.normalizer = normalizer;
        let stats = episode_stats(&rollout.episodes, self.config.algo.probability_factor());
        // the run's steps over its wall time: with the pipeline, an epoch's call also collects
        // the next epoch's rollout, so a ratio per call would charge that rollout to the wrong
        // epoch (and make the last epoch, with none ahead, look fast)
        let steps_per_s = state.env_steps as f64 / state.elapsed_s.max(1e-9);
        let mut row = ProgressRow::new(
            state.epoch,
            state.env_steps,
            stats.as_ref(),
            rollout.success_rate(),
            rollout.unstable(),
            &update,
            EpochTimes {
                rollout_s,
                sim_s: rollout.sim_s,
                steps_per_s,
                time_s: state.elapsed_s,
            },
        );
        let mut episodes: Vec<EpisodeRecord> = rollout
            .episodes
            .iter()
            .map(|e| EpisodeRecord::new(state.epoch, Phase::Train, e))
            .collect();
        let every = self.config.eval_every;
        if let Some(evaluator) = self.evaluator.as_mut().filter(|_| every > 0) {
            if row.epoch.is_multiple_of(every) {
                let start = Instant::now();
                let evaluation = evaluator.evaluate(
                    &mut self.actor,
                    self.state.normalizer.as_ref(),
                    self.config.algo.probability_factor(),
                );
                row.set_evaluation(
                    evaluation.stats.as_ref(),
                    evaluation.unstable,
                    start.elapsed().as_secs_f64(),
                );
                episodes.extend(
                    evaluation
                        .episodes
                        .iter()
                        .map(|e| EpisodeRecord::new(row.epoch, Phase::Eval, e)),
                );
            }
        }
        EpochReport {
            row,
            update,
            episodes,
        }
    }

    /// The seed of epoch `epoch`'s streams: rank 0 draws a one-process run's, the others
    /// their own.
    fn epoch_seed(&self, epoch: usize) -> u64 {
        let seed = derive_seed(self.config.seed, epoch as u64, 0);
        match self.comm.rank() as u64 {
            0 => seed,
            rank => derive_seed(seed, rank, 3),
        }
    }

    /// Agrees over the ranks on whether the rollout's steps were stopped (a stop on any rank
    /// drops the rollout on all of them), then completes it with the actor's critic and, with
    /// several ranks, gathers every rank's episodes.
    fn finish_rollout(
        &mut self,
        steps: Option<crate::rollout::Rollout>,
    ) -> Option<crate::rollout::Rollout> {
        let mut stopped = [f64::from(u8::from(steps.is_none()))];
        self.comm.max(&mut stopped);
        let mut rollout = match steps {
            Some(rollout) if stopped[0] == 0.0 => rollout,
            Some(_) => {
                self.collector.discard();
                return None;
            }
            None => return None,
        };
        self.collector.finish(&mut rollout, &mut self.actor);
        if self.comm.is_distributed() {
            let num_envs = self.collector.num_envs();
            gather_episodes(&self.comm, num_envs, &mut rollout);
        }
        Some(rollout)
    }

    /// The checkpoint schedule after the last completed epoch: one is due every
    /// `checkpoint_every` epochs, at the last epoch, every `keep_checkpoint_every` epochs
    /// (kept), and when the run is being `interrupted`.
    pub fn checkpoint_due(&self, interrupted: bool) -> Option<Checkpoint> {
        let (epoch, config) = (self.state.epoch, &self.config);
        let keep =
            config.keep_checkpoint_every > 0 && epoch.is_multiple_of(config.keep_checkpoint_every);
        (interrupted
            || keep
            || epoch.is_multiple_of(config.checkpoint_every)
            || epoch == config.epochs)
            .then_some(Checkpoint { keep })
    }
}

/// The numbers that carry one [`Episode`] between ranks.
const EPISODE_WIDTH: usize = 8;

/// Every rank's episodes (in rank order, rank `r`'s environment `i` renumbered
/// `r · num_envs + i`) and steps, on every rank.
fn gather_episodes(comm: &Comm, num_envs: usize, rollout: &mut crate::rollout::Rollout) {
    // every field exactly: the seed as two 32-bit halves, the rest are small integers or f64
    let mine: Vec<f64> = rollout
        .episodes
        .iter()
        .flat_map(|e| {
            [
                e.env as f64,
                (e.seed >> 32) as f64,
                (e.seed & 0xffff_ffff) as f64,
                e.nth as f64,
                e.ret,
                e.length as f64,
                f64::from(u8::from(e.unstable)),
                e.success.map_or(-1.0, |s| f64::from(u8::from(s))),
            ]
        })
        .collect();
    let mut episodes = Vec::new();
    for (rank, theirs) in comm.gather(&mine).iter().enumerate() {
        episodes.extend(theirs.chunks_exact(EPISODE_WIDTH).map(|e| Episode {
            env: rank * num_envs + e[0] as usize,
            seed: ((e[1] as u64) << 32) | e[2] as u64,
            nth: e[3] as usize,
            ret: e[4],
            length: e[5] as usize,
            unstable: e[6] != 0.0,
            success: (e[7] >= 0.0).then_some(e[7] != 0.0),
        }));
    }
    let mut steps = [rollout.steps as f64];
    comm.sum(&mut steps);
    rollout.episodes = episodes;
    rollout.steps = steps[0] as u64;
}

/// What is not finite after an update, if anything: a loss, the KL, the entropy, or a
/// parameter, followed by [`batch_summary`] of the epoch's batch and, when the batch's
/// observations or rewards-to-go hold non-finite values, that the rollout brought them (the
/// networks were finite after the last update, so the environment produced them).
fn non_finite<B: Backend, F: PolicyFamily>(
    report: &UpdateReport,
    learner: &Learner<B, F>,
    batch: &Batch,
) -> Option<String>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    non_finite_value(report, learner).map(|what| {
        // read only on the error path: the batch is not scanned after a good update
        let from_env = [&batch.obs, &batch.ret]
            .iter()
            .any(|field| field.iter().any(|x| !x.is_finite()));
        let summary = batch_summary(batch);
        if from_env {
            format!(
                "{what} ({summary}); the environment returned non-finite observations or rewards, which the update only met"
            )
        } else {
            format!("{what} ({summary})")
        }
    })
}

/// The largest magnitude of each of the batch's float fields, and the fields holding
/// non-finite entries (with how many): where a non-finite update came from.
fn batch_summary(batch: &Batch) -> String {
    let fields: [(&str, &[f32]); 8] = [
        ("obs", &batch.obs),
        ("actions", &batch.actions),
        ("logp", &batch.logp),
        ("dist", &batch.dist),
        ("value", &batch.value),
        ("delta", &batch.delta),
        ("adv", &batch.adv),
        ("ret", &batch.ret),
    ];
    let mut parts = vec![format!("the epoch's batch: {} transitions", batch.len)];
    for (name, values) in fields {
        let bad = values.iter().filter(|v| !v.is_finite()).count();
        let max = values
            .iter()
            .filter(|v| v.is_finite())
            .fold(0.0f32, |m, v| m.max(v.abs()));
        parts.push(match bad {
            0 => format!("max |{name}| {max:.4e}"),
            _ => format!("max |{name}| {max:.4e} and {bad} non-finite"),
        });
    }
    parts.push(format!("adv_scale {:.4e}", batch.adv_scale));
    parts.join(", ")
}

/// [`non_finite`]'s check of the report and the parameters.
fn non_finite_value<B: Backend, F: PolicyFamily>(
    report: &UpdateReport,
    learner: &Learner<B, F>,
) -> Option<String>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
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

/// The config keys [`Trainer::from_envs`] cannot apply to environments it is given, refused
/// unless they are no-ops there.
fn check_given_envs(config: &TrainConfig, envs: &VecEnv) -> Result<(), TrainError> {
    let refuse = |field: &str, value: String, rule: &str| {
        Err(TrainError::Config(ConfigError::new(
            field,
            value,
            &format!("{rule} with Trainer::from_envs, which steps the environments as given"),
        )))
    };
    if config.eval_every > 0 {
        return refuse(
            "eval_every",
            config.eval_every.to_string(),
            "must be 0 (the evaluation makes its environment from the registry: use Trainer::new with a registered environment)",
        );
    }
    if config.max_episode_steps > 0 {
        return refuse(
            "max_episode_steps",
            config.max_episode_steps.to_string(),
            "must be 0 (wrap each environment in apo_envs::TimeLimit instead)",
        );
    }
    if config.episode_reset != EpisodeReset::default() {
        return refuse(
            "episode_reset",
            format!("{:?}", config.episode_reset),
            "must be `epoch` (wrap each environment in apo_envs::FixedReset instead)",
        );
    }
    if config.physics != apo_envs::mujoco::Physics::default() {
        return refuse(
            "physics",
            format!("{:?}", config.physics),
            "must be the default (it chooses how registered MuJoCo tasks are built)",
        );
    }
    if let (ActionMapping::Rescale, apo_envs::Space::Box { low, high, .. }) =
        (config.actions, envs.action_space())
    {
        if low.iter().any(|&l| l != -1.0) || high.iter().any(|&h| h != 1.0) {
            return refuse(
                "actions",
                "rescale".to_string(),
                "needs an action box of [-1, 1] (wrap each environment in apo_envs::RescaleAction, or set actions = raw to send the samples unmapped)",
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::batch_summary;
    use apo_core::Batch;

    #[test]
    fn the_batch_summary_names_the_largest_magnitudes_and_the_non_finite_fields() {
        let batch = Batch {
            len: 2,
            obs: vec![0.5, -3.0, f32::NAN, 1.0],
            actions: vec![0.25, -0.5],
            logp: vec![-1.0, -2.0],
            dist: vec![0.0, 0.0],
            value: vec![2.0, -4.5],
            delta: vec![f32::INFINITY, 1.0],
            adv: vec![1.0, -1.0],
            ret: vec![3.0, 3.0],
            adv_scale: 2.0,
            ..Batch::default()
        };
        let summary = batch_summary(&batch);
        assert!(
            summary.starts_with("the epoch's batch: 2 transitions"),
            "{summary}"
        );
        assert!(
            summary.contains("max |obs| 3.0000e0 and 1 non-finite"),
            "{summary}"
        );
        assert!(summary.contains("max |value| 4.5000e0,"), "{summary}");
        assert!(
            summary.contains("max |delta| 1.0000e0 and 1 non-finite"),
            "{summary}"
        );
        assert!(!summary.contains("max |adv| 1.0000e0 and"), "{summary}");
        assert!(summary.ends_with("adv_scale 2.0000e0"), "{summary}");
    }
}
