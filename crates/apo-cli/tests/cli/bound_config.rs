//! A run is bound to the config it was trained with: its checkpoint records every config value
//! that can change what is learned, and `eval`, `render`, `train --resume` and `report` refuse
//! a run whose `config.toml` no longer gives them, naming the keys; only the resumable keys
//! (the epoch target, the checkpoint and evaluation cadence, videos) may change.

use crate::{fails, ok, path};

/// Replaces the line of `config.toml` in `run` that starts with `key = ` by `key = value`.
fn edit(run: &std::path::Path, key: &str, value: &str) {
    let file = run.join("config.toml");
    let text = std::fs::read_to_string(&file).expect("config.toml");
    let prefix = format!("{key} = ");
    assert!(
        text.lines().any(|l| l.starts_with(&prefix)),
        "{key} in {text}"
    );
    let edited: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with(&prefix) {
                format!("{prefix}{value}")
            } else {
                l.to_string()
            }
        })
        .collect();
    std::fs::write(&file, edited.join("\n") + "\n").expect("write");
}

#[test]
fn every_subcommand_refuses_a_run_whose_config_was_edited_to_another_task() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("cheetah");
    ok(&[
        "train",
        "--algo",
        "trpo",
        "--env",
        "HalfCheetah-v4",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--quiet",
        "--out",
        path(&run),
    ]);
    let original = std::fs::read_to_string(run.join("config.toml")).expect("config.toml");
    // another environment with the same sizes: the networks fit, what they learned does not
    edit(&run, "env", "\"Walker2d-v4\"");
    let named = |err: &str| {
        err.contains("differs from what the checkpoint")
            && err.contains("env = \"Walker2d-v4\" (trained with: \"HalfCheetah-v4\")")
            && err.contains("apo train --config")
    };
    let err = fails(&["eval", "--run", path(&run), "--episodes", "1"]);
    assert!(named(&err), "eval: {err}");
    let err = fails(&["train", "--resume", path(&run), "--epochs", "2", "--quiet"]);
    assert!(named(&err), "resume: {err}");
    let video = tmp.path().join("v.gif");
    let err = fails(&["render", "--run", path(&run), "--out", path(&video)]);
    assert!(named(&err), "render: {err}");
    assert!(!video.exists(), "render wrote {}", video.display());
    let err = fails(&[
        "report",
        path(&run),
        "--out",
        path(&tmp.path().join("report")),
    ]);
    assert!(named(&err), "report: {err}");
    // nothing was trained on the other task
    assert_eq!(
        std::fs::read_to_string(run.join("progress.csv"))
            .expect("progress")
            .lines()
            .count(),
        2
    );
    // a learning setting is bound too, and every key that differs is named
    std::fs::write(run.join("config.toml"), &original).expect("restore");
    edit(&run, "seed", "3");
    edit(&run, "steps_per_epoch", "400");
    let err = fails(&["eval", "--run", path(&run), "--episodes", "1"]);
    assert!(
        err.contains("seed = 3 (trained with: 0)")
            && err.contains("steps_per_epoch = 400 (trained with: 200)"),
        "{err}"
    );
    // the resumable keys may change: the epoch target, the evaluation cadence
    std::fs::write(run.join("config.toml"), &original).expect("restore");
    edit(&run, "eval_every", "1");
    ok(&["eval", "--run", path(&run), "--episodes", "1"]);
    ok(&["train", "--resume", path(&run), "--epochs", "2", "--quiet"]);
}
