//! The library behind the `apo` binary: run configuration, the training loop, run
//! directories, checkpoints, evaluation, videos, plots and benchmarks.

pub mod atomic;
pub mod bench;
pub mod checkpoint;
pub mod config;
pub mod episodes;
pub mod eval;
pub mod input;
#[cfg(feature = "mpi")]
pub mod mpi;
pub mod plot;
pub mod progress;
pub mod removal;
pub mod report;
pub mod run_dir;
pub mod stats;
mod stats_plot;
pub mod summary;
pub mod sweep;
pub mod tensorboard;
pub mod theory;
pub mod trainer;
pub mod video;

pub use config::{BackendKind, RunConfig};
