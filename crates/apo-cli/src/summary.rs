//! The paper's metrics over runs: the average of the epochs' mean return and of their
//! worst return, over all epochs and over the last N epochs; the risk metrics of the last N
//! epochs (the average of the epochs' lower CVaR at 10 % and 10 % quantile of the returns);
//! and, for tasks that judge success, the average success rate over the last N. Printed as a
//! table or as CSV.

use std::path::Path;

use apo_core::metrics::average_over_epochs;

use apo_train::progress_csv;

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
    /// Average over the last N epochs of the lower CVaR at 10 % of the returns.
    pub cvar10_last: Option<f64>,
    /// Average over the last N epochs of the 10 % quantile of the returns.
    pub q10_last: Option<f64>,
    /// Average environment steps per second (rollout and update).
    pub steps_per_s: f64,
    /// Average over the last N epochs of the success rate, for tasks that judge success.
    pub success_last: Option<f64>,
}

/// Summarizes the run in `dir` with the last `last` epochs.
pub fn summarize(dir: &Path, last: usize) -> anyhow::Result<RunSummary> {
    Ok(summarize_rows(&run_rows(dir)?, last))
}

/// The rows of the run in `dir`'s `progress.csv` ([`progress_csv::read_rows`], after
/// [`apo_train::run_dir::progress_of`]); rows missing at the end — the checkpoint is at a later
/// epoch than the last row — are named in a warning, as a gap in the middle is.
///
/// # Errors
/// As those two.
pub fn run_rows(dir: &Path) -> anyhow::Result<Vec<progress_csv::ProgressRow>> {
    let path = apo_train::run_dir::progress_of(dir)?;
    let rows = progress_csv::read_rows(&path)?;
    let last = rows.last().map_or(0, |r| r.epoch);
    if let Ok(Some(checkpoint)) = apo_train::checkpoint::latest_epoch(dir) {
        if checkpoint > last {
            let missing = if checkpoint == last + 1 {
                format!("{checkpoint}")
            } else {
                format!("{}–{checkpoint}", last + 1)
            };
            progress_csv::warn(
                &path,
                &format!(
                    "epoch range(s) missing at the end (the checkpoint is at epoch {checkpoint})"
                ),
                &[missing],
            );
        }
    }
    Ok(rows)
}

/// [`summarize`] of a run's progress rows.
pub fn summarize_rows(rows: &[progress_csv::ProgressRow], last: usize) -> RunSummary {
    let means: Vec<f64> = rows.iter().filter_map(|r| r.ep_ret_mean).collect();
    let worst: Vec<f64> = rows.iter().filter_map(|r| r.ep_ret_min).collect();
    let success: Vec<f64> = rows.iter().filter_map(|r| r.success_rate).collect();
    let cvar10: Vec<f64> = rows.iter().filter_map(|r| r.ep_ret_cvar10).collect();
    let q10: Vec<f64> = rows.iter().filter_map(|r| r.ep_ret_q10).collect();
    let time = rows.last().map_or(0.0, |r| r.time_s);
    let env_steps = rows.last().map_or(0, |r| r.env_steps);
    RunSummary {
        // the last epoch recorded: a gap (named when read) does not shorten the run
        epochs: rows.last().map_or(0, |r| r.epoch),
        env_steps,
        mean_all: average_over_epochs(&means, None),
        mean_last: average_over_epochs(&means, Some(last)),
        worst_all: average_over_epochs(&worst, None),
        worst_last: average_over_epochs(&worst, Some(last)),
        cvar10_last: average_over_epochs(&cvar10, Some(last)),
        q10_last: average_over_epochs(&q10, Some(last)),
        steps_per_s: if time > 0.0 {
            env_steps as f64 / time
        } else {
            0.0
        },
        success_last: average_over_epochs(&success, Some(last)),
    }
}

/// The mean and the population standard deviation of `values` (`(NaN, NaN)` when empty).
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt())
}

/// A run's values in the column order of [`table`] and [`csv`], formatted (returns with two
/// decimals, steps/s as a whole number, the success rate with three); `None` where the run has
/// no episode to average. The success column only `with_success`.
fn cells(s: &RunSummary, with_success: bool) -> Vec<Option<String>> {
    let returns = |v: Option<f64>| v.map(|v| format!("{v:.2}"));
    let mut cells = vec![
        Some(s.epochs.to_string()),
        Some(s.env_steps.to_string()),
        returns(s.mean_all),
        returns(s.mean_last),
        returns(s.worst_all),
        returns(s.worst_last),
        returns(s.cvar10_last),
        returns(s.q10_last),
        Some(format!("{:.0}", s.steps_per_s)),
    ];
    if with_success {
        cells.push(s.success_last.map(|v| format!("{v:.3}")));
    }
    cells
}

