//! Telling the truth to the user: help and `apo config`, flags, summaries, eval, logs,
//! TensorBoard files.

use std::path::Path;
use std::process::Command;

use super::{fails, ok, path, train};

#[test]
fn help_shows_defaults_and_config_prints_every_key_documented() {
    let help = ok(&["train", "--help"]);
    for text in [
        "default 200",
        "default 30000",
        "apo config --algo",
        "--num-envs",
        "--checkpoint-every",
        "0..=9223372036854775807",
    ] {
        assert!(
            help.contains(text),
            "`apo train --help` lacks `{text}`:\n{help}"
        );
    }
    let text = ok(&[
        "config", "--algo", "papo", "--env", "Hopper", "--set", "algo.k=5",
    ]);
    assert!(
        text.contains("# probability factor k") && text.contains("\nk = 5.0\n"),
        "{text}"
    );
    assert!(
        text.contains("[algo.papo.policy_update]")
            && text.contains(
                "# Adam learning rate (paper: 3e-4 policy, 1e-3 value); (0, 1e30]\nlr = 0.0003"
            ),
        "{text}"
    );
    // what `apo config` prints is a config file that reproduces itself
    let tmp = tempfile::tempdir().expect("tempdir");
    let file = tmp.path().join("papo.toml");
    std::fs::write(&file, &text).expect("write");
    let again = ok(&[
        "config",
        "--algo",
        "papo",
        "--env",
        "Hopper",
        "--config",
        path(&file),
    ]);
    assert_eq!(again, text);
    let err = fails(&["config", "--algo", "apo", "--set", "algo.k=-1"]);
    assert!(err.contains("`algo.apo.k` = -1"), "{err}");
    // every number has a range: a k of 1e308 is named with it, not left to overflow the loss
    let err = fails(&["config", "--algo", "papo", "--set", "algo.k=1e308"]);
    assert!(
        err.contains("`algo.papo.k` = 1e308") && err.contains("[0, 1000]"),
        "{err}"
    );
}

#[test]
fn flags_summary_eval_logs_and_tensorboard() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run, with a comma");
    let out = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args([
            "train",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--epochs",
            "2",
            "--steps-per-epoch",
            "400",
            "--num-envs",
            "2",
            "--checkpoint-every",
            "2",
            "--quiet",
            "--set",
            "keep_checkpoint_every=1",
            "--out",
            path(&run),
        ])
        .env("RUST_LOG", "info")
        .output()
        .expect("apo runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("epoch done"),
        "RUST_LOG=info shows the log: {stderr}"
    );
    assert!(
        !stderr.contains('\x1b'),
        "no colour codes when stderr is not a terminal: {stderr:?}"
    );
    let config = std::fs::read_to_string(run.join("config.toml")).expect("config");
    assert!(
        config.contains("num_envs = 2") && config.contains("checkpoint_every = 2"),
        "{config}"
    );
    let log = std::fs::read_to_string(run.join("train.log")).expect("log");
    assert!(
        log.contains("ret_mean=") && !log.contains("Some("),
        "the log prints values: {log}"
    );

    // TensorBoard: one event file with the epochs' scalars
    let events: Vec<_> = std::fs::read_dir(&run)
        .expect("run dir")
        .flatten()
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with("events.out.tfevents.")
        })
        .collect();
    assert_eq!(events.len(), 1);
    let bytes = std::fs::read(events[0].path()).expect("events");
    let has = |tag: &str| bytes.windows(tag.len()).any(|w| w == tag.as_bytes());
    assert!(has("brain.Event:2") && has("return/mean") && has("policy/kl"));

    // summary: an aligned table, or CSV
    let other = tmp.path().join("other");
    train(&other, "trpo", &[]);
    let table = ok(&["summary", path(&run), path(&other), "--last", "1"]);
    let lines: Vec<&str> = table.lines().collect();
    assert_eq!(lines.len(), 3, "{table}");
    assert!(
        lines[0].starts_with("run") && lines[0].contains("worst(last 1)"),
        "{table}"
    );
    assert!(
        lines
            .iter()
            .all(|l| l.chars().count() == lines[0].chars().count()),
        "aligned:\n{table}"
    );
    let csv = ok(&["summary", path(&run), path(&other), "--last", "1", "--csv"]);
    assert!(
        csv.starts_with("run,epochs,env_steps,mean_all,mean_last1,"),
        "{csv}"
    );
    assert!(
        csv.contains(&format!("\"{}\",2,", path(&run))),
        "a run name with a comma is quoted: {csv}"
    );

    // eval: std, and a chosen checkpoint
    let latest = ok(&["eval", "--run", path(&run), "--episodes", "3"]);
    assert!(
        latest.contains("checkpoint_epoch=2 episodes=3 mean_return=")
            && latest.contains("std_return="),
        "{latest}"
    );
    let first = ok(&[
        "eval",
        "--run",
        path(&run),
        "--episodes",
        "3",
        "--checkpoint",
        "1",
    ]);
    assert!(first.contains("checkpoint_epoch=1 "), "{first}");
    let err = fails(&["eval", "--run", path(&run), "--checkpoint", "7"]);
    assert!(
        err.contains("no checkpoint of epoch 7 (kept: [1, 2])"),
        "{err}"
    );
    // a kept folder that holds another epoch's state (renamed) is named, not played
    let kept = run.join("checkpoints");
    std::fs::remove_dir_all(kept.join("epoch-000001")).expect("rm");
    std::fs::rename(kept.join("epoch-000002"), kept.join("epoch-000001")).expect("mv");
    let err = fails(&["eval", "--run", path(&run), "--checkpoint", "1"]);
    assert!(
        err.contains("holds the state of epoch 2, not of epoch 1"),
        "{err}"
    );
}

