//! A vector of environments stepped together, with automatic reset.
//!
//! [`VecEnv`] holds `n` environments with the same spaces and exchanges flat row-major
//! buffers with the caller: observations `[n, obs_dim]`, actions `[n, act_dim]` (for a
//! discrete action space `act_dim = 1` and the action is the index stored as `f32`).
//!
//! # Semantics of [`VecEnv::step`]
//!
//! For each environment `i`, `step` applies row `i` of `actions` and writes its outcome to
//! `out[i]` (reward, `terminated`, `truncated`, info). Then:
//!
//! - if the episode goes on, row `i` of `obs` holds the next observation;
//! - if the episode ended (`out[i].done()`), the environment is **reset at once** (its RNG
//!   stream continues, no reseeding) and row `i` of `obs` holds the **first observation of the
//!   next episode**. The last observation of the finished episode, needed to bootstrap the
//!   value of a truncated episode, is copied to row `i` of an internal final-observation
//!   buffer, read with [`VecEnv::final_obs`]`(i)` (which returns `Some` exactly when
//!   `out[i].done()` in the latest step) or all at once with [`VecEnv::final_obs_buffer`].
//!
//! So `(obs_before[i], actions[i], out[i].reward)` is always a genuine transition, and its
//! next state is `final_obs(i)` when done, else `obs[i]`. No step allocates: the final
//! observations live in a buffer made once, and rows of environments that did not finish are
//! left as they were (stale).
//!
//! # Threads
//!
//! [`VecEnv::with_threads`] steps the environments on a pool of worker threads: the `n`
//! environments are cut into at most `threads` consecutive slices of `⌈n / threads⌉`, each
//! stepped in place by one worker (rows of the caller's buffers are written directly, no copy,
//! no allocation, no lock per environment step). Every environment owns its RNG and state, so
//! the outcome is bit-identical whatever the number of threads.

use crate::env::{Action, Env, StepInfo, Transition};
use crate::error::EnvError;
use crate::space::Space;

/// What [`VecEnv::step`] hands to one environment's step: the environment, its action row,
/// its observation row, its final-observation row, and its outcome and finished flag.
type Row<'a> = (
    (
        ((&'a mut Box<dyn Env>, &'a [f32]), &'a mut [f32]),
        &'a mut [f32],
    ),
    (&'a mut VecStep, &'a mut bool),
);

/// The outcome of one environment in a [`VecEnv::step`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct VecStep {
    /// The reward of the step.
    pub reward: f64,
    /// The episode reached a terminal state (value 0) and was reset.
    pub terminated: bool,
    /// The episode was cut (time limit) and was reset; bootstrap from the final observation.
    pub truncated: bool,
    /// Extra facts about the step.
    pub info: StepInfo,
}

impl VecStep {
    /// `terminated || truncated`: the episode ended in this step and the environment was reset.
    pub fn done(&self) -> bool {
        self.terminated || self.truncated
    }
}

impl From<Transition> for VecStep {
    fn from(t: Transition) -> Self {
        Self {
            reward: t.reward,
            terminated: t.terminated,
            truncated: t.truncated,
            info: t.info,
        }
    }
}

/// `n` environments with the same spaces, stepped in order, reset automatically when their
/// episode ends. See the [module documentation](self) for the exact semantics.
pub struct VecEnv {
    envs: Vec<Box<dyn Env>>,
    observation_space: Space,
    action_space: Space,
    obs_dim: usize,
    act_dim: usize,
    final_obs: Vec<f32>,
    finished: Vec<bool>,
    /// The worker threads, when stepping in parallel.
    pool: Option<rayon::ThreadPool>,
}

impl std::fmt::Debug for VecEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VecEnv")
            .field("num_envs", &self.envs.len())
            .field("observation_space", &self.observation_space)
            .field("action_space", &self.action_space)
            .field("threads", &self.threads())
            .finish_non_exhaustive()
    }
}

impl VecEnv {
    /// A vector of the given environments.
    ///
    /// # Errors
    /// [`EnvError::EmptyVector`] if `envs` is empty, [`EnvError::MismatchedSpaces`] if an
    /// environment's spaces differ from the first one's, [`EnvError::UnsupportedSpace`] if a
    /// space has dimension 0.
    pub fn new(envs: Vec<Box<dyn Env>>) -> Result<Self, EnvError> {
        let first = envs.first().ok_or(EnvError::EmptyVector)?;
        let observation_space = first.observation_space().clone();
        let action_space = first.action_space().clone();
        for (index, env) in envs.iter().enumerate().skip(1) {
            if env.observation_space() != &observation_space || env.action_space() != &action_space
            {
                return Err(EnvError::MismatchedSpaces {
                    index,
                    expected: Box::new((observation_space, action_space)),
                    found: Box::new((env.observation_space().clone(), env.action_space().clone())),
                });
            }
        }
        let obs_dim = observation_space.flat_dim();
        let act_dim = action_space.flat_dim();
        for (what, space, dim) in [
            ("observation", &observation_space, obs_dim),
            ("action", &action_space, act_dim),
        ] {
            if dim == 0 {
                return Err(EnvError::UnsupportedSpace {
                    wrapper: "VecEnv",
                    what,
                    space: space.clone(),
                    reason: "it needs a space of dimension > 0",
                });
            }
        }
        let n = envs.len();
        Ok(Self {
            envs,
            observation_space,
            action_space,
            obs_dim,
            act_dim,
            final_obs: vec![0.0; n * obs_dim],
            finished: vec![false; n],
            pool: None,
        })
    }

