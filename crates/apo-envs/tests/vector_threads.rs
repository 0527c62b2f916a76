//! The worker threads of a threaded vector: joined on drop, and an environment's panic reaches
//! the caller instead of hanging it.

use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::Duration;

use apo_envs::{Action, Env, Space, StepInfo, Transition, VecEnv, VecStep};

/// The tests of this file count the process's worker threads, so they run one at a time.
static SERIAL: Mutex<()> = Mutex::new(());

/// Runs `f` on a fresh thread and fails the test if it panics or takes longer than a minute
/// (a hang).
fn within_a_minute<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
    let _guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (tx, rx) = mpsc::channel();
    let body = std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    match rx.recv_timeout(Duration::from_secs(60)) {
        Ok(value) => value,
        // The body panicked: fail with its panic.
        Err(mpsc::RecvTimeoutError::Disconnected) => match body.join() {
            Err(payload) => panic::resume_unwind(payload),
            Ok(()) => unreachable!("the body sent nothing and did not panic"),
        },
        Err(mpsc::RecvTimeoutError::Timeout) => panic!("the vector hung"),
    }
}

/// The threads of this process named like the vector's workers, where the system says.
fn worker_threads() -> Option<usize> {
    let tasks = std::fs::read_dir("/proc/self/task").ok()?;
    Some(
        tasks
            .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
            .filter(|name| name.starts_with("apo-env-"))
            .count(),
    )
}

