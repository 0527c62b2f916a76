//! Hardening II: the experiment tools lose nothing, count before they allocate, pass signals
//! on, refuse what they would silently get wrong, and name what is wrong. Every test drives
//! the real binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::{apo, fails, ok, path, small};

/// Plants `text` at `dir/rel` (folders created).
fn plant(dir: &Path, rel: &str, text: &str) -> PathBuf {
    let file = dir.join(rel);
    std::fs::create_dir_all(file.parent().expect("parent")).expect("mkdir");
    std::fs::write(&file, text).expect("plant");
    file
}

/// Every file under `dir` whose content is `text`.
fn find_content(dir: &Path, text: &str) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if std::fs::read_to_string(&p).is_ok_and(|t| t == text) {
                found.push(p);
            }
        }
    }
    found
}

/// A sweep of one PPO CartPole run per seed, `epochs` epochs of 200 steps, in `out`.
fn sweep(out: &Path, epochs: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--seeds",
        "0",
        "--epochs",
        epochs,
        "--steps-per-epoch",
        "200",
        "--quiet",
        "--out",
        path(out),
    ];
    args.extend_from_slice(extra);
    apo(&args)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn force_removes_only_the_files_apo_created_and_never_a_folder_with_user_files() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &["--set", "keep_checkpoint_every=1"]);
    let planted = [
        ("notes.txt", "notes of the user"),
        ("checkpoints/mybest/model.pt", "the user's best model"),
        (
            "checkpoints/latest/mine.txt",
            "a file the user put into latest",
        ),
        (
            "checkpoints/epoch-000001/why.txt",
            "a note inside a kept checkpoint",
        ),
    ];
    for (rel, content) in planted {
        plant(&run, rel, content);
    }
    small(&run, &["--force", "--set", "keep_checkpoint_every=1"]);
    for (rel, content) in planted {
        assert_eq!(
            find_content(&run, content).len(),
            1,
            "{rel} was lost by --force"
        );
    }
    assert_eq!(
        std::fs::read_to_string(run.join("checkpoints/mybest/model.pt")).expect("kept"),
        "the user's best model"
    );
    // the run itself was replaced and is whole
    ok(&["eval", "--run", path(&run), "--episodes", "1"]);
    let marker = std::fs::read_to_string(run.join(".apo-run")).expect("marker");
    for entry in [
        "config.toml",
        "progress.csv",
        "episodes.csv",
        "train.log",
        "checkpoints",
        "apo.lock",
    ] {
        assert!(
            marker.lines().any(|l| l == entry),
            "{entry} not in {marker}"
        );
    }
    assert!(!marker.contains("notes.txt"), "{marker}");
}

#[test]
fn a_folder_that_merely_holds_a_config_is_not_a_run_directory() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let proj = tmp.path().join("proj");
    std::fs::create_dir(&proj).expect("mkdir");
    let config = ok(&["config", "--algo", "ppo", "--env", "CartPole-v1"]);
    std::fs::write(proj.join("config.toml"), &config).expect("write");
    plant(&proj, "train.log", "the user's own log");
    plant(
        &proj,
        "checkpoints/resnet/model.pt",
        "weights of another project",
    );
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--out",
        path(&proj),
        "--force",
        "--quiet",
    ]);
    assert!(
        err.contains("nothing in it was touched") && err.contains(".apo-run"),
        "{err}"
    );
    let err = fails(&["train", "--resume", path(&proj), "--quiet"]);
    assert!(err.contains("not a run directory of apo"), "{err}");
    assert_eq!(
        std::fs::read_to_string(proj.join("train.log")).expect("kept"),
        "the user's own log"
    );
    assert!(proj.join("checkpoints/resnet/model.pt").exists());
    assert_eq!(
        std::fs::read_to_string(proj.join("config.toml")).expect("kept"),
        config
    );
    assert!(!proj.join(".apo-run").exists() && !proj.join("progress.csv").exists());
    // a run directory where a file of apo's names was put by someone else: --force refuses
    let run = tmp.path().join("run");
    small(&run, &[]);
    let marker = run.join(".apo-run");
    let listed = std::fs::read_to_string(&marker).expect("marker");
    std::fs::write(&marker, listed.replace("train.log\n", "")).expect("edit");
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
    assert!(
        err.contains("train.log") && err.contains("did not create"),
        "{err}"
    );
    assert!(run.join("progress.csv").exists(), "nothing may be touched");
}

