//! Wrappers that change an environment's episodes, actions or observations.
//!
//! - [`TimeLimit`] truncates episodes after a number of steps.
//! - [`RescaleAction`] lets the policy act in `[-1, 1]^d` whatever the box bounds.
//! - [`NormalizeObservation`] standardizes observations with a [`RunningMeanStd`].
//! - [`FixedReset`] starts every episode from the same seed.
//!
//! [`RunningMeanStd`] is also meant to be used directly on a vector of environments
//! (`[n, dim]` batches), and it serializes, so a checkpoint can save and restore it.

use serde::{Deserialize, Serialize};

use crate::env::{Action, Env, Transition};
use crate::error::EnvError;
use crate::render::{Camera, Frame, RenderError};
use crate::space::Space;

/// Ends episodes with `truncated = true` after `max_episode_steps` steps.
///
/// The step counter restarts at every [`Env::reset`]. A step that terminates is never marked
/// truncated, even on the last allowed step: a terminal state's value is 0 and must not be
/// bootstrapped. (Gymnasium's `TimeLimit` would set both flags there.)
#[derive(Debug, Clone)]
pub struct TimeLimit<E> {
    env: E,
    max_episode_steps: usize,
    elapsed_steps: usize,
}

impl<E: Env> TimeLimit<E> {
    /// Wraps `env` with a limit of `max_episode_steps` steps per episode.
    pub fn new(env: E, max_episode_steps: usize) -> Self {
        Self {
            env,
            max_episode_steps,
            elapsed_steps: 0,
        }
    }

    /// The limit of steps per episode.
    pub fn max_episode_steps(&self) -> usize {
        self.max_episode_steps
    }

    /// Steps taken since the last reset.
    pub fn elapsed_steps(&self) -> usize {
        self.elapsed_steps
    }
}

impl<E: Env> Env for TimeLimit<E> {
    fn observation_space(&self) -> &Space {
        self.env.observation_space()
    }

    fn action_space(&self) -> &Space {
        self.env.action_space()
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.elapsed_steps = 0;
        self.env.reset(seed, obs);
    }

    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let mut transition = self.env.step(action, obs);
        self.elapsed_steps += 1;
        if self.elapsed_steps >= self.max_episode_steps && !transition.terminated {
            transition.truncated = true;
        }
        transition
    }
    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        self.env.render(camera, frame)
    }
}

/// Resets the wrapped environment with the same seed at every reset, whatever seed the
/// caller passes (or none): every episode starts from the same initial state, as the
/// paper's published code did on the Gym MuJoCo tasks (`env.reset(seed=seed)` per episode).
#[derive(Debug, Clone)]
pub struct FixedReset<E> {
    env: E,
    seed: u64,
}

impl<E: Env> FixedReset<E> {
    /// Wraps `env`; every reset uses `seed`.
    pub fn new(env: E, seed: u64) -> Self {
        Self { env, seed }
    }
}

impl<E: Env> Env for FixedReset<E> {
    fn observation_space(&self) -> &Space {
        self.env.observation_space()
    }

    fn action_space(&self) -> &Space {
        self.env.action_space()
    }

    fn reset(&mut self, _seed: Option<u64>, obs: &mut [f32]) {
        self.env.reset(Some(self.seed), obs);
    }

    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        self.env.step(action, obs)
    }
    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        self.env.render(camera, frame)
    }
}

/// Lets the policy act in `[-1, 1]^d`: an action `a` is mapped linearly to
/// `low + (a + 1) / 2 · (high − low)` of the wrapped environment's box and then clipped to
/// `[low, high]`. Its action space is `[-1, 1]^d`, with the wrapped box's shape.
///
/// Needs a box action space with finite bounds. The mapping uses a buffer allocated once.
#[derive(Debug, Clone)]
pub struct RescaleAction<E> {
    env: E,
    low: Vec<f32>,
    high: Vec<f32>,
    action_space: Space,
    scratch: Vec<f32>,
}

