//! Rule: a run's record is whole. A checkpoint is verified before it is read (manifest,
//! sizes, CRCs, finite parameters), written synced and swapped atomically, agrees with
//! `progress.csv` on resume, and a run directory is trained by one process at a time.

use super::*;

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

/// The episode record is part of a run's record: resuming refuses an `episodes.csv` that lost
/// records the checkpoint counted (deleted, emptied, cut), keeping every file.
#[test]
fn resume_refuses_an_episode_record_that_lost_what_the_checkpoint_counted() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    train(&run, "ppo", &[]);
    let episodes = run.join("episodes.csv");
    let saved = std::fs::read_to_string(&episodes).expect("episodes.csv");
    let cut: String = saved.lines().take(3).map(|l| format!("{l}\n")).collect();
    let doubled = format!("{saved}{}\n", saved.lines().nth(1).expect("a record"));
    for (case, content, says) in [
        ("deleted", None, "counted"),
        ("emptied", Some(String::new()), "counted"),
        ("cut", Some(cut), "counted"),
        (
            "a record repeated",
            Some(doubled),
            "repeats the record of line 2",
        ),
    ] {
        match &content {
            None => std::fs::remove_file(&episodes).expect("rm"),
            Some(text) => std::fs::write(&episodes, text).expect("write"),
        }
        let err = fails(&["train", "--resume", path(&run), "--epochs", "4", "--quiet"]);
        assert!(
            err.contains("episodes.csv") && err.contains(says),
            "{case}: {err}"
        );
        assert_eq!(timeless(&run).len(), 3, "{case}: progress.csv kept");
        std::fs::write(&episodes, &saved).expect("restore");
    }
    ok(&["train", "--resume", path(&run), "--epochs", "4", "--quiet"]);
}

