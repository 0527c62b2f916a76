//! Writing to the terminal without panicking: `println!` panics when standard output is a
//! closed pipe (`apo list | head -1`) or a full device (`> /dev/full`). Every line apo prints
//! goes through [`outln!`](crate::outln) / [`out!`](crate::out), which return an error naming
//! standard output, or [`apo_train::warnln!`] for standard error, which drops what cannot be
//! written (there is nowhere left to report it; the exit status still says how apo ended).

/// The error of a write to standard output: "cannot write to standard output: …", with the
/// OS error as its source (a closed pipe ends apo quietly: see [`is_closed_pipe`]).
pub fn stdout_error(error: std::io::Error) -> anyhow::Error {
    anyhow::Error::new(error).context("cannot write to standard output")
}

/// Whether `error` comes from writing to a closed pipe (the reader went away, as `head`
/// does): apo then ends quietly with the status of a process killed by SIGPIPE (141).
pub fn is_closed_pipe(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// `println!` that returns `anyhow::Result<()>` instead of panicking.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*).map_err($crate::terminal::stdout_error)
    }};
}

/// `print!` that returns `anyhow::Result<()>` instead of panicking.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout().lock(), $($arg)*).map_err($crate::terminal::stdout_error)
    }};
}