#[test]
fn a_run_that_fails_before_its_first_epoch_leaves_only_what_was_there() {
    let tmp = tempfile::tempdir().expect("tempdir");
    // an empty folder the user made, then a run that fails at its first update
    let dir = tmp.path().join("empty");
    std::fs::create_dir(&dir).expect("mkdir");
    let err = fails(&[
        "train",
        "--algo",
        "a2c",
        "--env",
        "Pendulum-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "400",
        "--set",
        "algo.policy_update.lr=1e30",
        "--quiet",
        "--out",
        path(&dir),
    ]);
    assert!(err.contains("non-finite"), "{err}");
    assert!(dir.is_dir(), "a folder apo did not create stays");
    assert_eq!(
        std::fs::read_dir(&dir).expect("ls").count(),
        0,
        "nothing of apo's is left"
    );
}

#[test]
fn a_finished_sweep_run_with_an_unparsable_cell_is_reported_and_left_alone() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let first = sweep(&out, "2", &[]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let run = out.join("CartPole-v1-ppo-s0");
    let progress = run.join("progress.csv");
    let csv = std::fs::read_to_string(&progress).expect("progress");
    let mut lines: Vec<String> = csv.lines().map(str::to_string).collect();
    lines[1] = lines[1].replacen(",", ",not-a-number", 2);
    std::fs::write(&progress, lines.join("\n") + "\n").expect("corrupt");
    let damaged = std::fs::read_to_string(&progress).expect("read");
    plant(&run, "checkpoints/mybest/best.pt", "keep me");
    let again = sweep(&out, "2", &[]);
    let (stdout, stderr) = (text(&again.stdout), text(&again.stderr));
    assert!(again.status.success(), "{stderr}");
    assert!(stdout.contains("skipped 1 finished before"), "{stdout}");
    assert!(
        stderr.contains("progress.csv") && stderr.contains("left out") && stderr.contains("line 2"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(&progress).expect("read"),
        damaged,
        "untouched"
    );
    assert_eq!(
        std::fs::read_to_string(run.join("checkpoints/mybest/best.pt")).expect("kept"),
        "keep me"
    );
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
fn sweeps_are_counted_before_anything_is_allocated() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("s");
    let started = Instant::now();
    for seeds in ["0..9223372036854775807", "0..1000000000", "0..10001"] {
        let result = apo(&[
            "sweep",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--seeds",
            seeds,
            "--out",
            path(&out),
        ]);
        let err = text(&result.stderr);
        assert_eq!(result.status.code(), Some(1), "{seeds}: {err}");
        assert!(err.contains("--max-runs"), "{seeds}: {err}");
    }
    let values: Vec<String> = (0..1000)
        .map(|i| format!("{}", 0.001 * (i + 1) as f64))
        .collect();
    let (k, w) = (
        format!("algo.k={}", values.join(",")),
        format!("algo.omega1={}", values.join(",")),
    );
    let err = fails(&[
        "sweep",
        "--algo",
        "apo",
        "--env",
        "Pendulum-v1",
        "--grid",
        &k,
        "--grid",
        &w,
        "--out",
        path(&out),
    ]);
    assert!(
        err.contains("3000000 runs") || err.contains("1000000"),
        "{err}"
    );
    assert!(
        started.elapsed() < Duration::from_secs(60),
        "{:?}",
        started.elapsed()
    );
    assert!(!out.exists(), "nothing is created");
    // an explicit limit
    let err = fails(&[
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--seeds",
        "0..3",
        "--max-runs",
        "2",
        "--out",
        path(&out),
    ]);
    assert!(
        err.contains("more than the 2") && err.contains("--max-runs"),
        "{err}"
    );
}

#[test]
fn sweeps_refuse_what_they_would_get_wrong() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("s");
    let base = [
        "sweep",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--out",
        path(&out),
    ];
    let cases: [(&[&str], &str); 9] = [
        (&["--algo", "ppo", "--grid", "seed=1,2"], "use --seeds"),
        (&["--algo", "ppo", "--grid", "epochs=1,2"], "use --epochs"),
        (
            &["--algo", "ppo", "--grid", "steps_per_epoch=200,400"],
            "use --steps-per-epoch",
        ),
        (&["--algo", "ppo", "--set", "env=Pendulum-v1"], "use --env"),
        (
            &["--algo", "ppo", "--seeds", "0,1,0"],
            "seed 0 is listed twice",
        ),
        (&["--algo", "ppo,ppo"], "are the same"),
        (&["--algo", "apo", "--grid", "algo.k=1,1.0"], "given twice"),
        (
            &["--algo", "apo", "--grid", "algo.k=1", "--grid", "algo.k=2"],
            "given twice",
        ),
        (
            &["--algo", "ppo", "--epochs", "18446744073709551615"],
            "epochs",
        ),
    ];
    for (extra, expected) in cases {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        let err = fails(&args);
        assert!(err.contains(expected), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?} created the sweep folder");
    }
    let err = fails(&[
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "Hopper,Hopper-v4",
        "--out",
        path(&out),
    ]);
    assert!(err.contains("are the same"), "{err}");
    // a config file with one algorithm's section and a sweep of two: said before anything runs
    let config = tmp.path().join("apo.toml");
    std::fs::write(&config, ok(&["config", "--algo", "apo"])).expect("write");
    let err = fails(&[
        "sweep",
        "--algo",
        "apo,trpo",
        "--env",
        "CartPole-v1",
        "--config",
        path(&config),
        "--out",
        path(&out),
    ]);
    assert!(err.contains("[algo.apo]") && err.contains("trpo"), "{err}");
    // the sweep's --out is a file: named
    let file = tmp.path().join("file");
    std::fs::write(&file, "").expect("write");
    let err = fails(&[
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--seeds",
        "0",
        "--epochs",
        "1",
        "--out",
        path(&file),
    ]);
    assert!(
        err.contains(path(&file)) && err.contains("not a directory"),
        "{err}"
    );
    assert_eq!(
        err.matches("not a directory").count(),
        1,
        "said once: {err}"
    );
}

