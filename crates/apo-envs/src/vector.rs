//! A vector of environments stepped together, with automatic reset.
//!
//! A vector environment ([`VectorEnv`]) holds `n` environments with the same spaces and
//! exchanges flat row-major buffers with the caller: observations `[n, obs_dim]`, actions
//! `[n, act_dim]` (for a discrete action space `act_dim = 1` and the action is the index stored
//! as `f32`). Two implementations share these semantics bit for bit: [`SerialVecEnv`] steps the
//! environments in order on the caller's thread, [`ThreadedVecEnv`] on persistent worker
//! threads. [`VecEnv`], the type the rest of apo holds, is either one, picked by
//! [`VecEnv::with_threads`].
//!
//! # Semantics of [`VectorEnv::step`]
//!
//! For each environment `i`, `step` applies row `i` of `actions` and writes its outcome to
//! `out[i]` (reward, `terminated`, `truncated`, info). Then:
//!
//! - if the episode goes on, row `i` of `obs` holds the next observation;
//! - if the episode ended (`out[i].done()`), the environment is **reset at once** (its RNG
//!   stream continues, no reseeding) and row `i` of `obs` holds the **first observation of the
//!   next episode**. The last observation of the finished episode, needed to bootstrap the
//!   value of a truncated episode, is copied to row `i` of an internal final-observation
//!   buffer, read with [`VectorEnv::final_obs`]`(i)` (which returns `Some` exactly when
//!   `out[i].done()` in the latest step) or all at once with [`VectorEnv::final_obs_buffer`].
//!
//! So `(obs_before[i], actions[i], out[i].reward)` is always a genuine transition, and its
//! next state is `final_obs(i)` when done, else `obs[i]`. No step allocates: the final
//! observations live in a buffer made once, and rows of environments that did not finish are
//! left as they were (stale).
//!
//! # Threads
//!
//! [`ThreadedVecEnv`] cuts the `n` environments into `t` consecutive slices (sizes differing by
//! at most one) and moves each slice but the first into a worker thread started once, which
//! owns it for the vector's lifetime; the calling thread steps the first slice itself, so `t`
//! threads are `t − 1` workers and the caller. See [`ThreadedVecEnv`] for the hand-off. Every
//! environment owns its RNG and state and is stepped by the same code whatever thread runs it,
//! so the outcome is bit-identical whatever the number of threads.
//!
//! # Panics in environments
//!
//! A panic of an environment's `step` or `reset` reaches the caller of [`VectorEnv::step`] or
//! [`VectorEnv::reset`]: on the caller's own thread it unwinds as is, on a worker thread it is
//! caught there and raised again on the caller's thread, with the environment's index and the
//! original message. The vector stays usable (and droppable) afterwards, but the state of the
//! environments of that step is unspecified.

mod serial;
mod threaded;

pub use serial::SerialVecEnv;
pub use threaded::ThreadedVecEnv;

use crate::env::{Action, Env, StepInfo, Transition};
use crate::error::EnvError;
use crate::space::Space;

/// The outcome of one environment in a [`VectorEnv::step`].
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

/// `n` environments with the same spaces, stepped together and reset automatically when
/// their episode ends. See the [module documentation](self) for the exact semantics, which
/// every implementation follows bit for bit.
pub trait VectorEnv: Send {
    /// The number of environments `n`.
    fn num_envs(&self) -> usize;

    /// The observation space of one environment.
    fn observation_space(&self) -> &Space;

    /// The action space of one environment.
    fn action_space(&self) -> &Space;

    /// The length of one observation row.
    fn obs_dim(&self) -> usize;

    /// The length of one action row (1 for a discrete action space).
    fn act_dim(&self) -> usize;

    /// The number of threads that step the environments (the caller's included).
    fn threads(&self) -> usize;

    /// Resets every environment and writes the first observations into `obs` (`[n, obs_dim]`).
    /// With `Some(seed)`, environment `i` is reseeded with `seed + i` (wrapping); with `None`
    /// their RNG streams continue. Clears the final-observation flags.
    ///
    /// # Panics
    /// If `obs.len() != n * obs_dim`, or if an environment panics.
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]);

    /// Steps every environment with its row of `actions` (`[n, act_dim]`), writes the outcomes
    /// to `out` (`[n]`) and the observations to `obs` (`[n, obs_dim]`), resetting the
    /// environments whose episode ended; see the [module documentation](self).
    ///
    /// # Panics
    /// If a buffer has the wrong length, if a discrete action is not an index of the action
    /// space, or if an environment panics.
    fn step(&mut self, actions: &[f32], obs: &mut [f32], out: &mut [VecStep]);

    /// The last observation of environment `i`'s episode if that episode ended in the latest
    /// [`VectorEnv::step`], else `None`.
    fn final_obs(&self, i: usize) -> Option<&[f32]>;

    /// The whole final-observation buffer (`[n, obs_dim]`): row `i` is meaningful only when
    /// `out[i].done()` in the latest step (for one batched value evaluation).
    fn final_obs_buffer(&self) -> &[f32];
}