    /// Steps on `threads` worker threads (at most one per environment; 0 = the cores
    /// available; 1 = on the caller's thread). Results do not depend on it.
    ///
    /// # Errors
    /// [`EnvError::Threads`] if the operating system refuses to start the threads.
    pub fn with_threads(mut self, threads: usize) -> Result<Self, EnvError> {
        let threads = match threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            t => t,
        }
        .min(self.envs.len());
        self.pool = if threads > 1 {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .thread_name(|i| format!("apo-env-{i}"))
                .build()
                .map_err(|e| EnvError::Threads(e.to_string()))?;
            Some(pool)
        } else {
            None
        };
        Ok(self)
    }

    /// The number of threads that step the environments.
    pub fn threads(&self) -> usize {
        self.pool.as_ref().map_or(1, |p| p.current_num_threads())
    }

    /// The number of environments `n`.
    pub fn num_envs(&self) -> usize {
        self.envs.len()
    }

    /// The observation space of one environment.
    pub fn observation_space(&self) -> &Space {
        &self.observation_space
    }

    /// The action space of one environment.
    pub fn action_space(&self) -> &Space {
        &self.action_space
    }

    /// The length of one observation row.
    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    /// The length of one action row (1 for a discrete action space).
    pub fn act_dim(&self) -> usize {
        self.act_dim
    }

    /// Resets every environment and writes the first observations into `obs` (`[n, obs_dim]`).
    /// With `Some(seed)`, environment `i` is reseeded with `seed + i` (wrapping); with `None`
    /// their RNG streams continue. Clears the final-observation flags.
    ///
    /// # Panics
    /// If `obs.len() != n * obs_dim`.
    pub fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.check_len("obs", obs.len(), self.obs_dim);
        for (i, (env, row)) in self
            .envs
            .iter_mut()
            .zip(obs.chunks_exact_mut(self.obs_dim))
            .enumerate()
        {
            env.reset(seed.map(|s| s.wrapping_add(i as u64)), row);
        }
        self.finished.fill(false);
    }

    /// Steps every environment with its row of `actions` (`[n, act_dim]`), writes the outcomes
    /// to `out` (`[n]`) and the observations to `obs` (`[n, obs_dim]`), resetting the
    /// environments whose episode ended; see the [module documentation](self).
    ///
    /// # Panics
    /// If a buffer has the wrong length, or if a discrete action is not an index of the action
    /// space.
    pub fn step(&mut self, actions: &[f32], obs: &mut [f32], out: &mut [VecStep]) {
        self.check_len("actions", actions.len(), self.act_dim);
        self.check_len("obs", obs.len(), self.obs_dim);
        self.check_len("out", out.len(), 1);
        let (obs_dim, act_dim, space) = (self.obs_dim, self.act_dim, &self.action_space);
        let step_one = |((((env, action), obs_row), final_row), (step, finished)): Row<'_>| {
            let action = match space {
                Space::Box { .. } => Action::Continuous(action),
                Space::Discrete { n } => Action::Discrete(discrete_index(action[0], *n)),
            };
            let transition = env.step(action, obs_row);
            *step = transition.into();
            *finished = transition.done();
            if transition.done() {
                final_row.copy_from_slice(obs_row);
                env.reset(None, obs_row);
            }
        };
        match &self.pool {
            None => self
                .envs
                .iter_mut()
                .zip(actions.chunks_exact(act_dim))
                .zip(obs.chunks_exact_mut(obs_dim))
                .zip(self.final_obs.chunks_exact_mut(obs_dim))
                .zip(out.iter_mut().zip(&mut self.finished))
                .for_each(step_one),
            Some(pool) => {
                use rayon::prelude::*;
                // one consecutive slice of environments per worker
                let slice = self.envs.len().div_ceil(pool.current_num_threads());
                let (envs, final_obs, finished) =
                    (&mut self.envs, &mut self.final_obs, &mut self.finished);
                pool.install(|| {
                    envs.par_iter_mut()
                        .zip(actions.par_chunks_exact(act_dim))
                        .zip(obs.par_chunks_exact_mut(obs_dim))
                        .zip(final_obs.par_chunks_exact_mut(obs_dim))
                        .zip(out.par_iter_mut().zip(finished.par_iter_mut()))
                        .with_min_len(slice)
                        .for_each(step_one)
                });
            }
        }
    }

    /// The last observation of environment `i`'s episode if that episode ended in the latest
    /// [`VecEnv::step`], else `None`.
    pub fn final_obs(&self, i: usize) -> Option<&[f32]> {
        if *self.finished.get(i)? {
            self.final_obs.get(i * self.obs_dim..(i + 1) * self.obs_dim)
        } else {
            None
        }
    }

    /// The whole final-observation buffer (`[n, obs_dim]`): row `i` is meaningful only when
    /// `out[i].done()` in the latest step (for one batched value evaluation).
    pub fn final_obs_buffer(&self) -> &[f32] {
        &self.final_obs
    }

    fn check_len(&self, what: &str, len: usize, row: usize) {
        let expected = self.envs.len() * row;
        assert_eq!(
            len,
            expected,
            "VecEnv: `{what}` has length {len}, expected {} × {row}",
            self.envs.len()
        );
    }
}

/// The discrete action index stored as `value`.
///
/// # Panics
/// If `value` is not an integer in `0..n`.
fn discrete_index(value: f32, n: usize) -> usize {
    assert!(
        value >= 0.0 && value.fract() == 0.0 && (value as usize) < n,
        "VecEnv: discrete action {value} is not an index in 0..{n}"
    );
    value as usize
}
