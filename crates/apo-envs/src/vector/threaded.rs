//! The threaded vector: persistent worker threads, each owning a fixed slice of the
//! environments.
//!
//! # Hand-off
//!
//! Each worker owns its slice of environments (moved into the thread) and a preallocated
//! mailbox ([`Mailbox`]: the command, the action rows of its slice, and the rows it writes
//! back) behind a mutex. The mutex is taken three times per vector step and never contended:
//! by the caller to copy the actions in, by the worker once for its whole slice, by the caller
//! to copy the results out (the hand-off below orders the three). So there is no lock per
//! environment step, and nothing is allocated after construction. All of it is safe code.
//!
//! The caller publishes a command by bumping a generation counter; it then steps its own slice
//! and waits until the count of workers done reaches the number of workers. Both waits
//! (workers for a new generation, the caller for the count) busy-spin for [`SPIN`], then spin
//! and yield the core until [`SPIN_AND_YIELD`] (slices of a vector step usually finish within
//! microseconds of each other), then block on a condition variable ([`Signal`]), so idle
//! workers cost nothing while the caller does something else (runs the policy, trains).
//!
//! A panic of an environment on a worker is caught there, recorded in the mailbox, and counted
//! as done like a normal step; the caller raises it once every slice is done. A panic of the
//! caller's own slice is held until the workers are done too, so the workers are always idle
//! when `step` or `reset` returns or unwinds. Dropping the vector sends the workers a stop
//! command and joins them.

use std::any::Any;
use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering::SeqCst};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{final_row, Layout, Parts, Rows, Shard, VecStep, VectorEnv};
use crate::env::Env;
use crate::error::EnvError;
use crate::space::Space;

/// How long a wait busy-spins before it starts yielding its core between checks: a step of a
/// vector's slice usually ends within microseconds of the others'.
const SPIN: Duration = Duration::from_micros(2);

/// How long a wait spins and yields before it blocks. Yielding keeps the thread ready to go
/// on at once on free cores, and lets the threads that have work run when there are more
/// threads than cores (more threads than asked for cores, or a busy machine).
const SPIN_AND_YIELD: Duration = Duration::from_micros(100);

/// A [`VectorEnv`] that steps its environments on persistent worker threads; see the
/// [module documentation](super#threads). Dropping it stops and joins its threads.
pub struct ThreadedVecEnv {
    layout: Layout,
    /// The first slice of environments, stepped by the caller.
    own: Shard,
    final_obs: Vec<f32>,
    finished: Vec<bool>,
    workers: Vec<Worker>,
    shared: Arc<Shared>,
}

/// The caller's handle on one worker thread.
struct Worker {
    /// The slice `first..first + len` of the vector's environments.
    first: usize,
    len: usize,
    mailbox: Arc<Mutex<Mailbox>>,
    thread: Option<JoinHandle<Vec<Box<dyn Env>>>>,
}

/// What a worker is asked to do.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Command {
    Step,
    Reset(Option<u64>),
    Stop,
}

/// One worker's preallocated buffers: the rows of its slice.
struct Mailbox {
    command: Command,
    actions: Vec<f32>,
    obs: Vec<f32>,
    final_obs: Vec<f32>,
    finished: Vec<bool>,
    out: Vec<VecStep>,
    /// The vector index of an environment that panicked, and the panic's message.
    panic: Option<(usize, String)>,
}

/// State shared by the caller and all workers. Each field on its own cache line.
struct Shared {
    /// Bumped by the caller to publish a command.
    generation: Padded<AtomicU64>,
    /// Workers that carried out the latest command.
    done: Padded<AtomicUsize>,
    /// Workers wait here for a new generation.
    start: Padded<Signal>,
    /// The caller waits here for `done`.
    finish: Padded<Signal>,
}

#[repr(align(128))]
struct Padded<T>(T);

impl<T> std::ops::Deref for Padded<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.0
    }
}

impl std::fmt::Debug for ThreadedVecEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ThreadedVecEnv")
            .field("num_envs", &self.layout.num_envs)
            .field("observation_space", &self.layout.observation_space)
            .field("action_space", &self.layout.action_space)
            .field("threads", &self.threads())
            .finish_non_exhaustive()
    }
}