/// The column headers after `run`, each as (the words of [`table`], the name of [`csv`]).
fn headers(last: usize, with_success: bool) -> Vec<(String, String)> {
    let mut names = vec![
        ("epochs".into(), "epochs".into()),
        ("env steps".into(), "env_steps".into()),
        ("mean(all)".into(), "mean_all".into()),
        (format!("mean(last {last})"), format!("mean_last{last}")),
        ("worst(all)".into(), "worst_all".into()),
        (format!("worst(last {last})"), format!("worst_last{last}")),
        (format!("cvar10(last {last})"), format!("cvar10_last{last}")),
        (format!("q10(last {last})"), format!("q10_last{last}")),
        ("steps/s".into(), "steps_per_s".into()),
    ];
    if with_success {
        names.push((
            format!("success(last {last})"),
            format!("success_last{last}"),
        ));
    }
    names
}

/// Whether any of the runs judged success (then the success column is shown).
fn any_success(rows: &[(String, RunSummary)]) -> bool {
    rows.iter().any(|(_, s)| s.success_last.is_some())
}

/// An aligned table of the runs' summaries (`last`: the N of "last N"), one line per run
/// under a header: the run names left-aligned, the numbers right-aligned, "-" for a missing
/// value; a `success(last N)` column when any run's task judges success. Every line ends with
/// a newline.
pub fn table(rows: &[(String, RunSummary)], last: usize) -> String {
    let with_success = any_success(rows);
    let header = std::iter::once("run".to_string())
        .chain(
            headers(last, with_success)
                .into_iter()
                .map(|(words, _)| words),
        )
        .collect();
    let lines: Vec<Vec<String>> = std::iter::once(header)
        .chain(rows.iter().map(|(run, s)| {
            std::iter::once(run.clone())
                .chain(
                    cells(s, with_success)
                        .into_iter()
                        .map(|c| c.unwrap_or_else(|| "-".to_string())),
                )
                .collect()
        }))
        .collect();
    let mut widths = vec![0; lines[0].len()];
    for line in &lines {
        for (width, cell) in widths.iter_mut().zip(line) {
            *width = (*width).max(cell.chars().count());
        }
    }
    let mut out = String::new();
    for line in &lines {
        let (run, numbers) = (&line[0], &line[1..]);
        out.push_str(&format!("{run:<w$}", w = widths[0]));
        for (cell, width) in numbers.iter().zip(&widths[1..]) {
            out.push_str(&format!("  {cell:>width$}"));
        }
        out.push('\n');
    }
    out
}