/// A vector of environments, stepped serially ([`SerialVecEnv`], the default) or on worker
/// threads ([`ThreadedVecEnv`], see [`VecEnv::with_threads`]); the results are the same bit
/// for bit. See the [module documentation](self) for the exact semantics.
///
/// Its inherent methods are those of [`VectorEnv`], which it implements too.
pub struct VecEnv {
    inner: Inner,
}

enum Inner {
    Serial(SerialVecEnv),
    Threaded(ThreadedVecEnv),
}

impl std::fmt::Debug for VecEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VecEnv")
            .field("num_envs", &self.num_envs())
            .field("observation_space", self.observation_space())
            .field("action_space", self.action_space())
            .field("threads", &self.threads())
            .finish_non_exhaustive()
    }
}

impl From<SerialVecEnv> for VecEnv {
    fn from(envs: SerialVecEnv) -> Self {
        Self {
            inner: Inner::Serial(envs),
        }
    }
}

impl From<ThreadedVecEnv> for VecEnv {
    fn from(envs: ThreadedVecEnv) -> Self {
        Self {
            inner: Inner::Threaded(envs),
        }
    }
}

/// Evaluates `$body` with `$envs` bound to whichever implementation `$self` holds.
macro_rules! dispatch {
    ($self:expr, $envs:ident => $body:expr) => {
        match $self {
            Inner::Serial($envs) => $body,
            Inner::Threaded($envs) => $body,
        }
    };
}

impl VecEnv {
    /// A vector of the given environments, stepped on the caller's thread.
    ///
    /// # Errors
    /// [`EnvError::EmptyVector`] if `envs` is empty, [`EnvError::MismatchedSpaces`] if an
    /// environment's spaces differ from the first one's, [`EnvError::UnsupportedSpace`] if a
    /// space has dimension 0.
    pub fn new(envs: Vec<Box<dyn Env>>) -> Result<Self, EnvError> {
        SerialVecEnv::new(envs).map(Self::from)
    }

    /// Steps on `threads` threads (at most one per environment; 0 = the cores available;
    /// 1 = serially on the caller's thread): `threads − 1` worker threads are started now and
    /// joined when the vector is dropped. The environments keep their state; the
    /// final-observation buffer and flags too. Results do not depend on it.
    ///
    /// # Errors
    /// [`EnvError::Threads`] if the operating system refuses to start the threads (the
    /// environments are then lost).
    pub fn with_threads(self, threads: usize) -> Result<Self, EnvError> {
        let threads = match threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            t => t,
        }
        .min(self.num_envs());
        if threads == self.threads() {
            return Ok(self);
        }
        let parts = match self.inner {
            Inner::Serial(envs) => envs.into_parts(),
            Inner::Threaded(envs) => envs.into_parts(),
        };
        Ok(if threads <= 1 {
            SerialVecEnv::from_parts(parts).into()
        } else {
            ThreadedVecEnv::from_parts(parts, threads)?.into()
        })
    }

    /// The number of threads that step the environments (the caller's included).
    pub fn threads(&self) -> usize {
        dispatch!(&self.inner, e => e.threads())
    }

    /// The number of environments `n`.
    pub fn num_envs(&self) -> usize {
        dispatch!(&self.inner, e => e.num_envs())
    }

    /// The observation space of one environment.
    pub fn observation_space(&self) -> &Space {
        dispatch!(&self.inner, e => e.observation_space())
    }

    /// The action space of one environment.
    pub fn action_space(&self) -> &Space {
        dispatch!(&self.inner, e => e.action_space())
    }

    /// The length of one observation row.
    pub fn obs_dim(&self) -> usize {
        dispatch!(&self.inner, e => e.obs_dim())
    }

    /// The length of one action row (1 for a discrete action space).
    pub fn act_dim(&self) -> usize {
        dispatch!(&self.inner, e => e.act_dim())
    }

    /// See [`VectorEnv::reset`].
    ///
    /// # Panics
    /// If `obs.len() != n * obs_dim`, or if an environment panics.
    pub fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        dispatch!(&mut self.inner, e => e.reset(seed, obs))
    }

    /// See [`VectorEnv::step`] and the [module documentation](self).
    ///
    /// # Panics
    /// If a buffer has the wrong length, if a discrete action is not an index of the action
    /// space, or if an environment panics.
    pub fn step(&mut self, actions: &[f32], obs: &mut [f32], out: &mut [VecStep]) {
        dispatch!(&mut self.inner, e => e.step(actions, obs, out))
    }

    /// The last observation of environment `i`'s episode if that episode ended in the latest
    /// [`VecEnv::step`], else `None`.
    pub fn final_obs(&self, i: usize) -> Option<&[f32]> {
        dispatch!(&self.inner, e => e.final_obs(i))
    }

    /// The whole final-observation buffer (`[n, obs_dim]`): row `i` is meaningful only when
    /// `out[i].done()` in the latest step (for one batched value evaluation).
    pub fn final_obs_buffer(&self) -> &[f32] {
        dispatch!(&self.inner, e => e.final_obs_buffer())
    }
}

