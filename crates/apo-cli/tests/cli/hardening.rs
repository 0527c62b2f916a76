//! Nothing lost, nothing panics: `--force`, resume consistency, checkpoint verification,
//! locks, sizes, non-finite updates, signals.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use super::{apo, fails, ok, path, small, timeless};

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_apo"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn apo")
}

/// A 500-epoch PPO run on CartPole in `dir`, to be stopped by the test.
fn long_run(dir: &Path) -> Child {
    spawn(&[
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
        path(dir),
    ])
}

fn wait_for(file: &Path) {
    let deadline = Instant::now() + Duration::from_secs(300);
    while !file.exists() {
        assert!(
            Instant::now() < deadline,
            "{} did not appear in time",
            file.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn signal(child: &Child, name: &str) {
    let status = Command::new("kill")
        .args([&format!("-{name}"), &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
}

/// Waits for `child` at most `secs` seconds; kills it and fails when it takes longer.
fn finish(mut child: Child, secs: u64) -> (Option<i32>, String, String) {
    let deadline = Instant::now() + Duration::from_secs(secs);
    loop {
        if child.try_wait().expect("try_wait").is_some() {
            let out = child.wait_with_output().expect("output");
            return (
                out.status.code(),
                String::from_utf8_lossy(&out.stdout).into_owned(),
                String::from_utf8_lossy(&out.stderr).into_owned(),
            );
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("apo did not exit within {secs} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn force_replaces_only_run_directories_and_keeps_foreign_files() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let notes = tmp.path().join("notes");
    std::fs::create_dir(&notes).expect("mkdir");
    std::fs::write(notes.join("thesis.txt"), "years of work").expect("write");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--out",
        path(&notes),
        "--force",
        "--quiet",
    ]);
    assert!(
        err.contains("not one") && err.contains("nothing in it was touched"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(notes.join("thesis.txt")).expect("kept"),
        "years of work"
    );

    let run = tmp.path().join("run");
    small(&run, &[]);
    std::fs::write(run.join("curves.png"), "a plot the user made").expect("write");
    let out = apo(&[
        "train",
        "--algo",
        "a2c",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--quiet",
        "--out",
        path(&run),
        "--force",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("kept what apo did not create"));
    assert_eq!(
        std::fs::read_to_string(run.join("curves.png")).expect("kept"),
        "a plot the user made"
    );
    assert!(std::fs::read_to_string(run.join("config.toml"))
        .expect("config")
        .contains("[algo.a2c]"));
}

#[test]
fn resume_with_epochs_records_the_new_target() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    ok(&["train", "--resume", path(&run), "--epochs", "2", "--quiet"]);
    let config = std::fs::read_to_string(run.join("config.toml")).expect("config");
    assert!(config.contains("epochs = 2"), "{config}");
    assert_eq!(timeless(&run).len(), 2);
    let err = fails(&["train", "--resume", path(&run), "--epochs", "1", "--quiet"]);
    assert!(err.contains("more than epochs = 1"), "{err}");
}

#[test]
fn resume_refuses_when_progress_and_checkpoint_disagree() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let mut args = vec![
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "2",
        "--steps-per-epoch",
        "200",
    ];
    args.extend(["--quiet", "--out", path(&run)]);
    ok(&args);
    let progress = run.join("progress.csv");
    let saved = std::fs::read(&progress).expect("progress");
    let header = String::from_utf8_lossy(&saved)
        .lines()
        .next()
        .expect("header")
        .to_string()
        + "\n";
    for (case, content) in [
        ("missing", None),
        ("empty", Some(String::new())),
        ("header only", Some(header)),
    ] {
        match &content {
            None => std::fs::remove_file(&progress).expect("rm"),
            Some(text) => std::fs::write(&progress, text).expect("write"),
        }
        let err = fails(&["train", "--resume", path(&run), "--epochs", "3", "--quiet"]);
        assert!(
            err.contains("rows of epochs 1..=2 are missing"),
            "{case}: {err}"
        );
        assert!(
            !err.contains("--force"),
            "{case}: must not advise --force: {err}"
        );
        std::fs::write(&progress, &saved).expect("restore");
    }
    std::fs::remove_file(run.join("checkpoints/latest/state.json")).expect("rm state");
    let err = fails(&["train", "--resume", path(&run), "--epochs", "3", "--quiet"]);
    assert!(!err.contains("--force"), "must not advise --force: {err}");
    assert!(err.contains("state.json"), "{err}");
    assert_eq!(std::fs::read(&progress).expect("progress kept"), saved);
}

#[test]
fn damaged_or_foreign_checkpoint_files_are_named() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &["--set", "normalize_obs=true"]);
    let other = tmp.path().join("other");
    small(
        &other,
        &["--set", "hidden=[32]", "--set", "normalize_obs=true"],
    );
    let latest = run.join("checkpoints/latest");
    for file in ["policy.mpk", "value.mpk", "value_optim.mpk", "state.json"] {
        let original = std::fs::read(latest.join(file)).expect("read");
        // a file of another run's networks (another shape)
        std::fs::copy(
            other.join("checkpoints/latest").join(file),
            latest.join(file),
        )
        .expect("copy");
        for args in [
            vec!["train", "--resume", path(&run), "--epochs", "2", "--quiet"],
            vec!["eval", "--run", path(&run)],
        ] {
            let err = fails(&args);
            assert!(err.contains(&format!("{file} is corrupt")), "{file}: {err}");
        }
        // one flipped byte
        let mut flipped = original.clone();
        let middle = flipped.len() / 2;
        flipped[middle] ^= 0x40;
        std::fs::write(latest.join(file), &flipped).expect("write");
        let err = fails(&["eval", "--run", path(&run)]);
        assert!(err.contains(&format!("{file} is corrupt")), "{file}: {err}");
        std::fs::write(latest.join(file), &original).expect("restore");
    }
    // a whole checkpoint of other shapes, or config.toml edited under a checkpoint
    let config = std::fs::read_to_string(run.join("config.toml")).expect("config");
    std::fs::write(
        run.join("config.toml"),
        config.replace("hidden = [\n    64,\n    64,\n]", "hidden = [32]"),
    )
    .expect("edit");
    let err = fails(&["eval", "--run", path(&run)]);
    assert!(
        err.contains("do not fit this run") && err.contains("hidden [64, 64]"),
        "{err}"
    );
    std::fs::write(run.join("config.toml"), &config).expect("restore");
    ok(&["eval", "--run", path(&run), "--episodes", "1"]);
}

#[test]
fn a_second_training_on_a_run_directory_is_refused() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let child = long_run(&run);
    wait_for(&run.join("progress.csv"));
    let err = fails(&["train", "--resume", path(&run), "--quiet"]);
    assert!(err.contains("in use by another apo process"), "{err}");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--out",
        path(&run),
        "--force",
        "--quiet",
    ]);
    assert!(err.contains("in use by another apo process"), "{err}");
    signal(&child, "INT");
    let (code, _, stderr) = finish(child, 120);
    assert_eq!(code, Some(130), "{stderr}");
}

#[test]
fn sizes_are_checked_before_anything_is_created() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let o = path(&run);
    for (flags, culprit) in [
        (
            vec!["--steps-per-epoch", "1000000000000"],
            "--steps-per-epoch",
        ),
        (
            vec!["--set", "steps_per_epoch=1000000000000"],
            "steps_per_epoch",
        ),
        (vec!["--set", "hidden=[1000000000]"], "hidden"),
        (vec!["--set", "hidden=[1000000, 1000000]"], "GiB of memory"),
        (vec!["--num-envs", "1000000000000"], "1..=65536"),
        (
            vec!["--set", "num_envs=1000000000000"],
            "`num_envs` = 1000000000000",
        ),
        (vec!["--set", "init_log_std=1e30"], "init_log_std"),
    ] {
        let mut args = vec![
            "train",
            "--algo",
            "apo",
            "--env",
            "CartPole-v1",
            "--quiet",
            "--out",
            o,
        ];
        args.extend(flags.iter().copied());
        let err = fails(&args);
        assert!(err.contains(culprit), "{flags:?}: {err}");
        assert!(
            !run.exists(),
            "{flags:?}: a run that fails before its first epoch leaves no directory behind"
        );
    }
    let err = fails(&[
        "train",
        "--algo",
        "apo",
        "--env",
        "CartPole-v1",
        "--seed",
        "9223372036854775808",
        "--out",
        o,
    ]);
    assert!(err.contains("0..=9223372036854775807"), "{err}");
    for args in [
        vec!["bench", "update", "--obs", "0"],
        vec!["bench", "update", "--act", "0"],
        vec!["bench", "update", "--batch", "0"],
        vec!["bench", "policy", "--obs", "0"],
        vec!["bench", "policy", "--batch", "0"],
        vec!["bench", "env", "--env", "CartPole-v1", "--steps", "0"],
    ] {
        let out = apo(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("is not in 1.."), "{args:?}: {err}");
    }
    let err = fails(&["bench", "update", "--batch", "10000000", "--obs", "100000"]);
    assert!(err.contains("GiB of memory"), "{err}");
}

