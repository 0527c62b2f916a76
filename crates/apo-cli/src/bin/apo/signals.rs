//! The signals that ask a process to stop ([`STOP_SIGNALS`]: SIGINT from Ctrl-C, SIGTERM from
//! `kill` and schedulers, SIGHUP from a closed terminal, SIGQUIT from Ctrl-\\): a training
//! checkpoints and stops on the first and exits at once on the second, or when its epoch has
//! not ended [`STOP_GRACE`] after the first; a render removes its unfinished file; a sweep
//! passes each one on to its running runs and waits for them. A SIGHUP that the process was
//! started ignoring (`nohup apo train … &`) stays ignored, as it does for other Unix tools:
//! a closed terminal then leaves the run going.

/// Signals that come within this of the first count as the first (see [`Signals::install`]).
pub const SAME_SIGNAL_WITHIN: Duration = Duration::from_millis(500);

/// How long a training may take after the first SIGINT or SIGTERM to end its epoch and write
/// its checkpoint; then it stops at once, keeping the last checkpoint on disk (what a second
/// signal does).
pub const STOP_GRACE: Duration = Duration::from_secs(10);

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use signal_hook::consts::{SIGHUP, SIGINT, SIGQUIT, SIGTERM};

/// The signals every subcommand that writes files stops on cleanly, one rule for all.
pub const STOP_SIGNALS: [i32; 4] = [SIGINT, SIGTERM, SIGHUP, SIGQUIT];

/// The name of stop signal `signal` (`SIGINT` for an unknown number).
pub fn signal_name(signal: usize) -> &'static str {
    match i32::try_from(signal).unwrap_or(SIGINT) {
        SIGTERM => "SIGTERM",
        SIGHUP => "SIGHUP",
        SIGQUIT => "SIGQUIT",
        _ => "SIGINT",
    }
}

/// Exit status of a process stopped by a signal: 128 + its number (SIGINT 130, SIGTERM 143,
/// SIGHUP 129, SIGQUIT 131).
pub fn interrupted_status(signal: usize) -> u8 {
    128u8.saturating_add(u8::try_from(signal).unwrap_or(0))
}

/// Stop flags raised by SIGINT and SIGTERM: the first raises `stop` (the run checkpoints and
/// ends), a second exits at once with 128 + the signal's number.
pub struct Signals {
    /// Raised by the first signal.
    pub stop: Arc<AtomicBool>,
    /// The last signal's number.
    pub which: Arc<AtomicUsize>,
}

impl Signals {
    /// Installs the handlers: a thread that raises `stop` on the first signal and exits at
    /// once on a later one — one that comes [`SAME_SIGNAL_WITHIN`] or more after the first
    /// (GNU `timeout` sends its signal to the child and then to the child's process group:
    /// two at once, meant as one).
    pub fn install() -> anyhow::Result<Self> {
        let (stop, which) = (
            Arc::new(AtomicBool::new(false)),
            Arc::new(AtomicUsize::new(0)),
        );
        // a hangup ignored from the start (nohup) stays ignored: no handler replaces SIG_IGN
        let watched: Vec<i32> = STOP_SIGNALS
            .into_iter()
            .filter(|&s| s != SIGHUP || !ignored(s))
            .collect();
        let mut signals = signal_hook::iterator::Signals::new(watched)
            .context("installing the signal handlers")?;
        let (raised, last) = (Arc::clone(&stop), Arc::clone(&which));
        std::thread::spawn(move || {
            let mut first: Option<Instant> = None;
            for signal in signals.forever() {
                last.store(signal as usize, Ordering::SeqCst);
                match first {
                    None => {
                        first = Some(Instant::now());
                        raised.store(true, Ordering::SeqCst);
                    }
                    Some(at) if at.elapsed() >= SAME_SIGNAL_WITHIN => {
                        std::process::exit(i32::from(interrupted_status(signal as usize)))
                    }
                    Some(_) => {}
                }
            }
        });
        Ok(Self { stop, which })
    }
}

/// Whether `signal` is ignored (`SIG_IGN`) in this process now, as `nohup` leaves SIGHUP.
fn ignored(signal: i32) -> bool {
    // SAFETY: sigaction with a null new action only reads the current one into `old`, a
    // zeroed struct owned here
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(signal, std::ptr::null(), &mut old) == 0
            && old.sa_sigaction == libc::SIG_IGN
    }
}

impl Signals {
    /// Starts a watchdog over the work that follows: when it has not ended `grace` after the
    /// first signal (an epoch's update, an evaluation or a checkpoint can outlast the stop
    /// checks of the rollout), it prints `message()` and exits at once with 128 + the
    /// signal's number, as a second signal would. Dropping the returned [`Deadline`] ends it.
    pub fn deadline(&self, grace: Duration, message: Box<dyn Fn() -> String + Send>) -> Deadline {
        let done = Arc::new(AtomicBool::new(false));
        let (stop, which, ended) = (
            Arc::clone(&self.stop),
            Arc::clone(&self.which),
            Arc::clone(&done),
        );
        std::thread::spawn(move || {
            let mut since: Option<Instant> = None;
            while !ended.load(Ordering::SeqCst) {
                if stop.load(Ordering::SeqCst) {
                    let first = *since.get_or_insert_with(Instant::now);
                    if first.elapsed() >= grace && !ended.load(Ordering::SeqCst) {
                        apo_train::warnln!("{}", message());
                        std::process::exit(i32::from(interrupted_status(
                            which.load(Ordering::SeqCst),
                        )));
                    }
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        });
        Deadline { done }
    }
}

/// The watchdog of [`Signals::deadline`], ended when dropped.
pub struct Deadline {
    done: Arc<AtomicBool>,
}

impl Drop for Deadline {
    fn drop(&mut self) {
        self.done.store(true, Ordering::SeqCst);
    }
}

/// A sweep's signals: every SIGINT and SIGTERM is counted into `received` (never exiting the
/// sweep, which must outlive its runs), by a thread that ends when this is dropped.
pub struct SweepSignals {
    /// What was received.
    pub received: Arc<apo_cli::sweep::Received>,
    handle: signal_hook::iterator::Handle,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl SweepSignals {
    /// Installs the handler thread.
    pub fn install() -> anyhow::Result<Self> {
        use std::sync::atomic::Ordering;
        // a hangup ignored from the start (nohup) stays ignored: no handler replaces SIG_IGN
        let watched: Vec<i32> = STOP_SIGNALS
            .into_iter()
            .filter(|&s| s != SIGHUP || !ignored(s))
            .collect();
        let mut signals = signal_hook::iterator::Signals::new(watched)
            .context("installing the signal handlers")?;
        let handle = signals.handle();
        let received = Arc::new(apo_cli::sweep::Received::default());
        let counter = Arc::clone(&received);
        let thread = std::thread::spawn(move || {
            for signal in signals.forever() {
                counter.which.store(signal as usize, Ordering::SeqCst);
                counter.count.fetch_add(1, Ordering::SeqCst);
                apo_train::warnln!(
                    "apo sweep: signal {signal} received; passing it on to the running runs and waiting for them"
                );
            }
        });
        Ok(Self {
            received,
            handle,
            thread: Some(thread),
        })
    }
}

impl Drop for SweepSignals {
    fn drop(&mut self) {
        self.handle.close();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
