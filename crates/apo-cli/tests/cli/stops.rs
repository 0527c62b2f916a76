//! Rule: every wait can be stopped within seconds. One SIGTERM ends a training whose epoch
//! would last minutes (a long update) within the grace period, with the signal's exit status
//! and a message that says what was kept; a stalled `ffmpeg` is stopped by `apo render` (see
//! `causes`); a long bootstrap shows a progress bar with an estimate of the time left.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::*;

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

/// Rule: every signal that asks a process to stop — SIGTERM (`kill`, schedulers), SIGHUP (a
/// closed terminal), SIGQUIT (Ctrl-\\), SIGINT (Ctrl-C, `main.rs`) — stops a training the same
/// way: a checkpoint of its last epoch, 128 + the signal's number, the resume command, and no
/// temporary file left.
#[test]
fn every_stop_signal_checkpoints_and_exits_with_its_status_and_the_resume_command() {
    let tmp = tempfile::tempdir().expect("tempdir");
    for (name, status) in [("TERM", 143), ("HUP", 129), ("QUIT", 131)] {
        let run = tmp.path().join(name);
        let child = long_run(&run);
        wait_for(&run.join("progress.csv"));
        signal(&child, name);
        let (code, stdout, stderr) = finish(child, 120);
        assert_eq!(code, Some(status), "SIG{name}: {stdout}{stderr}");
        assert!(
            stdout.contains(&format!("interrupted by SIG{name}"))
                && stdout.contains(&format!("apo train --resume {}", path(&run))),
            "{stdout}"
        );
        let done = timeless(&run).len();
        let state =
            std::fs::read_to_string(run.join("checkpoints/latest/state.json")).expect("checkpoint");
        assert!(state.contains(&format!("\"epoch\": {done}")), "{state}");
        let temps = files_under(&run)
            .into_iter()
            .filter(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().contains(".tmp"))
            })
            .collect::<Vec<_>>();
        assert!(temps.is_empty(), "SIG{name} left {temps:?}");
    }
}

/// Rule: a SIGHUP that `apo train` was started ignoring (`nohup apo train … &`) stays ignored,
/// as for other Unix tools: the run goes on; SIGTERM still stops it with a checkpoint.
#[test]
fn a_run_started_ignoring_sighup_keeps_going_after_one() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("nohup");
    let child = std::process::Command::new("nohup")
        .arg(env!("CARGO_BIN_EXE_apo"))
        .args([
            "train",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--epochs",
            "500",
            "--steps-per-epoch",
            "200",
            "--quiet",
            "--out",
            path(&run),
        ])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("nohup apo train");
    wait_for(&run.join("progress.csv"));
    signal(&child, "HUP");
    let before = timeless(&run).len();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    while timeless(&run).len() < before + 3 {
        assert!(
            std::time::Instant::now() < deadline,
            "the run stopped training after SIGHUP under nohup"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    signal(&child, "TERM");
    let (code, stdout, stderr) = finish(child, 120);
    assert_eq!(code, Some(143), "{stdout}{stderr}");
    assert!(stdout.contains("interrupted by SIGTERM"), "{stdout}");
}

/// An interrupted `apo bench epoch` removes its temporary run directory.
#[test]
fn an_interrupted_bench_epoch_leaves_no_temporary_run() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let child = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args([
            "bench",
            "epoch",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--steps-per-epoch",
            "2000",
            "--epochs",
            "200",
        ])
        .env("TMPDIR", tmp.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let deadline = Instant::now() + Duration::from_secs(300);
    while files_under(tmp.path())
        .iter()
        .all(|p| !p.ends_with("progress.csv"))
    {
        assert!(Instant::now() < deadline, "no epoch in time");
        std::thread::sleep(Duration::from_millis(20));
    }
    signal(&child, "INT");
    let (code, _, stderr) = finish(child, 120);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("interrupted by SIGINT"), "{stderr}");
    let left: Vec<_> = std::fs::read_dir(tmp.path()).expect("ls").collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn a_second_interrupt_exits_at_once() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    // A2C never stops its policy update early: 10 000 Adam passes over 2000 steps keep the
    // first epoch's update busy for longer than this test, and the update does not look at
    // the stop flag (the watchdog of `stops.rs` would end it 10 s after the first signal).
    let child = spawn(&[
        "train",
        "--algo",
        "a2c",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "2000",
        "--quiet",
        "--out",
        path(&run),
        "--set",
        "algo.policy_update.iters=10000",
        "--set",
        "algo.value_update.iters=10000",
    ]);
    wait_for(&run.join("train.log"));
    std::thread::sleep(Duration::from_secs(3));
    signal(&child, "INT");
    std::thread::sleep(Duration::from_secs(1));
    let mut child = child;
    assert!(
        child.try_wait().expect("try_wait").is_none(),
        "the first interrupt lets the update finish"
    );
    signal(&child, "INT");
    let (code, stdout, _) = finish(child, 30);
    assert_eq!(code, Some(130));
    assert!(!stdout.contains("checkpoint written"), "{stdout}");
}