/// The runs' summaries as CSV (`last`: the N of "last N") with the header
/// `run,epochs,env_steps,mean_all,mean_last{N},worst_all,worst_last{N},cvar10_last{N},q10_last{N},steps_per_s`, and
/// `success_last{N}` after it when any run's task judges success; fields are quoted where
/// needed and a missing value is an empty field.
pub fn csv(rows: &[(String, RunSummary)], last: usize) -> anyhow::Result<String> {
    let with_success = any_success(rows);
    let mut writer = ::csv::Writer::from_writer(Vec::new());
    writer.write_record(
        std::iter::once("run".to_string()).chain(
            headers(last, with_success)
                .into_iter()
                .map(|(_, name)| name),
        ),
    )?;
    for (run, s) in rows {
        let values: Vec<String> = cells(s, with_success)
            .into_iter()
            .map(Option::unwrap_or_default)
            .collect();
        writer.write_record(std::iter::once(run).chain(&values))?;
    }
    let bytes = writer
        .into_inner()
        .map_err(|e| anyhow::anyhow!("csv: {e}"))?;
    Ok(String::from_utf8(bytes)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows() -> Vec<(String, RunSummary)> {
        vec![
            (
                "runs/Hopper-apo-s0".to_string(),
                RunSummary {
                    epochs: 75,
                    env_steps: 300_000,
                    mean_all: Some(812.456),
                    mean_last: Some(1503.1),
                    worst_all: Some(-12.0),
                    worst_last: Some(420.0),
                    cvar10_last: Some(431.25),
                    q10_last: None,
                    steps_per_s: 1234.4,
                    success_last: None,
                },
            ),
            (
                "runs/a,b \"quoted\"".to_string(),
                RunSummary {
                    epochs: 2,
                    env_steps: 40,
                    mean_all: None,
                    mean_last: None,
                    worst_all: None,
                    worst_last: None,
                    cvar10_last: None,
                    q10_last: None,
                    steps_per_s: 0.0,
                    success_last: None,
                },
            ),
        ]
    }

    #[test]
    fn table_is_aligned_with_a_header() {
        let text = table(&rows(), 20);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        let width = lines[0].chars().count();
        assert!(lines.iter().all(|l| l.chars().count() == width), "{text}");
        let header: Vec<&str> = lines[0]
            .split("  ")
            .filter(|c| !c.is_empty())
            .map(str::trim)
            .collect();
        assert_eq!(
            header,
            [
                "run",
                "epochs",
                "env steps",
                "mean(all)",
                "mean(last 20)",
                "worst(all)",
                "worst(last 20)",
                "cvar10(last 20)",
                "q10(last 20)",
                "steps/s"
            ]
        );
        assert!(lines[1].starts_with("runs/Hopper-apo-s0 "));
        assert!(lines[1].ends_with("  1234"), "{text}");
        // Right-aligned: each value ends where its header ends.
        let end_of = |line: &str, cell: &str| line.find(cell).map(|i| i + cell.len());
        assert_eq!(end_of(lines[1], "812.46"), end_of(lines[0], "mean(all)"));
        assert_eq!(end_of(lines[1], "-12.00"), end_of(lines[0], "worst(all)"));
        // the first run: "-12.00" and its missing q10
        assert_eq!(lines[1].matches(" -").count(), 2, "{text}");
        assert_eq!(lines[2].matches(" -").count(), 6, "{text}");
        assert!(lines[2].ends_with(" 0"));
    }

    #[test]
    fn csv_round_trips_and_quotes() {
        let text = csv(&rows(), 10).unwrap();
        assert!(text.starts_with(
            "run,epochs,env_steps,mean_all,mean_last10,worst_all,worst_last10,cvar10_last10,q10_last10,steps_per_s\n"
        ));
        assert!(text.contains("\"runs/a,b \"\"quoted\"\"\","), "{text}");
        let mut reader = ::csv::Reader::from_reader(text.as_bytes());
        let records: Vec<::csv::StringRecord> = reader.records().collect::<Result<_, _>>().unwrap();
        assert_eq!(records.len(), 2);
        assert_eq!(
            records[0].iter().collect::<Vec<_>>(),
            [
                "runs/Hopper-apo-s0",
                "75",
                "300000",
                "812.46",
                "1503.10",
                "-12.00",
                "420.00",
                "431.25",
                "",
                "1234"
            ]
        );
        assert_eq!(
            records[1].iter().collect::<Vec<_>>(),
            [
                "runs/a,b \"quoted\"",
                "2",
                "40",
                "",
                "",
                "",
                "",
                "",
                "",
                "0"
            ]
        );
    }

    #[test]
    fn a_success_column_appears_when_a_run_judges_success() {
        let mut rows = rows();
        rows[0].1.success_last = Some(0.25);
        let text = table(&rows, 5);
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines[0].ends_with("  success(last 5)"), "{text}");
        assert!(lines[1].ends_with("  0.250"), "{text}");
        assert!(lines[2].ends_with(" -"), "{text}");
        let text = csv(&rows, 5).unwrap();
        let mut lines = text.lines();
        assert!(lines
            .next()
            .unwrap()
            .ends_with(",steps_per_s,success_last5"));
        assert!(lines.next().unwrap().ends_with(",1234,0.250"), "{text}");
        assert!(lines.next().unwrap().ends_with(",0,"), "{text}");
    }

    #[test]
    fn the_success_rate_is_averaged_over_the_last_epochs() {
        let row = |epoch: usize, success_rate: Option<f64>| progress_csv::ProgressRow {
            epoch,
            success_rate,
            ..Default::default()
        };
        let rows = [row(1, Some(0.0)), row(2, Some(0.5)), row(3, Some(1.0))];
        assert_eq!(summarize_rows(&rows, 2).success_last, Some(0.75));
        assert_eq!(summarize_rows(&rows[..1], 2).success_last, Some(0.0));
        assert_eq!(summarize_rows(&[row(1, None)], 2).success_last, None);
        let risk = |epoch: usize, cvar10: f64| progress_csv::ProgressRow {
            epoch,
            ep_ret_cvar10: Some(cvar10),
            ep_ret_q10: Some(cvar10 + 1.0),
            ..Default::default()
        };
        let s = summarize_rows(&[risk(1, -4.0), risk(2, 1.0), risk(3, 2.0)], 2);
        assert_eq!((s.cvar10_last, s.q10_last), (Some(1.5), Some(2.5)));
    }
}