impl VectorEnv for VecEnv {
    fn num_envs(&self) -> usize {
        VecEnv::num_envs(self)
    }
    fn observation_space(&self) -> &Space {
        VecEnv::observation_space(self)
    }
    fn action_space(&self) -> &Space {
        VecEnv::action_space(self)
    }
    fn obs_dim(&self) -> usize {
        VecEnv::obs_dim(self)
    }
    fn act_dim(&self) -> usize {
        VecEnv::act_dim(self)
    }
    fn threads(&self) -> usize {
        VecEnv::threads(self)
    }
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        VecEnv::reset(self, seed, obs)
    }
    fn step(&mut self, actions: &[f32], obs: &mut [f32], out: &mut [VecStep]) {
        VecEnv::step(self, actions, obs, out)
    }
    fn final_obs(&self, i: usize) -> Option<&[f32]> {
        VecEnv::final_obs(self, i)
    }
    fn final_obs_buffer(&self) -> &[f32] {
        VecEnv::final_obs_buffer(self)
    }
}

/// The spaces and buffer sizes of a vector, checked once.
#[derive(Debug, Clone)]
struct Layout {
    num_envs: usize,
    observation_space: Space,
    action_space: Space,
    obs_dim: usize,
    act_dim: usize,
}

impl Layout {
    /// The layout of a vector of `envs`; see [`VecEnv::new`] for the errors.
    fn of(envs: &[Box<dyn Env>]) -> Result<Self, EnvError> {
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
        Ok(Self {
            num_envs: envs.len(),
            observation_space,
            action_space,
            obs_dim,
            act_dim,
        })
    }

    /// # Panics
    /// Unless `len == num_envs × row`.
    fn check_len(&self, what: &str, len: usize, row: usize) {
        let expected = self.num_envs * row;
        assert_eq!(
            len, expected,
            "VecEnv: `{what}` has length {len}, expected {} × {row}",
            self.num_envs
        );
    }
}

/// Everything a vector is made of, handed from one implementation to the other.
struct Parts {
    layout: Layout,
    envs: Vec<Box<dyn Env>>,
    /// `[n, obs_dim]`, see [`VectorEnv::final_obs_buffer`].
    final_obs: Vec<f32>,
    /// `[n]`: environment `i` finished in the latest step.
    finished: Vec<bool>,
}

impl Parts {
    fn new(envs: Vec<Box<dyn Env>>) -> Result<Self, EnvError> {
        let layout = Layout::of(&envs)?;
        Ok(Self {
            final_obs: vec![0.0; layout.num_envs * layout.obs_dim],
            finished: vec![false; layout.num_envs],
            layout,
            envs,
        })
    }
}

/// [`VectorEnv::final_obs`]`(i)` over a final-observation buffer and its flags.
fn final_row<'a>(
    final_obs: &'a [f32],
    finished: &[bool],
    dim: usize,
    i: usize,
) -> Option<&'a [f32]> {
    if *finished.get(i)? {
        final_obs.get(i * dim..(i + 1) * dim)
    } else {
        None
    }
}

/// Consecutive environments of a vector, with the code that steps them: the only code that
/// touches environments, whatever thread runs it (which is why thread counts cannot change a
/// bit). All buffers are the rows of these environments only.
struct Shard {
    envs: Vec<Box<dyn Env>>,
    /// The index in the vector of `envs[0]`.
    first: usize,
}

impl Shard {
    /// Resets the environments (environment `i` of the vector with `seed + i`), writing `obs`;
    /// `current` is set to the vector index of each environment before it is touched, so
    /// that a panic can name it.
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32], current: &mut usize) {
        if self.envs.is_empty() {
            return;
        }
        let obs_dim = obs.len() / self.envs.len();
        for (k, (env, row)) in self
            .envs
            .iter_mut()
            .zip(obs.chunks_exact_mut(obs_dim))
            .enumerate()
        {
            let i = self.first + k;
            *current = i;
            env.reset(seed.map(|s| s.wrapping_add(i as u64)), row);
        }
    }

    /// Steps the environments with `rows.actions`, resetting those whose episode ended (see
    /// the [module documentation](self)); `current` as in [`Shard::reset`].
    fn step(&mut self, space: &Space, rows: Rows<'_>, current: &mut usize) {
        let n = self.envs.len();
        if n == 0 {
            return;
        }
        let (obs_dim, act_dim) = (rows.obs.len() / n, rows.actions.len() / n);
        for (k, ((((env, action), obs_row), final_row), (step, finished))) in self
            .envs
            .iter_mut()
            .zip(rows.actions.chunks_exact(act_dim))
            .zip(rows.obs.chunks_exact_mut(obs_dim))
            .zip(rows.final_obs.chunks_exact_mut(obs_dim))
            .zip(rows.out.iter_mut().zip(rows.finished.iter_mut()))
            .enumerate()
        {
            *current = self.first + k;
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
        }
    }
}

/// The rows of a [`Shard`]'s environments in the buffers of one step.
struct Rows<'a> {
    actions: &'a [f32],
    obs: &'a mut [f32],
    final_obs: &'a mut [f32],
    finished: &'a mut [bool],
    out: &'a mut [VecStep],
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