impl ThreadedVecEnv {
    /// A vector of the given environments stepped on `threads` threads: at most one per
    /// environment, at least one (the caller's); `threads − 1` workers are started now.
    ///
    /// # Errors
    /// Those of [`VecEnv::new`](super::VecEnv::new), and [`EnvError::Threads`] if the operating
    /// system refuses to start the threads.
    pub fn new(envs: Vec<Box<dyn Env>>, threads: usize) -> Result<Self, EnvError> {
        Self::from_parts(Parts::new(envs)?, threads)
    }

    /// Stops and joins the workers and returns the environments, in order.
    pub fn into_envs(self) -> Vec<Box<dyn Env>> {
        self.into_parts().envs
    }

    pub(super) fn from_parts(parts: Parts, threads: usize) -> Result<Self, EnvError> {
        let Parts {
            layout,
            mut envs,
            final_obs,
            finished,
        } = parts;
        let n = layout.num_envs;
        let threads = threads.clamp(1, n);
        // Slice sizes differ by at most one; the caller, who also hands off and gathers,
        // gets one of the smallest (the first).
        let (base, extra) = (n / threads, n % threads);
        let len = |k: usize| base + usize::from(k >= threads - extra);
        let shared = Arc::new(Shared {
            generation: Padded(AtomicU64::new(0)),
            done: Padded(AtomicUsize::new(0)),
            start: Padded(Signal::default()),
            finish: Padded(Signal::default()),
        });
        let mut this = Self {
            own: Shard {
                envs: Vec::new(),
                first: 0,
            },
            final_obs,
            finished,
            workers: Vec::with_capacity(threads - 1),
            shared,
            layout,
        };
        // Split from the back so that every slice is a `split_off` of the remaining front.
        let mut slices: Vec<Shard> = (1..threads)
            .rev()
            .map(|k| {
                let first = (0..k).map(len).sum::<usize>();
                Shard {
                    envs: envs.split_off(first),
                    first,
                }
            })
            .collect();
        slices.reverse();
        this.own = Shard { envs, first: 0 };
        for (k, shard) in slices.into_iter().enumerate() {
            // `this` is dropped on error, which stops and joins the workers started so far.
            this.spawn(k + 1, shard)?;
        }
        Ok(this)
    }

    /// Starts worker `k` with its slice of environments.
    fn spawn(&mut self, k: usize, shard: Shard) -> Result<(), EnvError> {
        let (obs_dim, act_dim, len) = (self.layout.obs_dim, self.layout.act_dim, shard.envs.len());
        let mailbox = Arc::new(Mutex::new(Mailbox {
            command: Command::Step,
            actions: vec![0.0; len * act_dim],
            obs: vec![0.0; len * obs_dim],
            final_obs: vec![0.0; len * obs_dim],
            finished: vec![false; len],
            out: vec![VecStep::default(); len],
            panic: None,
        }));
        let first = shard.first;
        // Read before the thread starts, so that no command published later is missed.
        let seen = self.shared.generation.load(SeqCst);
        let (space, shared, inbox) = (
            self.layout.action_space.clone(),
            Arc::clone(&self.shared),
            Arc::clone(&mailbox),
        );
        let thread = std::thread::Builder::new()
            .name(format!("apo-env-{k}"))
            .spawn(move || work(shard, &space, &shared, &inbox, seen))
            .map_err(|e| EnvError::Threads(e.to_string()))?;
        self.workers.push(Worker {
            first,
            len,
            mailbox,
            thread: Some(thread),
        });
        Ok(())
    }

    pub(super) fn into_parts(mut self) -> Parts {
        let mut envs = std::mem::take(&mut self.own.envs);
        for (k, slice) in self.stop().into_iter().enumerate() {
            envs.extend(
                slice.unwrap_or_else(|| panic!("VecEnv: worker thread apo-env-{} died", k + 1)),
            );
        }
        Parts {
            layout: self.layout.clone(),
            envs,
            final_obs: std::mem::take(&mut self.final_obs),
            finished: std::mem::take(&mut self.finished),
        }
    }

    /// Tells the workers to stop, joins them, and returns their environments (`None` for a
    /// thread that died). Leaves no worker.
    fn stop(&mut self) -> Vec<Option<Vec<Box<dyn Env>>>> {
        for worker in &self.workers {
            lock(&worker.mailbox).command = Command::Stop;
        }
        self.launch();
        self.workers
            .drain(..)
            .map(|mut w| w.thread.take().and_then(|t| t.join().ok()))
            .collect()
    }

