//! Rollout collection: a vector of environments stepped with one batched actor call per step.
//!
//! The epoch's steps are split over `num_envs` environments (rounded up to a multiple of
//! `num_envs`), stepped together by a [`VecEnv`] (on worker threads when asked; the results do
//! not depend on it). At the start of each epoch every environment is reset with a seed derived
//! from the epoch's seed and the action-sampling RNG is reseeded the same way (as SpinningUp
//! resets its environment when an epoch ends), so an epoch depends only on the seed and the
//! networks: a resumed run reproduces an uninterrupted one.
//!
//! # Bootstrapping
//!
//! A path ending by termination bootstraps from 0; one truncated by the time limit from
//! `V(final observation)` (or from 0, with [`Collector::bootstrap_time_limit`]`(false)`); one
//! cut by the end of the epoch from `V(current observation)`.
//! An episode ended by a simulator instability is treated as terminated (value 0).
//!
//! # Every episode counts
//!
//! Every episode that ends in the epoch is one [`Episode`] of [`Rollout::episodes`], with the
//! return it had reached when it ended: an episode ended by a simulator instability is kept
//! with [`Episode::unstable`] set (and counted by [`Rollout::unstable`]), so a policy that drives
//! the simulator into failure cannot raise its worst return by failing.
//!
//! # Success
//!
//! For tasks that judge success (the hand tasks), an episode counts as a success when its last
//! step reports one, as Gymnasium-Robotics' success rate is measured; an unstable episode of
//! such a task counts as a failure ([`Rollout::success_rate`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use apo_core::inference::ActBuffers;
use apo_core::{ActionKind, BufferLayout, Comm, RolloutBuffer};
use apo_envs::{RunningMeanStd, Space, VecEnv, VecStep};
use rand::rngs::StdRng;
use rand::SeedableRng;

use crate::actor::Act;
use crate::seed::derive_seed;

/// The policy's action kind for an environment's action space.
pub fn action_kind(space: &Space) -> ActionKind {
    match space {
        Space::Box { low, .. } => ActionKind::Continuous { dim: low.len() },
        Space::Discrete { n } => ActionKind::Discrete { n: *n },
    }
}

/// One episode that ended: where it was played and how it went.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Episode {
    /// The environment of the vector that played it (with several MPI ranks, rank `r`'s
    /// environment `i` is `r · num_envs + i`).
    pub env: usize,
    /// The seed of the reset that started the environment's stream of episodes…
    pub seed: u64,
    /// …and which episode of that stream it is (0: the one right after the seeded reset; the
    /// later ones follow automatic resets, which continue the environment's random stream).
    pub nth: usize,
    /// Its undiscounted return, up to the step that ended it.
    pub ret: f64,
    /// Its length in steps.
    pub length: usize,
    /// Ended by a simulator instability (still counted in every return statistic).
    pub unstable: bool,
    /// For tasks that judge success: whether it ended in success (an unstable episode of such a
    /// task is a failure); `None` for tasks that do not judge success.
    pub success: Option<bool>,
}

/// The statistics of `episodes` (every one counted, unstable ones included) with probability
/// factor `k`; `None` when there is none.
pub fn episode_stats(episodes: &[Episode], k: f64) -> Option<apo_core::EpisodeStats> {
    let returns: Vec<f64> = episodes.iter().map(|e| e.ret).collect();
    let lengths: Vec<usize> = episodes.iter().map(|e| e.length).collect();
    apo_core::EpisodeStats::from_episodes(&returns, &lengths, k)
}

/// The fraction of the judged `episodes` that ended in success; `None` when none was judged.
pub fn success_rate(episodes: &[Episode]) -> Option<f64> {
    let (judged, succeeded) = episodes
        .iter()
        .filter_map(|e| e.success)
        .fold((0usize, 0usize), |(j, s), ok| (j + 1, s + usize::from(ok)));
    (judged > 0).then(|| succeeded as f64 / judged as f64)
}

/// What one epoch's rollout produced.
pub struct Rollout {
    /// The transitions.
    pub batch: apo_core::Batch,
    /// Every episode that ended in the epoch, unstable ones included, in the order they ended
    /// (by vector step, then environment).
    pub episodes: Vec<Episode>,
    /// Environment steps taken.
    pub steps: u64,
    /// Wall time inside the environments' `reset` and `step` calls, seconds: the simulator's
    /// share of the rollout (with several environments on several threads, the vector step's
    /// wall time).
    pub sim_s: f64,
}

impl Rollout {
    /// Episodes ended by a simulator instability.
    pub fn unstable(&self) -> usize {
        self.episodes.iter().filter(|e| e.unstable).count()
    }