/// A refused resume writes nothing: a new `--epochs` target below the epochs done, or with a
/// damaged checkpoint, leaves `config.toml` as it was, and a plain resume still works.
#[test]
fn a_refused_resume_leaves_the_runs_target_as_it_was() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    train(&run, "ppo", &[]);
    let config = run.join("config.toml");
    let before = std::fs::read(&config).expect("config.toml");
    let err = fails(&["train", "--resume", path(&run), "--epochs", "1", "--quiet"]);
    assert!(err.contains("more than epochs = 1"), "{err}");
    assert_eq!(
        std::fs::read(&config).expect("kept"),
        before,
        "target below the epochs done"
    );
    let policy = run.join("checkpoints/latest/policy.mpk");
    let saved = std::fs::read(&policy).expect("policy");
    std::fs::write(&policy, "corrupt").expect("damage");
    let err = fails(&["train", "--resume", path(&run), "--epochs", "50", "--quiet"]);
    assert!(err.contains("policy.mpk"), "{err}");
    assert_eq!(
        std::fs::read(&config).expect("kept"),
        before,
        "damaged checkpoint"
    );
    std::fs::write(&policy, saved).expect("repair");
    // a run without apo's marker (written before it existed), refused for an edited config,
    // gains no marker
    let marker = run.join(".apo-run");
    let kept_marker = std::fs::read(&marker).expect("marker");
    std::fs::remove_file(&marker).expect("rm marker");
    let text = String::from_utf8_lossy(&before).replace("seed = 7", "seed = 8");
    std::fs::write(&config, text).expect("edit");
    let err = fails(&["train", "--resume", path(&run), "--quiet"]);
    assert!(err.contains("seed"), "{err}");
    assert!(!marker.exists(), "a refused resume wrote the marker");
    std::fs::write(&config, &before).expect("restore");
    std::fs::write(&marker, kept_marker).expect("restore marker");
    ok(&["train", "--resume", path(&run), "--epochs", "4", "--quiet"]);
    assert_eq!(timeless(&run).len(), 4);
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
    let text = String::from_utf8_lossy(&saved).to_string();
    let without_first: String = text
        .lines()
        .enumerate()
        .filter(|(i, _)| *i != 1)
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    for (case, content, missing) in [
        ("missing", None, "1..=2"),
        ("empty", Some(String::new()), "1..=2"),
        ("header only", Some(header), "1..=2"),
        ("first row deleted", Some(without_first), "1 "),
    ] {
        match &content {
            None => std::fs::remove_file(&progress).expect("rm"),
            Some(text) => std::fs::write(&progress, text).expect("write"),
        }
        let err = fails(&["train", "--resume", path(&run), "--epochs", "3", "--quiet"]);
        assert!(
            err.contains(&format!("rows of epoch(s) {missing}")) && err.contains("are missing"),
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
        err.contains("hidden = [32] (trained with: [64, 64])"),
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
fn checkpoint_files_and_directories_are_synced_before_and_after_the_swap() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let trace = tmp.path().join("trace.txt");
    let status = Command::new("strace")
        .args([
            "-f",
            "-y",
            "-e",
            "trace=fsync,rename,renameat2",
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
    // progress.csv's temporary file (`.progress.csv.apo-<pid>-<n>.tmp`) is synced before it
    // takes its place (`renameat2`, which replaces nothing it may not: `atomic::place`)
    let progress = format!("{}/.progress.csv.apo-", path(&run));
    assert!(first("fsync", &format!("<{progress}")) < first("renameat2", &format!("\"{progress}")));
}

#[test]
fn a_run_killed_between_its_last_row_and_its_last_checkpoint_is_resumed_not_skipped() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let first = sweep(&out, "2", &["--set", "keep_checkpoint_every=1"]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let run = out.join("CartPole-v1-ppo-s0");
    let whole = super::timeless(&run);
    // the checkpoint of epoch 1 in place of the last one: progress.csv is one row ahead
    let latest = run.join("checkpoints/latest");
    for e in std::fs::read_dir(&latest).expect("ls").flatten() {
        std::fs::remove_file(e.path()).expect("rm");
    }
    for e in std::fs::read_dir(run.join("checkpoints/epoch-000001"))
        .expect("ls")
        .flatten()
    {
        std::fs::copy(e.path(), latest.join(e.file_name())).expect("cp");
    }
    let again = sweep(&out, "2", &["--set", "keep_checkpoint_every=1"]);
    let stdout = text(&again.stdout);
    assert!(again.status.success(), "{}", text(&again.stderr));
    assert!(stdout.contains("finished 1 (skipped 0"), "{stdout}");
    assert_eq!(
        super::timeless(&run),
        whole,
        "the repaired run equals the uninterrupted one"
    );
}

#[test]
fn a_checkpoint_without_its_manifest_or_of_another_manifest_format_is_refused() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    let manifest = run.join("checkpoints/latest/manifest.json");
    let original = std::fs::read_to_string(&manifest).expect("read");
    std::fs::remove_file(&manifest).expect("rm");
    let err = fails(&["eval", "--run", path(&run)]);
    assert!(err.contains("manifest.json is missing"), "{err}");
    std::fs::write(
        &manifest,
        original.replacen("\"format\": 2", "\"format\": 99", 1),
    )
    .expect("write");
    let err = fails(&["eval", "--run", path(&run)]);
    assert!(err.contains("manifest format 99"), "{err}");
    std::fs::write(&manifest, &original).expect("restore");
    ok(&["eval", "--run", path(&run), "--episodes", "1"]);
}

#[test]
fn a_checkpoint_with_non_finite_parameters_is_refused() {
    use apo_core::{ActionKind, Learner};
    use apo_train::checkpoint::{self, Which};
    use apo_train::run_config::RunConfig;
    use burn::backend::NdArray;
    use burn::module::Module;
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    // the run's checkpoint, loaded and written back with one NaN in the policy (as a
    // corrupted or foreign writer could leave it; apo's own training never saves one)
    let config = RunConfig::load(&run.join("config.toml")).expect("config");
    let action = ActionKind::Discrete { n: 2 };
    let device = Default::default();
    let mut learner = Learner::<NdArray, _>::new(
        config.train.mlp_policy(4, action),
        action,
        &config.train.value(4),
        config.train.algo.clone(),
        &device,
        0,
    )
    .expect("learner");
    let shapes = apo_train::checkpoint::Shapes::of(&config, 4, action);
    let from = checkpoint::locate(&run, &Which::Latest)
        .expect("locate")
        .expect("latest");
    let state = checkpoint::load(&from, &mut learner, &shapes, &device).expect("load");
    let (policy, value) = learner.networks();
    let (policy_optim, value_optim) = learner.optimizers();
    let mut theta = learner.policy_params();
    theta[0] = f64::NAN;
    let theta = burn::tensor::Tensor::from_floats(
        theta
            .iter()
            .map(|&v| v as f32)
            .collect::<Vec<_>>()
            .as_slice(),
        &device,
    );
    let poisoned = apo_core::flat::unflatten(policy.clone(), theta);
    assert_eq!(poisoned.num_params(), policy.num_params());
    let (value, policy_optim, value_optim) =
        (value.clone(), policy_optim.clone(), value_optim.clone());
    learner.restore(poisoned, value, policy_optim, value_optim);
    checkpoint::save(&run, &learner, &state, &shapes, false).expect("save");
    for args in [
        vec!["eval", "--run", path(&run)],
        vec!["train", "--resume", path(&run), "--epochs", "2", "--quiet"],
    ] {
        let err = fails(&args);
        assert!(
            err.contains("non-finite policy parameter") && err.contains("policy.mpk"),
            "{args:?}: {err}"
        );
    }
    assert_eq!(
        super::timeless(&run).len(),
        1,
        "the refused resume wrote nothing"
    );
}