#[test]
fn grid_values_can_be_lists() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("s");
    let result = sweep(&out, "1", &["--grid", "hidden=[32,32],[16]"]);
    assert!(result.status.success(), "{}", text(&result.stderr));
    assert!(text(&result.stdout).contains("sweep: 2 runs"));
    for (name, hidden) in [
        ("CartPole-v1-ppo-hidden=[32,32]-s0", "[32, 32]"),
        ("CartPole-v1-ppo-hidden=[16]-s0", "[16]"),
    ] {
        let config = ok(&["config", "--run", path(&out.join(name))]);
        let compact: String = config.split_whitespace().collect();
        assert!(
            compact.contains(&format!("hidden={}", hidden.replace(' ', ""))),
            "{name}: {config}"
        );
    }
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
    apo_cli::run_dir::RunLock::acquire(&run).expect("the run's lock is free: no orphan");
    let epoch = apo_cli::checkpoint::latest_epoch(&run)
        .expect("read")
        .expect("a checkpoint");
    assert!(epoch < 500, "the run stopped early (epoch {epoch})");
    let rows = super::timeless(&run);
    assert_eq!(rows.len(), epoch, "progress.csv agrees with the checkpoint");
}

#[test]
fn report_and_summary_count_each_run_once_and_leave_out_bad_rows() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let runs = tmp.path().join("runs");
    for seed in ["0", "1"] {
        let dir = runs.join(format!("CartPole-v1-ppo-s{seed}"));
        ok(&[
            "train",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--epochs",
            "2",
            "--steps-per-epoch",
            "200",
            "--seed",
            seed,
            "--quiet",
            "--out",
            path(&dir),
        ]);
    }
    let one = runs.join("CartPole-v1-ppo-s0");
    let report = ok(&["report", path(&runs), path(&one), "--random-episodes", "1"]);
    assert!(report.contains("| ppo | 2 |"), "{report}");
    // a report folder: apo rewrites its own report, never a user's file of the same name
    let folder = tmp.path().join("folder");
    ok(&[
        "report",
        path(&runs),
        "--random-episodes",
        "1",
        "--out",
        path(&folder),
    ]);
    ok(&[
        "report",
        path(&runs),
        "--random-episodes",
        "1",
        "--out",
        path(&folder),
    ]);
    let mine = tmp.path().join("mine");
    plant(&mine, "report.md", "my own report");
    let err = fails(&[
        "report",
        path(&runs),
        "--random-episodes",
        "1",
        "--out",
        path(&mine),
    ]);
    assert!(
        err.contains("report.md") && err.contains("not written by apo"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(mine.join("report.md")).expect("kept"),
        "my own report"
    );
    // a non-finite and a duplicated epoch row: left out with a warning, never a NaN in a table
    let progress = one.join("progress.csv");
    let csv = std::fs::read_to_string(&progress).expect("read");
    let lines: Vec<&str> = csv.lines().collect();
    let nan_row = {
        let header: Vec<&str> = lines[0].split(',').collect();
        let col = header
            .iter()
            .position(|h| *h == "ep_ret_mean")
            .expect("column");
        let mut cells: Vec<String> = lines[2].split(',').map(str::to_string).collect();
        cells[col] = "inf".to_string();
        cells.join(",")
    };
    let edited = format!("{}\n{}\n{}\n{}\n", lines[0], lines[1], lines[1], nan_row);
    std::fs::write(&progress, edited).expect("write");
    let out = apo(&["summary", path(&one), "--csv"]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("2 row(s) left out")
            && stderr.contains("repeated")
            && stderr.contains("inf"),
        "{stderr}"
    );
    assert!(
        !stdout.contains("NaN") && !stdout.contains(",inf"),
        "{stdout}"
    );
    let report = ok(&["report", path(&runs), "--random-episodes", "1"]);
    assert!(
        !report.contains("NaN") && !report.contains("inf ±"),
        "{report}"
    );
    assert!(report.contains("(1 incomplete)"), "{report}");
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
fn memory_is_checked_before_anything_is_created() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let err = fails(&[
        "bench", "policy", "--obs", "100000", "--act", "10000", "--batch", "100000",
    ]);
    assert!(
        err.contains("GiB of memory") && err.contains("--batch"),
        "{err}"
    );
    let dir = tmp.path().join("humanoids");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "Humanoid",
        "--num-envs",
        "65536",
        "--steps-per-epoch",
        "65536",
        "--quiet",
        "--out",
        path(&dir),
    ]);
    assert!(err.contains("GiB of memory"), "{err}");
    assert!(!dir.exists(), "no directory is left behind");
}