    /// The fraction of the judged episodes that ended in success; `None` when no episode that
    /// ended was judged.
    pub fn success_rate(&self) -> Option<f64> {
        success_rate(&self.episodes)
    }
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
    buffers: Vec<RolloutBuffer>,
    normalizer: Option<RunningMeanStd>,
    steps_per_env: usize,
    bootstrap_time_limit: bool,
    /// The ranks of a data-parallel run (advantages normalized and observation statistics
    /// merged over all of them).
    comm: Comm,
    /// With several ranks and a normalizer, during a rollout: the statistics at its start and
    /// this rank's additions, merged over the ranks by [`Collector::finish`].
    merge: Option<(RunningMeanStd, RunningMeanStd)>,
    /// Per environment: whether its task has judged success on some step (an unstable step
    /// does not say, so an unstable episode of such a task is counted as a failure).
    judges_success: Vec<bool>,
}

impl Collector {
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
        let steps_per_env = steps_per_epoch.div_ceil(n);
        let layout = BufferLayout {
            observation_dim: obs_dim,
            action_width: action.width(),
            dist_width: action.dist_width(),
        };
        Self {
            obs: vec![0.0; n * obs_dim],
            obs_norm: vec![0.0; n * obs_dim],
            env_actions: Vec::with_capacity(n * envs.act_dim()),
            out: vec![VecStep::default(); n],
            act: ActBuffers::default(),
            buffers: (0..n)
                .map(|_| RolloutBuffer::new(layout, gamma, lambda, steps_per_env))
                .collect(),
            normalizer,
            steps_per_env,
            bootstrap_time_limit: true,
            envs,
            comm: Comm::default(),
            merge: None,
            judges_success: vec![false; n],
        }
    }

    /// Makes this collector rank `comm.rank()`'s of a data-parallel run collecting
    /// `steps_per_rank` steps (rounded up to whole vector steps): advantages are normalized
    /// over every rank's batch and, after each rollout, the observation normalizer holds the
    /// statistics of every rank's observations (merged in rank order, so equal on every rank).
    pub fn distribute(&mut self, comm: Comm, steps_per_rank: usize) {
        self.steps_per_env = steps_per_rank.div_ceil(self.envs.num_envs());
        self.comm = comm;
    }

    /// Whether paths truncated by the time limit bootstrap from `V(final observation)`
    /// (default `true`) or from 0.
    pub fn bootstrap_time_limit(mut self, bootstrap: bool) -> Self {
        self.bootstrap_time_limit = bootstrap;
        self
    }

    /// The number of environments stepped together.
    pub fn num_envs(&self) -> usize {
        self.envs.num_envs()
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
        actor: &mut dyn Act,
        seed: u64,
        stop: &AtomicBool,
        progress: &mut dyn FnMut(u64),
    ) -> Option<Rollout> {
        let mut rollout = self.collect_steps(actor, seed, stop, progress)?;
        self.finish(&mut rollout, actor);
        Some(rollout)
    }

    /// The rollout's steps with `actor`'s policy (its critic is not called), without the
    /// batch: the paths are ended but their values and advantages wait for
    /// [`Collector::finish`]. Makes no collective call, so it may run while another thread
    /// updates the critic. `None` when `stop` was raised.
    pub(crate) fn collect_steps(
        &mut self,
        actor: &mut dyn Act,
        seed: u64,
        stop: &AtomicBool,
        progress: &mut dyn FnMut(u64),
    ) -> Option<Rollout> {
        let n = self.envs.num_envs();
        let obs_dim = self.envs.obs_dim();
        let mut rng = StdRng::seed_from_u64(derive_seed(seed, 0, 1));
        let reset_seed = derive_seed(seed, 0, 0);
        let sim = Instant::now();
        self.envs.reset(Some(reset_seed), &mut self.obs);
        let mut sim_s = sim.elapsed().as_secs_f64();
        let (mut ep_ret, mut ep_len, mut nth) = (vec![0.0f64; n], vec![0usize; n], vec![0; n]);
        let mut rollout = Rollout {
            batch: Default::default(),
            episodes: vec![],
            steps: 0,
            sim_s: 0.0,
        };
        let mut row = vec![0.0f32; obs_dim];
        self.merge = (self.comm.is_distributed())
            .then(|| {
                self.normalizer
                    .as_ref()
                    .map(|rms| (rms.clone(), RunningMeanStd::new(rms.dim())))
            })
            .flatten();
        for t in 0..self.steps_per_env {
            if stop.load(Ordering::Relaxed) {
                self.discard();
                return None;
            }
            if t % PROGRESS_EVERY == 0 {
                progress(rollout.steps);
            }
            if let Some(rms) = &mut self.normalizer {
                rms.update(&self.obs, n);
            }
            if let Some((_, added)) = &mut self.merge {
                added.update(&self.obs, n);
            }
            let mut obs_norm = std::mem::take(&mut self.obs_norm);
            self.normalized(&self.obs, &mut obs_norm);
            actor.act(&obs_norm, n, false, &mut rng, &mut self.act);
            self.env_actions.clear();
            self.env_actions.extend_from_slice(&self.act.env_actions);
            let sim = Instant::now();
            self.envs
                .step(&self.env_actions, &mut self.obs, &mut self.out);
            sim_s += sim.elapsed().as_secs_f64();
            rollout.steps += n as u64;
            let (aw, dw) = (self.act.actions.len() / n, self.act.dist.len() / n);
            for i in 0..n {
                let step = self.out[i];
                // V(s_t) comes later, from `finish`
                self.buffers[i].store(
                    &obs_norm[i * obs_dim..(i + 1) * obs_dim],
                    &self.act.actions[i * aw..(i + 1) * aw],
                    self.act.logp[i],
                    &self.act.dist[i * dw..(i + 1) * dw],
                    0.0,
                    step.reward as f32,
                );
                ep_ret[i] += step.reward;
                ep_len[i] += 1;
                if step.info.success.is_some() {
                    self.judges_success[i] = true;
                }
                if !step.done() {
                    continue;
                }
                if step.terminated || step.info.unstable || !self.bootstrap_time_limit {
                    self.buffers[i].end_path(None);
                } else {
                    let final_obs = self
                        .envs
                        .final_obs(i)
                        .unwrap_or(&self.obs[i * obs_dim..(i + 1) * obs_dim]);
                    self.normalized(final_obs, &mut row);
                    self.buffers[i].end_path(Some(&row));
                }
                rollout.episodes.push(Episode {
                    env: i,
                    seed: reset_seed.wrapping_add(i as u64),
                    nth: nth[i],
                    ret: ep_ret[i],
                    length: ep_len[i],
                    unstable: step.info.unstable,
                    success: match step.info.success {
                        Some(success) => Some(success && !step.info.unstable),
                        None => (self.judges_success[i] && step.info.unstable).then_some(false),
                    },
                });
                ep_ret[i] = 0.0;
                ep_len[i] = 0;
                nth[i] += 1;
            }
            self.obs_norm = obs_norm;
        }
        for i in 0..n {
            if self.buffers[i].path_len() > 0 {
                self.normalized(&self.obs[i * obs_dim..(i + 1) * obs_dim], &mut row);
                self.buffers[i].cut_path(&row);
            }
        }
        rollout.sim_s = sim_s;
        Some(rollout)
    }

    /// Completes a rollout of [`Collector::collect_steps`]: `V(s_t)` of every step and the
    /// bootstrap values from `actor`'s critic (one batched call per environment), the
    /// advantages and rewards-to-go, the batch (advantages normalized over every rank's), and,
    /// with several ranks, the observation statistics merged over them.
    pub(crate) fn finish(&mut self, rollout: &mut Rollout, actor: &mut dyn Act) {
        let mut critic = |obs: &[f32], n: usize, out: &mut Vec<f32>| {
            out.clear();
            out.extend_from_slice(actor.values(obs, n));
        };
        for buffer in &mut self.buffers {
            buffer.finish_paths(&mut critic);
        }
        rollout.batch = RolloutBuffer::take_all_over(&mut self.buffers, &self.comm);
        if let Some((base, added)) = self.merge.take() {
            self.normalizer = Some(merge_ranks(&self.comm, base, &added));
        }
    }

    /// Drops a rollout stopped mid-way: the buffers are emptied for the next one.
    pub(crate) fn discard(&mut self) {
        self.merge = None;
        for buffer in &mut self.buffers {
            buffer.end_path(None);
            buffer.finish_paths(|_, n, out: &mut Vec<f32>| {
                out.clear();
                out.resize(n, 0.0);
            });
            let _ = buffer.take();
        }
    }
}

/// `base` with every rank's `added` statistics merged into it, in rank order.
fn merge_ranks(comm: &Comm, mut base: RunningMeanStd, added: &RunningMeanStd) -> RunningMeanStd {
    let mut mine = vec![added.count()];
    mine.extend_from_slice(added.mean());
    mine.extend_from_slice(added.var());
    let dim = added.dim();
    for theirs in comm.gather(&mine) {
        if theirs.len() != 1 + 2 * dim {
            continue;
        }
        let (mean, var) = theirs[1..].split_at(dim);
        if let Ok(stats) = RunningMeanStd::from_moments(mean.to_vec(), var.to_vec(), theirs[0]) {
            // same dimension by construction
            let _ = base.merge(&stats);
        }
    }
    base
}
