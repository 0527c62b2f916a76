//! The rollout buffer: what one epoch collected, and the per-path post-processing
//! (one-step advantages, GAE advantages, rewards-to-go).
//!
//! For each step the buffer stores the observation, the action, its log-probability under
//! the collecting policy π_j, π_j's distribution parameters, the critic's `V(s_t)` and the
//! reward. When a path ends, [`RolloutBuffer::finish_path`] takes the value to bootstrap
//! from: `0` when the episode terminated, `V(s_T)` of the last observation when it was
//! truncated by the time limit or cut by the end of the epoch. It then computes, with
//! `V(s_{T}) = last_value`:
//!
//! * `delta_t = r_t + γ V(s_{t+1}) − V(s_t)` — the one-step advantage `A(s, a, s')`;
//! * `adv_t = Σ_l (γλ)^l delta_{t+l}` — GAE(γ, λ), normalized over the whole batch in [`RolloutBuffer::take`];
//! * `ret_t = Σ_l γ^l r_{t+l} + γ^{T−t} last_value` — discounted rewards-to-go, the value targets.

use crate::collective::Comm;

/// Host arrays of one epoch's transitions, ready to become tensors. Row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch {
    /// Number of transitions `n`.
    pub len: usize,
    /// Observations, `[n, observation_dim]`.
    pub obs: Vec<f32>,
    /// Actions, `[n, action_width]` (one-hot rows for discrete actions).
    pub actions: Vec<f32>,
    /// `log π_j(a_t | s_t)`, `[n]`.
    pub logp: Vec<f32>,
    /// π_j's distribution parameters, `[n, dist_width]` (Gaussian: means then log-stds; categorical: logits).
    pub dist: Vec<f32>,
    /// Critic values `V(s_t)` at collection time, `[n]`.
    pub value: Vec<f32>,
    /// One-step advantages `delta_t`, `[n]`.
    pub delta: Vec<f32>,
    /// GAE advantages, normalized to mean 0 and standard deviation 1, `[n]`.
    pub adv: Vec<f32>,
    /// Rewards-to-go, `[n]`.
    pub ret: Vec<f32>,
    /// The standard deviation σ_A the raw GAE advantages were divided by when `adv` was
    /// normalized (over every rank's batch); 1 for a batch whose `adv` was given as it is.
    /// APO's scale-free penalty (`PenaltyUnits::Advantage`) measures `delta` and `value` in
    /// this unit.
    pub adv_scale: f64,
    /// The rewards `r_t` as the environment gave them, `[n]` (what [`crate::shaping`]
    /// reshapes before computing `delta`, `adv` and `ret` again).
    pub reward: Vec<f32>,
    /// The paths the rows form, in row order: each ends at a row and says what it bootstrapped
    /// from and whether an episode ended there.
    pub paths: Vec<PathEnd>,
}

/// The end of one path of a [`Batch`]: the path runs from the previous path's end (or row 0)
/// to `end` (exclusive).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathEnd {
    /// The row after the path's last step.
    pub end: usize,
    /// `V(s_T)` the path bootstrapped from (0 when the episode terminated).
    pub last_value: f32,
    /// Whether an episode ended with the path (terminated or truncated by the time limit);
    /// `false` for a path the end of the epoch cut, whose episode's return is not known.
    pub episode: bool,
}

impl Default for Batch {
    fn default() -> Self {
        Self {
            len: 0,
            obs: Vec::new(),
            actions: Vec::new(),
            logp: Vec::new(),
            dist: Vec::new(),
            value: Vec::new(),
            delta: Vec::new(),
            adv: Vec::new(),
            ret: Vec::new(),
            adv_scale: 1.0,
            reward: Vec::new(),
            paths: Vec::new(),
        }
    }
}

