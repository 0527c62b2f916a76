//! Rule: every wait can be stopped within seconds. One SIGTERM ends a training whose epoch
//! would last minutes (a long update) within the grace period, with the signal's exit status
//! and a message that says what was kept; a stalled `ffmpeg` is stopped by `apo render` (see
//! `causes`); a long bootstrap shows a progress bar with an estimate of the time left.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::path;

#[test]
fn one_sigterm_ends_a_long_update_within_seconds() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    // 10 000 passes of each update over the batch: minutes of one epoch's update
    let mut child = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args([
            "train",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--epochs",
            "2",
            "--steps-per-epoch",
            "2000",
            "--quiet",
            "--set",
            "algo.policy_update.iters=10000",
            "--set",
            "algo.policy_update.target_kl=1000",
            "--set",
            "algo.value_update.iters=10000",
            "--out",
            path(&run),
        ])
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn apo");
    // the rollout of 2000 CartPole steps takes well under this: the update is running
    std::thread::sleep(Duration::from_secs(4));
    assert!(
        child.try_wait().expect("poll").is_none(),
        "the epoch ended too soon for this test"
    );
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    let signalled = Instant::now();
    let out = child.wait_with_output().expect("wait");
    let waited = signalled.elapsed();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        waited < Duration::from_secs(20),
        "stopped after {waited:?}: {stderr}"
    );
    assert_eq!(out.status.code(), Some(143), "{stderr}");
    assert!(
        stderr.contains("did not end within 10 s of the signal")
            && stderr.contains("nothing to resume"),
        "{stderr}"
    );
    assert!(!run.join("progress.csv").exists(), "no epoch was recorded");
}

#[test]
fn a_long_bootstrap_shows_a_progress_bar_with_an_estimate_on_a_terminal() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let scores = tmp.path().join("scores.csv");
    let mut text = String::from("algorithm,task,score\n");
    for (a, algo) in ["x", "y", "z"].iter().enumerate() {
        for task in 0..4 {
            for run in 0..5 {
                text.push_str(&format!(
                    "{algo},t{task},{}\n",
                    (a * 31 + task * 7 + run) % 11
                ));
            }
        }
    }
    std::fs::write(&scores, text).expect("write");
    // `script` gives apo a terminal (util-linux, on every Debian)
    let command = format!(
        "{} stats {} --reps 10000",
        env!("CARGO_BIN_EXE_apo"),
        path(&scores)
    );
    let out = Command::new("script")
        .args(["-qec", &command, "/dev/null"])
        .output()
        .expect("script runs");
    let shown = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{shown}");
    assert!(
        shown.contains("bootstrap") && shown.contains("left)"),
        "{shown}"
    );
    // without a terminal (a pipe, a file), no bar
    let piped = super::apo(&["stats", path(&scores), "--reps", "10000"]);
    assert!(!String::from_utf8_lossy(&piped.stderr).contains("bootstrap"));
}