#[test]
fn a_signal_to_the_sweep_reaches_its_runs_which_checkpoint_and_nothing_is_orphaned() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("s");
    let child = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args([
            "sweep",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--seeds",
            "0",
            "--epochs",
            "500",
            "--steps-per-epoch",
            "200",
            "--quiet",
            "--out",
            path(&out),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let run = out.join("CartPole-v1-ppo-s0");
    let deadline = Instant::now() + Duration::from_secs(300);
    while !run.join("checkpoints/latest/manifest.json").exists() {
        assert!(Instant::now() < deadline, "the run did not start");
        std::thread::sleep(Duration::from_millis(20));
    }
    // a run training under its lock is told apart from an interrupted one, and not launched
    let standing = super::apo(&["sweep", "--status", "--out", path(&out)]);
    let said = text(&standing.stdout);
    assert!(
        said.contains("CartPole-v1-ppo-s0  training (pid ")
            && said.contains("a new submission would launch nothing"),
        "{said}{}",
        text(&standing.stderr)
    );
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    let started = Instant::now();
    let output = child.wait_with_output().expect("wait");
    assert!(started.elapsed() < Duration::from_secs(120));
    assert_eq!(output.status.code(), Some(143), "{}", text(&output.stderr));
    assert!(
        text(&output.stdout).contains("interrupted"),
        "{}",
        text(&output.stdout)
    );
    // no child holds the run: its lock is free, and its checkpoint is before the target
    apo_train::run_dir::RunLock::acquire(&run).expect("the run's lock is free: no orphan");
    let epoch = apo_train::checkpoint::latest_epoch(&run)
        .expect("read")
        .expect("a checkpoint");
    assert!(epoch < 500, "the run stopped early (epoch {epoch})");
    let rows = super::timeless(&run);
    assert_eq!(rows.len(), epoch, "progress.csv agrees with the checkpoint");
}

/// The processes whose command line mentions `needle` (read from /proc).
fn processes_with(needle: &str) -> Vec<String> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").expect("/proc").flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if !name.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        if let Ok(cmdline) = std::fs::read(entry.path().join("cmdline")) {
            let cmdline = String::from_utf8_lossy(&cmdline).replace('\0', " ");
            if cmdline.contains(needle) {
                found.push(format!("{name}: {cmdline}"));
            }
        }
    }
    found
}

#[test]
fn the_runs_of_a_sweep_killed_outright_stop_with_it() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let mut sweep = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args([
            "sweep",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--seeds",
            "0",
            "--epochs",
            "100000",
            "--steps-per-epoch",
            "200",
            "--quiet",
            "--out",
            path(&out),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn the sweep");
    let run = out.join("CartPole-v1-ppo-s0");
    let deadline = Instant::now() + Duration::from_secs(120);
    while !run.join("checkpoints/latest").is_dir() {
        assert!(Instant::now() < deadline, "the sweep's run did not start");
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        !processes_with(path(&run)).is_empty(),
        "the run is seen running"
    );
    sweep.kill().expect("SIGKILL the sweep");
    sweep.wait().expect("reap the sweep");
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let left = processes_with(path(&run));
        if left.is_empty() {
            break;
        }
        assert!(Instant::now() < deadline, "orphaned runs: {left:?}");
        std::thread::sleep(Duration::from_millis(100));
    }
    // it stopped as a signalled run does, its checkpoint whole
    assert!(run.join("checkpoints/latest").is_dir());
    ok(&["eval", "--run", path(&run), "--episodes", "1"]);
}

#[test]
fn the_two_signals_of_gnu_timeout_count_as_one_and_the_run_checkpoints() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    // timeout sends SIGTERM to apo and then to apo's process group: two at once
    let out = Command::new("timeout")
        .args([
            "--preserve-status",
            "-s",
            "TERM",
            "8",
            env!("CARGO_BIN_EXE_apo"),
        ])
        .args([
            "train",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--epochs",
            "100000",
            "--steps-per-epoch",
            "200",
            "--quiet",
            "--out",
            path(&run),
        ])
        .output()
        .expect("timeout runs (coreutils)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(143), "{stdout}");
    assert!(stdout.contains("checkpoint written"), "{stdout}");
    // nothing of the stop is left behind
    let temps: Vec<String> = std::fs::read_dir(&run)
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(temps.is_empty(), "{temps:?}");
}