impl<E: Env> RescaleAction<E> {
    /// Wraps `env`.
    ///
    /// # Errors
    /// [`EnvError::UnsupportedSpace`] if the action space is not a box with finite bounds
    /// `low <= high`.
    pub fn new(env: E) -> Result<Self, EnvError> {
        let unsupported = |reason| EnvError::UnsupportedSpace {
            wrapper: "RescaleAction",
            what: "action",
            space: env.action_space().clone(),
            reason,
        };
        let (low, high, shape) = match env.action_space() {
            Space::Box { low, high, shape } => (low.clone(), high.clone(), shape.clone()),
            Space::Discrete { .. } => return Err(unsupported("it needs a box")),
        };
        let finite = low
            .iter()
            .zip(&high)
            .all(|(l, h)| l.is_finite() && h.is_finite() && l <= h);
        if !finite {
            return Err(unsupported("it needs finite bounds with low <= high"));
        }
        let dim = low.len();
        Ok(Self {
            env,
            low,
            high,
            action_space: Space::Box {
                low: vec![-1.0; dim],
                high: vec![1.0; dim],
                shape,
            },
            scratch: vec![0.0; dim],
        })
    }

    /// Maps a policy action in `[-1, 1]^d` to the wrapped environment's bounds, clipped.
    ///
    /// # Panics
    /// If `action` and `out` do not both have the action dimension.
    pub fn rescale(&self, action: &[f32], out: &mut [f32]) {
        assert!(
            action.len() == self.low.len() && out.len() == self.low.len(),
            "RescaleAction: expected actions of dimension {}, got {} (output {})",
            self.low.len(),
            action.len(),
            out.len()
        );
        for (((o, a), l), h) in out.iter_mut().zip(action).zip(&self.low).zip(&self.high) {
            let (l64, h64) = (f64::from(*l), f64::from(*h));
            let mapped = l64 + (f64::from(*a) + 1.0) * 0.5 * (h64 - l64);
            *o = (mapped as f32).clamp(*l, *h);
        }
    }
}

impl<E: Env> Env for RescaleAction<E> {
    fn observation_space(&self) -> &Space {
        self.env.observation_space()
    }

    fn action_space(&self) -> &Space {
        &self.action_space
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.env.reset(seed, obs);
    }

    /// # Panics
    /// If `action` is not a continuous action of the action dimension.
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let Action::Continuous(a) = action else {
            panic!("RescaleAction: expected a continuous action, got {action:?}");
        };
        let mut scratch = std::mem::take(&mut self.scratch);
        self.rescale(a, &mut scratch);
        let transition = self.env.step(Action::Continuous(&scratch), obs);
        self.scratch = scratch;
        transition
    }
    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        self.env.render(camera, frame)
    }
}

/// Running mean and variance of vectors of dimension `dim`, updated with batches by the
/// parallel (Chan et al.) merge of Welford's statistics, kept in `f64`.
///
/// Starts empty (`count = 0`, mean 0, variance 1, so [`RunningMeanStd::normalize`] only clips
/// until the first update); after updates, `mean` and `var` are exactly the mean and the
/// population variance (divisor `count`) of every vector seen. (Gymnasium starts its count at
/// 1e-4 instead, which biases the first updates slightly.)
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunningMeanStd {
    mean: Vec<f64>,
    var: Vec<f64>,
    count: f64,
}

impl RunningMeanStd {
    /// Normalized values are clipped to `[-CLIP, CLIP]`.
    pub const CLIP: f32 = 10.0;
    /// Added to the variance before the square root in [`RunningMeanStd::normalize`].
    pub const EPSILON: f64 = 1e-8;

    /// Empty statistics for vectors of dimension `dim`.
    pub fn new(dim: usize) -> Self {
        Self {
            mean: vec![0.0; dim],
            var: vec![1.0; dim],
            count: 0.0,
        }
    }