impl Batch {
    /// The transitions `rows` (a contiguous range of `0..len`), for example one rank's share
    /// of a batch. The advantages are copied as they are (not normalized again); a path that
    /// `rows` cuts keeps the part inside, as a path cut by the epoch's end (bootstrapping from
    /// the value of the row after the cut). Shaping each part of a batch cut this way is not
    /// shaping the whole: the parts' paths and returns are the pieces'.
    ///
    /// # Panics
    /// If `rows` reaches past `len`.
    pub fn rows(&self, rows: std::ops::Range<usize>) -> Batch {
        assert!(
            rows.start <= rows.end && rows.end <= self.len,
            "Batch::rows: {rows:?} is outside 0..{}",
            self.len
        );
        let n = self.len.max(1);
        let part = |v: &[f32]| {
            let width = v.len() / n;
            v[rows.start * width..rows.end * width].to_vec()
        };
        Batch {
            len: rows.len(),
            obs: part(&self.obs),
            actions: part(&self.actions),
            logp: part(&self.logp),
            dist: part(&self.dist),
            value: part(&self.value),
            delta: part(&self.delta),
            adv: part(&self.adv),
            ret: part(&self.ret),
            adv_scale: self.adv_scale,
            reward: part(&self.reward),
            paths: self
                .path_ranges()
                .filter(|&(start, end, _)| {
                    rows.start < rows.end && end > rows.start && start < rows.end
                })
                .map(|(start, end, path)| PathEnd {
                    end: end.min(rows.end) - rows.start,
                    // a path `rows` cuts bootstraps from the value of the row after the cut
                    last_value: if end > rows.end {
                        self.value[rows.end]
                    } else {
                        path.last_value
                    },
                    episode: path.episode && start >= rows.start && end <= rows.end,
                })
                .collect(),
        }
    }

    /// Each path's rows `start..end` with its end.
    pub fn path_ranges(&self) -> impl Iterator<Item = (usize, usize, PathEnd)> + '_ {
        let mut start = 0;
        self.paths.iter().map(move |&path| {
            let range = (start, path.end, path);
            start = path.end;
            range
        })
    }
}

/// Appends one path's one-step advantages, (unnormalized) GAE(γ, λ) advantages and
/// rewards-to-go, computed in f64 from its `rewards [T]`, its critic `values [T]` and the
/// value `last_value` it bootstraps from:
/// `delta_t = r_t + γ V(s_{t+1}) − V(s_t)`, `adv_t = delta_t + γλ adv_{t+1}`,
/// `ret_t = r_t + γ ret_{t+1}`, with `V(s_T) = ret_T = last_value`.
///
/// # Panics
/// If `rewards` and `values` differ in length.
#[allow(clippy::too_many_arguments)]
pub fn path_advantages(
    rewards: &[f32],
    values: &[f32],
    last_value: f32,
    gamma: f64,
    lambda: f64,
    delta: &mut Vec<f32>,
    adv: &mut Vec<f32>,
    ret: &mut Vec<f32>,
) {
    assert_eq!(rewards.len(), values.len(), "one value per reward");
    let (from, len) = (delta.len(), rewards.len());
    delta.resize(from + len, 0.0);
    adv.resize(adv.len() + len, 0.0);
    ret.resize(ret.len() + len, 0.0);
    let (adv_from, ret_from) = (adv.len() - len, ret.len() - len);
    let gl = gamma * lambda;
    let mut next_value = f64::from(last_value);
    let mut adv_acc = 0.0f64;
    let mut ret_acc = f64::from(last_value);
    for t in (0..len).rev() {
        let r = f64::from(rewards[t]);
        let v = f64::from(values[t]);
        let d = r + gamma * next_value - v;
        adv_acc = d + gl * adv_acc;
        ret_acc = r + gamma * ret_acc;
        delta[from + t] = d as f32;
        adv[adv_from + t] = adv_acc as f32;
        ret[ret_from + t] = ret_acc as f32;
        next_value = v;
    }
}

/// Sizes of what is stored per step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BufferLayout {
    /// Observation dimension.
    pub observation_dim: usize,
    /// Action width (action dimension, or number of actions for one-hot rows).
    pub action_width: usize,
    /// Width of the distribution parameters (2 × action dimension, or number of actions).
    pub dist_width: usize,
}