#[test]
fn errors_name_the_culprit_and_are_said_once() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let err = fails(&[
        "train",
        "--algo",
        "apo",
        "--env",
        "CartPole-v1",
        "--set",
        "algo.k=inf",
        "--out",
        path(&tmp.path().join("r")),
    ]);
    assert!(err.contains("must be finite"), "{err}");
    // a config file with two algorithms' sections
    let two = tmp.path().join("two.toml");
    let both = "[algo.apo]\nk = 5.0\n\n[algo.trpo.trust_region]\nmax_kl = 0.01\n";
    std::fs::write(&two, both).expect("write");
    let r = tmp.path().join("r");
    for extra in [&[][..], &["--algo", "apo"][..]] {
        let mut args = vec![
            "train",
            "--env",
            "CartPole-v1",
            "--config",
            path(&two),
            "--out",
            path(&r),
        ];
        args.extend_from_slice(extra);
        let err = fails(&args);
        assert!(
            err.contains("several algorithms (apo, trpo)"),
            "{extra:?}: {err}"
        );
    }
    // a pipe or device as a config file: refused at once, never read
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--config",
        "/dev/zero",
        "--out",
        path(&tmp.path().join("r")),
    ]);
    assert!(
        err.contains("/dev/zero") && err.contains("not a regular file"),
        "{err}"
    );
    // plot: an output folder that does not exist, said with the path, before reading runs
    let err = fails(&[
        "plot",
        path(&tmp.path().join("missing-run")),
        "--out",
        path(&tmp.path().join("nodir/x.png")),
    ]);
    assert!(
        err.contains("nodir") && err.contains("does not exist"),
        "{err}"
    );
    // report: options are checked before any work
    let file = tmp.path().join("file");
    std::fs::write(&file, "").expect("write");
    let err = fails(&[
        "report",
        path(&tmp.path().join("missing")),
        "--out",
        path(&file),
    ]);
    assert!(
        err.contains("--out") && err.contains("not a directory"),
        "{err}"
    );
    let err = fails(&["report", path(&tmp.path().join("missing")), "--smooth", "0"]);
    assert!(err.contains("--smooth"), "{err}");
    // a flag and --set that disagree: the flag wins, with a warning
    let run = tmp.path().join("w");
    let out = apo(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--seed",
        "3",
        "--set",
        "seed=4",
        "--quiet",
        "--out",
        path(&run),
    ]);
    assert!(out.status.success());
    assert!(
        text(&out.stderr).contains("--seed 3 overrides --set seed=4"),
        "{}",
        text(&out.stderr)
    );
    // … and a flag that overrides the --config file's value
    let file = tmp.path().join("seeded.toml");
    std::fs::write(&file, "seed = 9\n").expect("write");
    let w2 = tmp.path().join("w2");
    let out = apo(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--seed",
        "3",
        "--config",
        path(&file),
        "--quiet",
        "--out",
        path(&w2),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("--seed 3 overrides seed = 9 of --config"),
        "{}",
        text(&out.stderr)
    );
    // an epoch count past any budget: refused with the rule, before a directory exists
    let never = tmp.path().join("never");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "18446744073709551615",
        "--out",
        path(&never),
    ]);
    assert!(
        err.contains("--epochs") && err.contains("1..=1000000000"),
        "{err}"
    );
    // … and one past the budget in a config file: the config's rule
    std::fs::write(&file, "epochs = 2000000000\n").expect("write");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--config",
        path(&file),
        "--out",
        path(&never),
    ]);
    assert!(
        err.contains("`epochs`") && err.contains("must be ≤ 1000000000"),
        "{err}"
    );
    assert!(!never.exists());
}

#[test]
fn a_checkpoint_with_non_finite_parameters_is_refused() {
    use apo_cli::checkpoint::{self, Which};
    use apo_cli::config::RunConfig;
    use apo_core::{ActionKind, Learner};
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
    let shapes = apo_cli::checkpoint::Shapes::of(&config, 4, action);
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