    /// Statistics of `count` vectors with per-dimension `mean` and population `var` (for
    /// example sent by another worker).
    ///
    /// # Errors
    /// [`EnvError::DimensionMismatch`] if `var` is not as long as `mean`.
    pub fn from_moments(mean: Vec<f64>, var: Vec<f64>, count: f64) -> Result<Self, EnvError> {
        if var.len() != mean.len() {
            return Err(EnvError::DimensionMismatch {
                expected: mean.len(),
                found: var.len(),
            });
        }
        Ok(Self { mean, var, count })
    }

    /// The dimension of the vectors.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// The per-dimension mean.
    pub fn mean(&self) -> &[f64] {
        &self.mean
    }

    /// The per-dimension population variance.
    pub fn var(&self) -> &[f64] {
        &self.var
    }

    /// The number of vectors seen.
    pub fn count(&self) -> f64 {
        self.count
    }

    /// Adds a batch of `n` vectors stored row-major in `batch` (`[n, dim]`). Allocates nothing.
    ///
    /// # Panics
    /// If `batch.len() != n * dim`.
    pub fn update(&mut self, batch: &[f32], n: usize) {
        let dim = self.dim();
        assert_eq!(
            batch.len(),
            n * dim,
            "RunningMeanStd::update: batch is not [n = {n}, dim = {dim}]"
        );
        if n == 0 {
            return;
        }
        let count = n as f64;
        let total = self.count + count;
        if n == 1 {
            // one vector is its own mean with variance 0: the same merge, without the
            // strided column passes, so that it vectorizes (the rollout's case, every step)
            for ((mean, var), x) in self.mean.iter_mut().zip(&mut self.var).zip(batch) {
                merge_one(mean, var, self.count, f64::from(*x), 0.0, count, total);
            }
            self.count = total;
            return;
        }
        for (d, (mean, var)) in self.mean.iter_mut().zip(&mut self.var).enumerate() {
            let column = || batch[d..].iter().step_by(dim).map(|x| f64::from(*x));
            let batch_mean = column().sum::<f64>() / count;
            let batch_var = column()
                .map(|x| (x - batch_mean) * (x - batch_mean))
                .sum::<f64>()
                / count;
            merge_one(mean, var, self.count, batch_mean, batch_var, count, total);
        }
        self.count = total;
    }

    /// Merges statistics gathered elsewhere (for example by another worker), as if every
    /// vector they saw had been passed to [`RunningMeanStd::update`] here.
    ///
    /// # Errors
    /// [`EnvError::DimensionMismatch`] if the dimensions differ.
    pub fn merge(&mut self, other: &RunningMeanStd) -> Result<(), EnvError> {
        if other.dim() != self.dim() {
            return Err(EnvError::DimensionMismatch {
                expected: self.dim(),
                found: other.dim(),
            });
        }
        if other.count > 0.0 {
            let total = self.count + other.count;
            for (((mean, var), other_mean), other_var) in self
                .mean
                .iter_mut()
                .zip(&mut self.var)
                .zip(&other.mean)
                .zip(&other.var)
            {
                merge_one(
                    mean,
                    var,
                    self.count,
                    *other_mean,
                    *other_var,
                    other.count,
                    total,
                );
            }
            self.count = total;
        }
        Ok(())
    }

    /// Standardizes `x` in place: `clip((x − mean) / sqrt(var + EPSILON), ±CLIP)`.
    /// `x` may hold one vector or several, row-major (`[m, dim]`).
    ///
    /// # Panics
    /// If `x.len()` is not a multiple of `dim`.
    pub fn normalize(&self, x: &mut [f32]) {
        let dim = self.dim();
        assert!(
            x.len().is_multiple_of(dim),
            "RunningMeanStd::normalize: length {} is not a multiple of dim = {dim}",
            x.len()
        );
        if dim == 0 {
            return;
        }
        for row in x.chunks_exact_mut(dim) {
            for ((x, m), v) in row.iter_mut().zip(&self.mean).zip(&self.var) {
                let z = (f64::from(*x) - m) / (v + Self::EPSILON).sqrt();
                *x = (z as f32).clamp(-Self::CLIP, Self::CLIP);
            }
        }
    }
}