/// Asserts that [`worker_threads`] is `expected` within five seconds: a new thread names itself
/// when it starts, and a joined thread leaves the list soon after it is joined.
fn assert_workers(expected: Option<usize>, what: &str) {
    let start = std::time::Instant::now();
    loop {
        let now = worker_threads();
        if now == expected {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "{what}: {now:?} worker threads, expected {expected:?}"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Observation `[t + action]`, terminates every 10 steps; panics at step `panic_at` (if any) or on a reset once `panic_on_reset`;
/// counts its drops in `dropped`.
struct Probe {
    t: usize,
    panic_at: Option<usize>,
    panic_on_reset: bool,
    dropped: Arc<AtomicUsize>,
    space: Space,
}

impl Probe {
    fn boxed(dropped: &Arc<AtomicUsize>, panic_at: Option<usize>) -> Box<dyn Env> {
        Box::new(Self {
            t: 0,
            panic_at,
            panic_on_reset: false,
            dropped: Arc::clone(dropped),
            space: Space::uniform_box(1, -1e6, 1e6),
        })
    }
}

impl Drop for Probe {
    fn drop(&mut self) {
        self.dropped.fetch_add(1, Ordering::SeqCst);
    }
}

impl Env for Probe {
    fn observation_space(&self) -> &Space {
        &self.space
    }
    fn action_space(&self) -> &Space {
        &self.space
    }
    fn reset(&mut self, _seed: Option<u64>, obs: &mut [f32]) {
        if std::mem::take(&mut self.panic_on_reset) {
            panic!("probe cannot reset");
        }
        self.t = 0;
        obs[0] = 0.0;
    }
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        self.t += 1;
        if self.panic_at == Some(self.t) {
            panic!("probe broke at step {}", self.t);
        }
        let Action::Continuous(a) = action else {
            unreachable!("a box action space")
        };
        obs[0] = self.t as f32 + a[0];
        Transition {
            reward: 1.0,
            terminated: self.t.is_multiple_of(10),
            truncated: false,
            info: StepInfo::default(),
        }
    }
}

fn probes(n: usize, panic_at: &[(usize, usize)], dropped: &Arc<AtomicUsize>) -> Vec<Box<dyn Env>> {
    (0..n)
        .map(|i| {
            let at = panic_at.iter().find(|(j, _)| *j == i).map(|(_, t)| *t);
            Probe::boxed(dropped, at)
        })
        .collect()
}

/// The message of a caught panic.
fn message(payload: Box<dyn std::any::Any + Send>) -> String {
    payload
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_default()
}

/// Steps `venv` once with action `a` for every environment; returns the observations.
fn step(venv: &mut VecEnv, a: f32) -> Vec<f32> {
    let n = venv.num_envs();
    let (mut obs, mut out) = (vec![0.0; n], vec![VecStep::default(); n]);
    venv.step(&vec![a; n], &mut obs, &mut out);
    obs
}

#[test]
fn dropping_a_threaded_vector_joins_its_workers() {
    within_a_minute(|| {
        let before = worker_threads();
        let dropped = Arc::new(AtomicUsize::new(0));
        let mut venv = VecEnv::new(probes(6, &[], &dropped))
            .and_then(|v| v.with_threads(3))
            .expect("threads start");
        assert_workers(before.map(|b| b + 2), "3 threads: the caller and 2 workers");
        let mut obs = vec![0.0; 6];
        venv.reset(Some(0), &mut obs);
        for _ in 0..7 {
            step(&mut venv, 0.5);
        }
        // Back to serial: the workers are joined, the environments kept.
        let mut venv = venv.with_threads(1).expect("serial");
        assert_workers(before, "back to serial, the workers were joined");
        assert_eq!(dropped.load(Ordering::SeqCst), 0);
        assert_eq!(step(&mut venv, 0.5), vec![8.5; 6], "the state was kept");
        let venv = venv.with_threads(6).expect("threads start");
        assert_workers(before.map(|b| b + 5), "6 threads: 5 workers");
        drop(venv);
        assert_workers(before, "dropping joined the workers");
        assert_eq!(
            dropped.load(Ordering::SeqCst),
            6,
            "and dropped every environment"
        );
        // A vector that sleeps between steps (its workers block) still steps and drops.
        let mut venv = VecEnv::new(probes(4, &[], &dropped))
            .and_then(|v| v.with_threads(4))
            .expect("threads start");
        venv.reset(None, &mut obs[..4]);
        for k in 1..4 {
            std::thread::sleep(Duration::from_millis(20));
            assert_eq!(step(&mut venv, 0.0), vec![k as f32; 4]);
        }
        drop(venv);
        assert_workers(before, "dropping joined the workers");
        assert_eq!(dropped.load(Ordering::SeqCst), 10);
    });
}

#[test]
fn a_panic_on_a_worker_reaches_the_caller_with_the_environment_and_message() {
    within_a_minute(|| {
        let before = worker_threads();
        let dropped = Arc::new(AtomicUsize::new(0));
        // Slices of 4 threads over 7 envs: [0], [1, 2], [3, 4], [5, 6]; env 4 panics at step 3.
        let mut venv = VecEnv::new(probes(7, &[(4, 3)], &dropped))
            .and_then(|v| v.with_threads(4))
            .expect("threads start");
        let mut obs = vec![0.0; 7];
        venv.reset(Some(0), &mut obs);
        step(&mut venv, 0.0);
        step(&mut venv, 0.0);
        let caught = panic::catch_unwind(AssertUnwindSafe(|| step(&mut venv, 0.0)));
        let message = message(caught.expect_err("the panic reached the caller"));
        assert!(
            message.contains("environment 4 panicked on worker thread apo-env-2")
                && message.contains("probe broke at step 3"),
            "{message}"
        );
        // The vector is still usable and its threads are alive and idle.
        assert_eq!(step(&mut venv, 0.25)[0], 4.25);
        drop(venv);
        assert_workers(before, "dropping joined the workers");
        assert_eq!(dropped.load(Ordering::SeqCst), 7);
    });
}

#[test]
fn a_panic_on_the_callers_slice_unwinds_after_the_workers_are_done() {
    within_a_minute(|| {
        let before = worker_threads();
        let dropped = Arc::new(AtomicUsize::new(0));
        let mut venv = VecEnv::new(probes(4, &[(1, 2), (3, 2)], &dropped))
            .and_then(|v| v.with_threads(2))
            .expect("threads start");
        let mut obs = vec![0.0; 4];
        venv.reset(Some(0), &mut obs);
        step(&mut venv, 0.0);
        let caught = panic::catch_unwind(AssertUnwindSafe(|| step(&mut venv, 0.0)));
        // The caller's own panic wins, unchanged; the worker's is dropped with that step.
        assert_eq!(
            message(caught.expect_err("the panic reached the caller")),
            "probe broke at step 2"
        );
        assert_eq!(step(&mut venv, 0.5), vec![3.5; 4]);
        drop(venv);
        assert_workers(before, "dropping joined the workers");
        assert_eq!(dropped.load(Ordering::SeqCst), 4);
    });
}

#[test]
fn a_panic_in_a_reset_on_a_worker_reaches_the_caller() {
    within_a_minute(|| {
        let dropped = Arc::new(AtomicUsize::new(0));
        let mut envs = probes(3, &[], &dropped);
        envs[2] = Box::new(Probe {
            t: 0,
            panic_at: None,
            panic_on_reset: true,
            dropped: Arc::clone(&dropped),
            space: Space::uniform_box(1, -1e6, 1e6),
        });
        let mut venv = VecEnv::new(envs)
            .and_then(|v| v.with_threads(3))
            .expect("threads start");
        let mut obs = vec![0.0; 3];
        let caught = panic::catch_unwind(AssertUnwindSafe(|| venv.reset(Some(1), &mut obs)));
        let message = message(caught.expect_err("the panic reached the caller"));
        assert!(
            message.contains("environment 2 panicked on worker thread apo-env-2")
                && message.contains("probe cannot reset"),
            "{message}"
        );
        venv.reset(Some(1), &mut obs);
        assert_eq!(step(&mut venv, 0.5), vec![1.5; 3]);
    });
}
