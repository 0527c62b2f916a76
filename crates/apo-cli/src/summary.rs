//! The paper's metrics over runs: the average of the epochs' mean return and of their
//! worst return, over all epochs and over the last N epochs.

use std::path::Path;

use apo_core::metrics::average_over_epochs;

use crate::progress;

/// The metrics of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSummary {
    /// Epochs in the run.
    pub epochs: usize,
    /// Environment steps in the run.
    pub env_steps: u64,
    /// Average over all epochs of the mean return.
    pub mean_all: Option<f64>,
    /// Average over the last N epochs of the mean return.
    pub mean_last: Option<f64>,
    /// Average over all epochs of the worst return.
    pub worst_all: Option<f64>,
    /// Average over the last N epochs of the worst return.
    pub worst_last: Option<f64>,
    /// Average environment steps per second (rollout and update).
    pub steps_per_s: f64,
}

/// Summarizes the run in `dir` with the last `last` epochs.
pub fn summarize(dir: &Path, last: usize) -> anyhow::Result<RunSummary> {
    let rows = progress::read(&dir.join("progress.csv"))?;
    let means: Vec<f64> = rows.iter().filter_map(|r| r.ep_ret_mean).collect();
    let worst: Vec<f64> = rows.iter().filter_map(|r| r.ep_ret_min).collect();
    let time = rows.last().map_or(0.0, |r| r.time_s);
    let env_steps = rows.last().map_or(0, |r| r.env_steps);
    Ok(RunSummary {
        epochs: rows.len(),
        env_steps,
        mean_all: average_over_epochs(&means, None),
        mean_last: average_over_epochs(&means, Some(last)),
        worst_all: average_over_epochs(&worst, None),
        worst_last: average_over_epochs(&worst, Some(last)),
        steps_per_s: if time > 0.0 { env_steps as f64 / time } else { 0.0 },
    })
}