#[test]
fn wgpu_runs_without_runtime_dir_noise() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let out = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args([
            "train",
            "--algo",
            "trpo",
            "--env",
            "Pendulum-v1",
            "--backend",
            "wgpu",
            "--epochs",
            "1",
            "--steps-per-epoch",
            "200",
            "--quiet",
            "--out",
            path(&run),
        ])
        .env_remove("XDG_RUNTIME_DIR")
        .output()
        .expect("apo runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("XDG_RUNTIME_DIR"), "{stderr}");
    assert!(Path::new(&run).join("progress.csv").exists());
}

#[test]
fn hand_runs_record_their_success_rate_and_eval_and_summary_print_it() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("hand");
    // 2 epochs of two 50-step episodes each
    ok(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "HandReachDense",
        "--epochs",
        "2",
        "--steps-per-epoch",
        "100",
        "--quiet",
        "--out",
        path(&run),
    ]);
    let csv = std::fs::read_to_string(run.join("progress.csv")).expect("progress.csv");
    let header = csv.lines().next().expect("header");
    assert!(header.split(',').any(|c| c == "success_rate"), "{header}");
    let rows = apo_train::progress_csv::read(&run.join("progress.csv")).expect("rows");
    for row in &rows {
        assert_eq!(row.episodes, 2, "{row:?}");
        let rate = row.success_rate.expect("a hand task judges success");
        assert!([0.0, 0.5, 1.0].contains(&rate), "{rate}");
    }
    let eval = ok(&["eval", "--run", path(&run), "--episodes", "2"]);
    assert!(eval.contains(" success_rate="), "{eval}");
    // a task without a goal: an empty column, and no success rate from eval
    let cartpole = tmp.path().join("cartpole");
    train(&cartpole, "ppo", &[]);
    let rows = apo_train::progress_csv::read(&cartpole.join("progress.csv")).expect("rows");
    assert!(rows.iter().all(|r| r.success_rate.is_none()), "{rows:?}");
    let eval = ok(&["eval", "--run", path(&cartpole), "--episodes", "2"]);
    assert!(!eval.contains("success_rate"), "{eval}");
    // `apo summary` adds the success column when a run has one
    let both = ok(&["summary", path(&run), path(&cartpole), "--last", "2"]);
    let header = both.lines().next().expect("header");
    assert!(header.ends_with("success(last 2)"), "{both}");
    let cartpole_only = ok(&["summary", path(&cartpole), "--last", "2"]);
    assert!(!cartpole_only.contains("success"), "{cartpole_only}");
}