/// Collects transitions over an epoch and post-processes each finished path.
#[derive(Debug, Clone)]
pub struct RolloutBuffer {
    layout: BufferLayout,
    gamma: f64,
    lambda: f64,
    batch: Batch,
    /// The steps a batch has room for from the start.
    capacity: usize,
    rewards: Vec<f32>,
    path_start: usize,
    /// Paths ended by [`RolloutBuffer::end_path`] or [`RolloutBuffer::cut_path`] and not yet
    /// finished: where each ends, the row of `bootstrap_obs` to bootstrap from (`None`: from
    /// 0), and whether an episode ended there.
    pending: Vec<(usize, Option<usize>, bool)>,
    /// The observations to bootstrap pending paths from, `[rows, observation_dim]`.
    bootstrap_obs: Vec<f32>,
}

impl RolloutBuffer {
    /// An empty buffer with room for `capacity` steps.
    pub fn new(layout: BufferLayout, gamma: f64, lambda: f64, capacity: usize) -> Self {
        Self {
            layout,
            gamma,
            lambda,
            batch: Self::empty_batch(layout, capacity),
            capacity,
            rewards: Vec::with_capacity(capacity),
            path_start: 0,
            pending: Vec::new(),
            bootstrap_obs: Vec::new(),
        }
    }

    /// An empty batch with room for `capacity` steps of `layout`.
    fn empty_batch(layout: BufferLayout, capacity: usize) -> Batch {
        Batch {
            len: 0,
            obs: Vec::with_capacity(capacity * layout.observation_dim),
            actions: Vec::with_capacity(capacity * layout.action_width),
            logp: Vec::with_capacity(capacity),
            dist: Vec::with_capacity(capacity * layout.dist_width),
            value: Vec::with_capacity(capacity),
            delta: Vec::with_capacity(capacity),
            adv: Vec::with_capacity(capacity),
            ret: Vec::with_capacity(capacity),
            adv_scale: 1.0,
            reward: Vec::new(),
            paths: Vec::new(),
        }
    }

    /// The sizes this buffer stores.
    pub fn layout(&self) -> BufferLayout {
        self.layout
    }

    /// Number of steps stored.
    pub fn len(&self) -> usize {
        self.batch.len
    }

    /// Whether no step is stored.
    pub fn is_empty(&self) -> bool {
        self.batch.len == 0
    }

    /// Stores one step: `obs [observation_dim]`, `action [action_width]`, `dist [dist_width]`.
    ///
    /// # Panics
    /// If a slice has the wrong length.
    pub fn store(
        &mut self,
        obs: &[f32],
        action: &[f32],
        logp: f32,
        dist: &[f32],
        value: f32,
        reward: f32,
    ) {
        assert_eq!(obs.len(), self.layout.observation_dim, "observation width");
        assert_eq!(action.len(), self.layout.action_width, "action width");
        assert_eq!(dist.len(), self.layout.dist_width, "distribution width");
        let b = &mut self.batch;
        b.obs.extend_from_slice(obs);
        b.actions.extend_from_slice(action);
        b.logp.push(logp);
        b.dist.extend_from_slice(dist);
        b.value.push(value);
        self.rewards.push(reward);
        b.len += 1;
    }

    /// Ends the current path with its episode, bootstrapping from `last_value` (0 when
    /// terminated, `V(s_T)` when truncated by the time limit), and computes its `delta`,
    /// (unnormalized) GAE advantages and rewards-to-go. A path the end of the epoch cuts ends
    /// with [`RolloutBuffer::finish_cut_path`].
    ///
    /// # Panics
    /// If paths ended by [`RolloutBuffer::end_path`] are still waiting for
    /// [`RolloutBuffer::finish_paths`].
    pub fn finish_path(&mut self, last_value: f32) {
        self.finish_now(last_value, true);
    }