    /// Publishes the command in the mailboxes to the workers.
    fn launch(&self) {
        if self.workers.is_empty() {
            return;
        }
        self.shared.done.store(0, SeqCst);
        self.shared.generation.fetch_add(1, SeqCst);
        self.shared.start.notify();
    }

    /// Waits until every worker has carried out the latest command.
    fn wait(&self) {
        let (done, count) = (&self.shared.done, self.workers.len());
        self.shared.finish.wait_until(|| done.load(SeqCst) == count);
    }

    /// Raises a panic of the caller's own slice, or else the first panic of a worker (`k`,
    /// environment `i`, message), on the caller's thread.
    fn raise(own: std::thread::Result<()>, worker: Option<(usize, (usize, String))>) {
        if let Err(payload) = own {
            panic::resume_unwind(payload);
        }
        if let Some((k, (i, message))) = worker {
            panic!("VecEnv: environment {i} panicked on worker thread apo-env-{k}: {message}");
        }
    }
}

impl Drop for ThreadedVecEnv {
    fn drop(&mut self) {
        self.stop();
    }
}

impl VectorEnv for ThreadedVecEnv {
    fn num_envs(&self) -> usize {
        self.layout.num_envs
    }

    fn observation_space(&self) -> &Space {
        &self.layout.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.layout.action_space
    }

    fn obs_dim(&self) -> usize {
        self.layout.obs_dim
    }

    fn act_dim(&self) -> usize {
        self.layout.act_dim
    }

    fn threads(&self) -> usize {
        self.workers.len() + 1
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        let obs_dim = self.layout.obs_dim;
        self.layout.check_len("obs", obs.len(), obs_dim);
        for worker in &self.workers {
            lock(&worker.mailbox).command = Command::Reset(seed);
        }
        let m = self.own.envs.len();
        let (own_obs, their_obs) = obs.split_at_mut(m * obs_dim);
        self.launch();
        let own = panic::catch_unwind(AssertUnwindSafe(|| {
            self.own.reset(seed, own_obs, &mut 0);
        }));
        self.wait();
        let mut failed = None;
        for (k, worker) in self.workers.iter().enumerate() {
            let mut mailbox = lock(&worker.mailbox);
            if let Some(panic) = mailbox.panic.take() {
                failed = failed.or(Some((k + 1, panic)));
            }
            let start = (worker.first - m) * obs_dim;
            their_obs[start..start + worker.len * obs_dim].copy_from_slice(&mailbox.obs);
        }
        self.finished.fill(false);
        Self::raise(own, failed);
    }

    fn step(&mut self, actions: &[f32], obs: &mut [f32], out: &mut [VecStep]) {
        let (obs_dim, act_dim) = (self.layout.obs_dim, self.layout.act_dim);
        self.layout.check_len("actions", actions.len(), act_dim);
        self.layout.check_len("obs", obs.len(), obs_dim);
        self.layout.check_len("out", out.len(), 1);
        for worker in &self.workers {
            let mut mailbox = lock(&worker.mailbox);
            mailbox.command = Command::Step;
            let rows = worker.first * act_dim..(worker.first + worker.len) * act_dim;
            mailbox.actions.copy_from_slice(&actions[rows]);
        }
        let m = self.own.envs.len();
        let (own_obs, their_obs) = obs.split_at_mut(m * obs_dim);
        let (own_out, their_out) = out.split_at_mut(m);
        self.launch();
        let own = panic::catch_unwind(AssertUnwindSafe(|| {
            let rows = Rows {
                actions: &actions[..m * act_dim],
                obs: own_obs,
                final_obs: &mut self.final_obs[..m * obs_dim],
                finished: &mut self.finished[..m],
                out: own_out,
            };
            self.own.step(&self.layout.action_space, rows, &mut 0);
        }));
        self.wait();
        let mut failed = None;
        for (k, worker) in self.workers.iter().enumerate() {
            let mut mailbox = lock(&worker.mailbox);
            if let Some(panic) = mailbox.panic.take() {
                failed = failed.or(Some((k + 1, panic)));
            }
            let (first, len) = (worker.first, worker.len);
            let rows = first - m..first - m + len;
            their_obs[rows.start * obs_dim..rows.end * obs_dim].copy_from_slice(&mailbox.obs);
            their_out[rows].copy_from_slice(&mailbox.out);
            self.finished[first..first + len].copy_from_slice(&mailbox.finished);
            for (j, _) in mailbox.finished.iter().enumerate().filter(|(_, f)| **f) {
                let i = first + j;
                self.final_obs[i * obs_dim..(i + 1) * obs_dim]
                    .copy_from_slice(&mailbox.final_obs[j * obs_dim..(j + 1) * obs_dim]);
            }
        }
        Self::raise(own, failed);
    }

