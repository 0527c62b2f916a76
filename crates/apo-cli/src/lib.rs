//! The library behind the `apo` binary: the front ends of benchmarks, plots, reports,
//! statistics, summaries, sweeps and the theory check. A run itself — its config,
//! directory, checkpoints, logs, evaluation and videos — is `apo_train`'s.

pub mod bench;
pub mod flags;
pub mod plot;
pub mod report;
pub mod slurm;
pub mod stats;
mod stats_plot;
pub mod summary;
pub mod sweep;
pub mod terminal;
pub mod theory;