    /// [`RolloutBuffer::finish_path`] for the path the end of the epoch cuts, bootstrapping from
    /// `V(s_T)` = `last_value`: it ends no episode (its return is not known; see
    /// [`PathEnd::episode`]).
    ///
    /// # Panics
    /// As [`RolloutBuffer::finish_path`].
    pub fn finish_cut_path(&mut self, last_value: f32) {
        self.finish_now(last_value, false);
    }

    fn finish_now(&mut self, last_value: f32, episode: bool) {
        assert!(
            self.pending.is_empty(),
            "finish_path with paths waiting for finish_paths"
        );
        self.finish_path_at(self.batch.len, last_value, episode);
    }

    /// Ends the current path without computing anything yet: the critic's values of its steps,
    /// its bootstrap value and its advantages come from [`RolloutBuffer::finish_paths`]. So a
    /// rollout needs no critic while it runs (the values of a whole batch are then one batched
    /// call). `bootstrap`: `None` to bootstrap from 0 (terminated), else the observation
    /// `[observation_dim]` whose `V` to bootstrap from (truncated, or cut by the epoch's end).
    /// The values stored with [`RolloutBuffer::store`] for these steps are replaced. The path
    /// ends an episode (terminated, or truncated by the time limit).
    ///
    /// # Panics
    /// If `bootstrap` has the wrong length.
    pub fn end_path(&mut self, bootstrap: Option<&[f32]>) {
        self.pend(bootstrap, true);
    }

    /// [`RolloutBuffer::end_path`] for the path the end of the epoch cuts: it bootstraps from
    /// `V(obs)` and ends no episode (its return is not known; see [`PathEnd::episode`]).
    ///
    /// # Panics
    /// If `obs` has the wrong length.
    pub fn cut_path(&mut self, obs: &[f32]) {
        self.pend(Some(obs), false);
    }

    fn pend(&mut self, bootstrap: Option<&[f32]>, episode: bool) {
        let row = bootstrap.map(|obs| {
            assert_eq!(obs.len(), self.layout.observation_dim, "observation width");
            self.bootstrap_obs.extend_from_slice(obs);
            self.bootstrap_obs.len() / self.layout.observation_dim - 1
        });
        self.pending.push((self.batch.len, row, episode));
    }

    /// Finishes every path ended by [`RolloutBuffer::end_path`] since the last finished one:
    /// `critic(obs, rows, out)` fills `out` with `V` of `obs: [rows, observation_dim]` →
    /// `[rows]`; it is called once for those paths' steps and once for their bootstrap
    /// observations. Then each path's `delta`, advantages and rewards-to-go are computed as
    /// [`RolloutBuffer::finish_path`] computes them.
    pub fn finish_paths(&mut self, mut critic: impl FnMut(&[f32], usize, &mut Vec<f32>)) {
        let Some(&(end, _, _)) = self.pending.last() else {
            return;
        };
        let (start, dim) = (self.path_start, self.layout.observation_dim);
        let mut values = Vec::with_capacity(end - start);
        critic(
            &self.batch.obs[start * dim..end * dim],
            end - start,
            &mut values,
        );
        self.batch.value[start..end].copy_from_slice(&values[..end - start]);
        let mut bootstraps = Vec::new();
        let rows = self.bootstrap_obs.len() / dim;
        if rows > 0 {
            critic(&self.bootstrap_obs, rows, &mut bootstraps);
        }
        for (end, row, episode) in std::mem::take(&mut self.pending) {
            let last_value = row.map_or(0.0, |r| bootstraps[r]);
            self.finish_path_at(end, last_value, episode);
        }
        self.bootstrap_obs.clear();
    }

    /// Finishes the path from `path_start` to `end` (exclusive), bootstrapping from
    /// `last_value`.
    fn finish_path_at(&mut self, end: usize, last_value: f32, episode: bool) {
        let start = self.path_start;
        let b = &mut self.batch;
        path_advantages(
            &self.rewards[start..end],
            &b.value[start..end],
            last_value,
            self.gamma,
            self.lambda,
            &mut b.delta,
            &mut b.adv,
            &mut b.ret,
        );
        b.paths.push(PathEnd {
            end,
            last_value,
            episode,
        });
        self.path_start = end;
    }

