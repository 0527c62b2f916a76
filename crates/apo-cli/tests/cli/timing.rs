//! Honest timing: `apo bench epoch`'s end-to-end figure is the whole run's steps over its wall
//! time and never exceeds the simulator's own speed in that run; `progress.csv`'s
//! `steps_per_s` is the run's steps over its wall time so far, and `sim_s` is part of the
//! rollout.

use super::{ok, train};
use apo_train::progress_csv;

/// `key=value` of `line`, parsed.
fn field(line: &str, key: &str) -> f64 {
    line.split_whitespace()
        .find_map(|kv| kv.strip_prefix(&format!("{key}=")))
        .unwrap_or_else(|| panic!("no {key}= in {line}"))
        .parse()
        .unwrap_or_else(|e| panic!("{key} in {line}: {e}"))
}

#[test]
fn bench_epoch_end_to_end_never_beats_the_simulator_in_the_same_run() {
    // one environment, one thread, pipelined: the last epoch has no rollout ahead, which made
    // a per-epoch ratio look faster than the simulator itself
    let out = ok(&[
        "bench",
        "epoch",
        "--algo",
        "apo",
        "--env",
        "Hopper",
        "--epochs",
        "4",
        "--steps-per-epoch",
        "1000",
        "--threads",
        "1",
    ]);
    // the end-to-end figures are the last line
    let end = out
        .lines()
        .last()
        .filter(|l| l.starts_with("end_to_end:"))
        .unwrap_or_else(|| panic!("the last line is not end_to_end: {out}"));
    let (steps, wall) = (field(end, "steps"), field(end, "wall_s"));
    let (rate, sim_rate, share) = (
        field(end, "steps_per_s"),
        field(end, "sim_steps_per_s"),
        field(end, "sim_share"),
    );
    assert_eq!(steps, 4000.0, "{out}");
    assert!((rate - steps / wall).abs() <= 0.5 + 1e-3 * rate, "{out}");
    assert!(
        rate <= sim_rate,
        "end to end {rate} above the simulator's {sim_rate}: {out}"
    );
    assert!(share > 0.0 && share <= 1.0, "{out}");
    // every epoch's rollout holds its simulator time, and the epochs' shares add up to at most
    // the run's wall time
    let rows: Vec<Vec<f64>> = out
        .lines()
        .skip_while(|l| !l.starts_with("epoch"))
        .skip(1)
        .take_while(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| {
            l.split_whitespace()
                .map(|v| v.parse().expect("a number"))
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), 4, "{out}");
    for r in &rows {
        let (total, rollout, sim) = (r[1], r[2], r[3]);
        assert!(sim > 0.0 && sim <= rollout + 1e-3, "epoch {}: {out}", r[0]);
        assert!(total > 0.0, "{out}");
    }
    let totals: f64 = rows.iter().map(|r| r[1]).sum();
    assert!(
        totals <= wall + 0.01,
        "epochs {totals} s, run {wall} s: {out}"
    );
}

#[test]
fn progress_steps_per_s_is_the_runs_steps_over_its_wall_time() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    train(&run, "apo", &[]);
    let rows = progress_csv::read(&run.join("progress.csv")).expect("progress.csv");
    assert_eq!(rows.len(), 3);
    for r in &rows {
        let expected = r.env_steps as f64 / r.time_s;
        assert!(
            (r.steps_per_s - expected).abs() <= 1e-6 * expected,
            "epoch {}: steps_per_s {} against env_steps / time_s {expected}",
            r.epoch,
            r.steps_per_s
        );
        assert!(
            r.sim_s > 0.0 && r.sim_s <= r.rollout_s,
            "epoch {}: {r:?}",
            r.epoch
        );
    }
}