/// Merges the moments `(mean_b, var_b)` of `count_b` samples into `(mean, var)` of
/// `count_a` samples (Chan et al.), with `total = count_a + count_b > 0`.
fn merge_one(
    mean: &mut f64,
    var: &mut f64,
    count_a: f64,
    mean_b: f64,
    var_b: f64,
    count_b: f64,
    total: f64,
) {
    let delta = mean_b - *mean;
    let m2 = *var * count_a + var_b * count_b + delta * delta * count_a * count_b / total;
    *mean += delta * count_b / total;
    *var = m2 / total;
}

/// Standardizes observations with running statistics of every observation it has seen
/// (those of resets included), then clips them to `±10`; its observation space is
/// `[-10, 10]^dim`.
///
/// In training mode (the default) each observation updates the statistics before it is
/// normalized; [`NormalizeObservation::set_training`]`(false)` freezes them for evaluation.
/// [`NormalizeObservation::stats`] and [`NormalizeObservation::set_stats`] save and restore them.
#[derive(Debug, Clone)]
pub struct NormalizeObservation<E> {
    env: E,
    stats: RunningMeanStd,
    training: bool,
    observation_space: Space,
}

impl<E: Env> NormalizeObservation<E> {
    /// Wraps `env`, with empty statistics, in training mode.
    ///
    /// # Errors
    /// [`EnvError::UnsupportedSpace`] if the observation space is not a box.
    pub fn new(env: E) -> Result<Self, EnvError> {
        let (dim, shape) = match env.observation_space() {
            Space::Box { low, shape, .. } => (low.len(), shape.clone()),
            space @ Space::Discrete { .. } => {
                return Err(EnvError::UnsupportedSpace {
                    wrapper: "NormalizeObservation",
                    what: "observation",
                    space: space.clone(),
                    reason: "it needs a box",
                })
            }
        };
        Ok(Self {
            env,
            stats: RunningMeanStd::new(dim),
            training: true,
            observation_space: Space::Box {
                low: vec![-RunningMeanStd::CLIP; dim],
                high: vec![RunningMeanStd::CLIP; dim],
                shape,
            },
        })
    }

    /// The running statistics.
    pub fn stats(&self) -> &RunningMeanStd {
        &self.stats
    }

    /// Replaces the running statistics (to restore a checkpoint).
    ///
    /// # Errors
    /// [`EnvError::DimensionMismatch`] if `stats` has another dimension than the observations.
    pub fn set_stats(&mut self, stats: RunningMeanStd) -> Result<(), EnvError> {
        if stats.dim() != self.stats.dim() {
            return Err(EnvError::DimensionMismatch {
                expected: self.stats.dim(),
                found: stats.dim(),
            });
        }
        self.stats = stats;
        Ok(())
    }

    /// Whether observations update the statistics.
    pub fn training(&self) -> bool {
        self.training
    }

    /// Turns updates of the statistics on (training) or off (evaluation).
    pub fn set_training(&mut self, training: bool) {
        self.training = training;
    }

    fn process(&mut self, obs: &mut [f32]) {
        if self.training {
            self.stats.update(obs, 1);
        }
        self.stats.normalize(obs);
    }
}

impl<E: Env> Env for NormalizeObservation<E> {
    fn observation_space(&self) -> &Space {
        &self.observation_space
    }

    fn action_space(&self) -> &Space {
        self.env.action_space()
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.env.reset(seed, obs);
        self.process(obs);
    }

    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let transition = self.env.step(action, obs);
        self.process(obs);
        transition
    }
    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        self.env.render(camera, frame)
    }
}