    /// Number of steps of the path in progress (0 right after [`RolloutBuffer::finish_path`]
    /// or [`RolloutBuffer::end_path`]).
    pub fn path_len(&self) -> usize {
        let open = self
            .pending
            .last()
            .map_or(self.path_start, |&(end, _, _)| end);
        self.batch.len - open
    }

    /// Takes the epoch's batch, with advantages normalized to mean 0 and standard
    /// deviation 1, and empties the buffer.
    ///
    /// # Panics
    /// If a path was left unfinished (call [`RolloutBuffer::finish_path`] first).
    pub fn take(&mut self) -> Batch {
        Self::take_all(std::slice::from_mut(self))
    }

    /// Takes the batches of several buffers (one per environment of a vector) as one
    /// batch, in buffer order, with advantages normalized over all of it; empties them.
    ///
    /// # Panics
    /// If a path was left unfinished in any buffer.
    pub fn take_all(buffers: &mut [RolloutBuffer]) -> Batch {
        Self::take_all_over(buffers, &Comm::default())
    }

    /// [`RolloutBuffer::take_all`] on one rank of `comm`: the advantages are normalized with
    /// the mean and standard deviation of every rank's batch.
    ///
    /// # Panics
    /// If a path was left unfinished in any buffer.
    pub fn take_all_over(buffers: &mut [RolloutBuffer], comm: &Comm) -> Batch {
        let mut batch = Batch::default();
        for buffer in buffers.iter_mut() {
            assert!(
                buffer.path_len() == 0 && buffer.pending.is_empty(),
                "take() with an unfinished path"
            );
            // the next epoch's steps go into a batch with room for them (growing one step by
            // step would copy it about twice over)
            let room = RolloutBuffer::empty_batch(buffer.layout, buffer.capacity);
            let mut part = std::mem::replace(&mut buffer.batch, room);
            part.reward = std::mem::take(&mut buffer.rewards);
            buffer.rewards.reserve(buffer.capacity);
            buffer.path_start = 0;
            if batch.len == 0 {
                batch = part;
                continue;
            }
            let offset = batch.len;
            batch.paths.extend(part.paths.iter().map(|p| PathEnd {
                end: p.end + offset,
                ..*p
            }));
            batch.reward.extend(part.reward);
            batch.len += part.len;
            batch.obs.extend(part.obs);
            batch.actions.extend(part.actions);
            batch.logp.extend(part.logp);
            batch.dist.extend(part.dist);
            batch.value.extend(part.value);
            batch.delta.extend(part.delta);
            batch.adv.extend(part.adv);
            batch.ret.extend(part.ret);
        }
        batch.adv_scale = normalize_over(&mut batch.adv, comm);
        batch
    }
}

/// Normalizes `x` in place to mean 0 and (population) standard deviation 1; a constant
/// vector becomes all zeros. Returns the standard deviation it divided by (at least 1e-8;
/// 1 for an empty `x`).
pub fn normalize(x: &mut [f32]) -> f64 {
    normalize_over(x, &Comm::default())
}

/// [`normalize`] with the mean and standard deviation of the union of every rank's `x`.
pub fn normalize_over(x: &mut [f32], comm: &Comm) -> f64 {
    let mut totals = [x.iter().map(|&v| f64::from(v)).sum::<f64>(), x.len() as f64];
    comm.sum(&mut totals);
    if totals[1] == 0.0 {
        return 1.0;
    }
    let n = totals[1];
    let mean = totals[0] / n;
    let mut squares = [x
        .iter()
        .map(|&v| (f64::from(v) - mean).powi(2))
        .sum::<f64>()];
    comm.sum(&mut squares);
    let var = squares[0] / n;
    let std = var.sqrt().max(1e-8);
    for v in x {
        *v = ((f64::from(*v) - mean) / std) as f32;
    }
    std
}
