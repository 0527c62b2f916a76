//! SIGINT and SIGTERM: a training checkpoints and stops on the first and exits at once on the
//! second; a sweep passes each one on to its running runs and waits for them.

use std::sync::atomic::{AtomicBool, AtomicUsize};
use std::sync::Arc;

use anyhow::Context;

/// Exit status of a process stopped by SIGINT (128 + 2) or SIGTERM (128 + 15).
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
    /// Installs the handlers.
    pub fn install() -> anyhow::Result<Self> {
        use signal_hook::consts::{SIGINT, SIGTERM};
        use signal_hook::flag;
        let (stop, which) = (
            Arc::new(AtomicBool::new(false)),
            Arc::new(AtomicUsize::new(0)),
        );
        for signal in [SIGINT, SIGTERM] {
            // registered first, so it sees `stop` as the previous signal left it
            flag::register_conditional_shutdown(signal, 128 + signal, Arc::clone(&stop))
                .and_then(|_| flag::register_usize(signal, Arc::clone(&which), signal as usize))
                .and_then(|_| flag::register(signal, Arc::clone(&stop)))
                .context("installing the signal handlers")?;
        }
        Ok(Self { stop, which })
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
        use signal_hook::consts::{SIGINT, SIGTERM};
        use std::sync::atomic::Ordering;
        let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM])
            .context("installing the signal handlers")?;
        let handle = signals.handle();
        let received = Arc::new(apo_cli::sweep::Received::default());
        let counter = Arc::clone(&received);
        let thread = std::thread::spawn(move || {
            for signal in signals.forever() {
                counter.which.store(signal as usize, Ordering::SeqCst);
                counter.count.fetch_add(1, Ordering::SeqCst);
                eprintln!(
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