    fn final_obs(&self, i: usize) -> Option<&[f32]> {
        final_row(&self.final_obs, &self.finished, self.layout.obs_dim, i)
    }

    fn final_obs_buffer(&self) -> &[f32] {
        &self.final_obs
    }
}

/// The body of a worker thread: waits for commands and carries them out on its slice until
/// told to stop, then hands the environments back. A panic of an environment is caught and
/// reported in the mailbox, so the thread never dies of one.
fn work(
    mut shard: Shard,
    space: &Space,
    shared: &Shared,
    mailbox: &Mutex<Mailbox>,
    mut seen: u64,
) -> Vec<Box<dyn Env>> {
    loop {
        shared
            .start
            .wait_until(|| shared.generation.load(SeqCst) != seen);
        seen = shared.generation.load(SeqCst);
        let stop = {
            let mut guard = lock(mailbox);
            let mailbox = &mut *guard;
            let mut current = shard.first;
            let result = match mailbox.command {
                Command::Stop => Ok(()),
                Command::Reset(seed) => panic::catch_unwind(AssertUnwindSafe(|| {
                    shard.reset(seed, &mut mailbox.obs, &mut current)
                })),
                Command::Step => {
                    let rows = Rows {
                        actions: &mailbox.actions,
                        obs: &mut mailbox.obs,
                        final_obs: &mut mailbox.final_obs,
                        finished: &mut mailbox.finished,
                        out: &mut mailbox.out,
                    };
                    panic::catch_unwind(AssertUnwindSafe(|| shard.step(space, rows, &mut current)))
                }
            };
            if let Err(payload) = result {
                mailbox.panic = Some((current, message(&*payload)));
            }
            mailbox.command == Command::Stop
        };
        shared.done.fetch_add(1, SeqCst);
        shared.finish.notify();
        if stop {
            return shard.envs;
        }
    }
}

/// The message of a panic payload.
fn message(payload: &(dyn Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(a panic without a message)".to_string())
}

/// Locks a mailbox. Environments never panic while it is held (their panics are caught
/// inside), so poisoning cannot happen, and would not matter: the buffers stay well-formed.
fn lock(mailbox: &Mutex<Mailbox>) -> MutexGuard<'_, Mailbox> {
    mailbox.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A wait for a condition that another thread makes true: spin for [`SPIN`], spin and yield
/// until [`SPIN_AND_YIELD`], then block on a condition variable. The waker makes the condition
/// true with a `SeqCst` write and then calls [`Signal::notify`], which takes the lock only when
/// someone may be blocked.
#[derive(Default)]
struct Signal {
    sleepers: AtomicUsize,
    lock: Mutex<()>,
    wake: Condvar,
}

impl Signal {
    /// Returns once `ready()` (which must read with `SeqCst`) is true.
    fn wait_until(&self, ready: impl Fn() -> bool) {
        if ready() {
            return;
        }
        let start = Instant::now();
        loop {
            for _ in 0..32 {
                std::hint::spin_loop();
                if ready() {
                    return;
                }
            }
            let elapsed = start.elapsed();
            if elapsed >= SPIN_AND_YIELD {
                break;
            }
            if elapsed >= SPIN {
                std::thread::yield_now();
            }
        }
        let mut guard = self.lock.lock().unwrap_or_else(PoisonError::into_inner);
        // With `SeqCst` on both sides, either the waker's `sleepers` load sees this increment
        // (and it then takes the lock, which it can only get once this thread is waiting, and
        // wakes it) or this thread's next `ready()` sees the waker's write.
        self.sleepers.fetch_add(1, SeqCst);
        while !ready() {
            guard = self
                .wake
                .wait(guard)
                .unwrap_or_else(PoisonError::into_inner);
        }
        self.sleepers.fetch_sub(1, SeqCst);
    }

    /// Wakes the blocked waiters, after the condition was made true.
    fn notify(&self) {
        if self.sleepers.load(SeqCst) != 0 {
            drop(self.lock.lock().unwrap_or_else(PoisonError::into_inner));
            self.wake.notify_all();
        }
    }
}