#[test]
fn a_diverging_update_stops_the_run_with_an_error_and_keeps_the_last_good_checkpoint() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let train = |extra: &[&str]| {
        let mut args = vec![
            "train",
            "--algo",
            "a2c",
            "--env",
            "Pendulum-v1",
            "--epochs",
            "1",
            "--steps-per-epoch",
            "400",
        ];
        args.extend(["--quiet", "--out", path(&run)]);
        args.extend_from_slice(extra);
        apo(&args)
    };
    // diverging in the first epoch: an error, exit 1, and no run directory left behind
    // a policy learning rate of 1e30 sends the log-std to ~1e30, and the KL after the update to NaN
    let out = train(&["--set", "algo.policy_update.lr=1e30"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(1),
        "a diverged run must not exit 0: {err}"
    );
    assert!(
        err.contains("epoch 1: the update produced")
            && err.contains("non-finite")
            && err.contains("nothing was saved"),
        "{err}"
    );
    // the error describes the epoch's batch, where a non-finite update would come from
    assert!(
        err.contains("the epoch's batch: 400 transitions, max |obs| ") && err.contains("adv_scale"),
        "{err}"
    );
    assert!(!String::from_utf8_lossy(&out.stdout).contains("run finished"));
    assert!(!run.exists());

    // diverging later: the rows and the checkpoint of the good epochs stay (a policy learning
    // rate of 1e3 keeps epoch 1 finite and sends epoch 2's update to NaN; a run's learning
    // rate cannot be edited under its checkpoint, bound_config.rs)
    let out = apo(&[
        "train",
        "--algo",
        "a2c",
        "--env",
        "Pendulum-v1",
        "--epochs",
        "3",
        "--steps-per-epoch",
        "400",
        "--set",
        "algo.policy_update.lr=1e3",
        "--quiet",
        "--out",
        path(&run),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("epoch 2: the update produced") && err.contains("non-finite"),
        "{err}"
    );
    assert!(err.contains("last good checkpoint (epoch 1)"), "{err}");
    // the settings that scale the update are named with their values
    assert!(err.contains("algo.a2c.policy_update.lr = 1000"), "{err}");
    assert_eq!(timeless(&run).len(), 1);
    let state = std::fs::read_to_string(run.join("checkpoints/latest/state.json"))
        .expect("last good checkpoint");
    assert!(state.contains("\"epoch\": 1"), "{state}");
}

#[test]
fn sigterm_checkpoints_and_exits_143_with_the_resume_command() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let child = long_run(&run);
    wait_for(&run.join("progress.csv"));
    signal(&child, "TERM");
    let (code, stdout, stderr) = finish(child, 120);
    assert_eq!(code, Some(143), "{stdout}{stderr}");
    assert!(
        stdout.contains("interrupted by SIGTERM")
            && stdout.contains(&format!("apo train --resume {}", path(&run))),
        "{stdout}"
    );
    let done = timeless(&run).len();
    let state =
        std::fs::read_to_string(run.join("checkpoints/latest/state.json")).expect("checkpoint");
    assert!(state.contains(&format!("\"epoch\": {done}")), "{state}");
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
fn checkpoint_files_and_directories_are_synced_before_and_after_the_swap() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let trace = tmp.path().join("trace.txt");
    let status = Command::new("strace")
        .args([
            "-f",
            "-y",
            "-e",
            "trace=fsync,rename",
            "-o",
            path(&trace),
            env!("CARGO_BIN_EXE_apo"),
        ])
        .args([
            "train",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--epochs",
            "1",
            "--steps-per-epoch",
            "200",
            "--quiet",
        ])
        .args(["--out", path(&run)])
        .stdout(Stdio::null())
        .status()
        .expect("strace runs (Debian package strace, installed by scripts/setup.sh)");
    assert!(status.success());
    let calls: Vec<String> = std::fs::read_to_string(&trace)
        .expect("trace")
        .lines()
        .map(str::to_string)
        .collect();
    let first = |call: &str, arg: &str| {
        calls
            .iter()
            .position(|l| l.contains(&format!(" {call}(")) && l.contains(arg))
            .unwrap_or_else(|| panic!("no {call} of `{arg}` in the trace:\n{}", calls.join("\n")))
    };
    let checkpoints = format!("{}/checkpoints", path(&run));
    let swap = first(
        "rename",
        &format!("\"{checkpoints}/.tmp-1\", \"{checkpoints}/latest\""),
    );
    for file in [
        "policy.mpk>",
        "value.mpk>",
        "policy_optim.mpk>",
        "value_optim.mpk>",
        "state.json>",
        // the manifest is written atomically: its temporary file (of a unique name) is synced
        ".manifest.json.apo-",
    ] {
        assert!(
            first("fsync", &format!("<{checkpoints}/.tmp-1/{file}")) < swap,
            "{file} is synced before the swap"
        );
    }
    assert!(
        first("fsync", &format!("<{checkpoints}/.tmp-1>")) < swap,
        "the new checkpoint's directory is synced before the swap"
    );
    let parent = format!("<{checkpoints}>)");
    assert!(
        calls[swap..]
            .iter()
            .any(|l| l.contains(" fsync(") && l.contains(&parent)),
        "checkpoints/ is synced after the swap"
    );
    // progress.csv's temporary file (`.progress.csv.apo-<pid>-<n>.tmp`) is synced before its rename
    let progress = format!("{}/.progress.csv.apo-", path(&run));
    assert!(first("fsync", &format!("<{progress}")) < first("rename", &format!("\"{progress}")));
}
