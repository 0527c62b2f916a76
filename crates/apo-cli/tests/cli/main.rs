//! End-to-end tests of the `apo` binary: reproducibility, resume, bad input, backends.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use apo_train::progress_csv::{self, ProgressRow};

mod bound_config;
mod causes;
mod checkpoints;
mod outputs;
mod physics;
mod plot;
mod ranges;
mod reading;
mod reference;
mod render;
mod reporting;
mod slurm;
mod stops;
mod sweep_report;
mod theory;
mod timing;

pub fn apo(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_apo"))
        .args(args)
        .output()
        .expect("the apo binary runs")
}

/// Runs `apo args`, failing the test (after killing it) when it is not done within `secs`
/// seconds: a command that hangs is a failure, not a stuck test run.
pub fn apo_within(secs: u64, args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn apo");
    let deadline = Instant::now() + Duration::from_secs(secs);
    while child.try_wait().expect("poll apo").is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("apo {args:?} still running after {secs} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().expect("apo's output")
}

pub fn ok(args: &[&str]) -> String {
    let out = apo(args);
    assert!(
        out.status.success(),
        "apo {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

pub fn fails(args: &[&str]) -> String {
    let out = apo(args);
    assert!(!out.status.success(), "apo {args:?} should fail");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

pub fn path(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// The arguments of a one-epoch CartPole PPO run of 200 steps in `dir`.
pub fn small_args(dir: &Path) -> Vec<&str> {
    vec![
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
        "--out",
        path(dir),
    ]
}

/// A one-epoch CartPole PPO run of 200 steps in `dir` (`extra` appended).
pub fn small(dir: &Path, extra: &[&str]) -> String {
    let mut args = small_args(dir);
    args.extend_from_slice(extra);
    ok(&args)
}

/// The arguments of a quiet `apo train` of `algo` on `env` for `epochs` epochs of `steps` steps
/// into `dir` (append the rest).
pub fn train_args<'a>(
    dir: &'a Path,
    algo: &'a str,
    env: &'a str,
    epochs: &'a str,
    steps: &'a str,
) -> Vec<&'a str> {
    vec![
        "train",
        "--algo",
        algo,
        "--env",
        env,
        "--epochs",
        epochs,
        "--steps-per-epoch",
        steps,
        "--quiet",
        "--out",
        path(dir),
    ]
}

/// A small run: 3 epochs of 600 steps on CartPole, seed 7 (`extra` appended).
pub fn train(dir: &Path, algo: &str, extra: &[&str]) -> String {
    let mut args = train_args(dir, algo, "CartPole-v1", "3", "600");
    args.extend(["--seed", "7"]);
    args.extend_from_slice(extra);
    ok(&args)
}

/// A named pipe at `place` (`mkfifo`).
pub fn mkfifo(place: &Path) {
    let made = Command::new("mkfifo")
        .arg(place)
        .status()
        .expect("mkfifo (coreutils)");
    assert!(made.success(), "mkfifo {}", place.display());
}

/// Starts `apo args` with SIGHUP at its default, as from a terminal, whatever the test runner
/// was started with (under `nohup` apo keeps ignoring a SIGHUP ignored from the start).
pub fn spawn(args: &[&str]) -> Child {
    use std::os::unix::process::CommandExt;
    let mut command = Command::new(env!("CARGO_BIN_EXE_apo"));
    // SAFETY: between fork and exec only `signal`, which is async-signal-safe, is called
    unsafe {
        command.pre_exec(|| {
            libc::signal(libc::SIGHUP, libc::SIG_DFL);
            Ok(())
        });
    }
    command
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn apo")
}

/// A 500-epoch PPO run on CartPole in `dir`, to be stopped by the test.
pub fn long_run(dir: &Path) -> Child {
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

pub fn wait_for(file: &Path) {
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

pub fn signal(child: &Child, name: &str) {
    let status = Command::new("kill")
        .args([&format!("-{name}"), &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
}

/// Waits for `child` at most `secs` seconds; kills it and fails when it takes longer.
pub fn finish(mut child: Child, secs: u64) -> (Option<i32>, String, String) {
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

/// Plants `text` at `dir/rel` (folders created).
pub fn plant(dir: &Path, rel: &str, text: &str) -> PathBuf {
    let file = dir.join(rel);
    std::fs::create_dir_all(file.parent().expect("parent")).expect("mkdir");
    std::fs::write(&file, text).expect("plant");
    file
}

/// Every file under `dir` (folders followed, links not).
pub fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                stack.push(p);
            } else {
                found.push(p);
            }
        }
    }
    found
}

/// Every file under `dir` whose content is `text`.
pub fn find_content(dir: &Path, text: &str) -> Vec<PathBuf> {
    files_under(dir)
        .into_iter()
        .filter(|p| std::fs::read_to_string(p).is_ok_and(|t| t == text))
        .collect()
}

/// A sweep of one CartPole PPO run (seed 0) of `epochs` epochs × 200 steps in `out` (`extra`
/// appended), run to its end.
pub fn sweep(out: &Path, epochs: &str, extra: &[&str]) -> std::process::Output {
    let mut args = sweep_args(out, epochs);
    args.extend_from_slice(extra);
    apo(&args)
}

/// The arguments of [`sweep`]: seed 0, 200 steps per epoch.
pub fn sweep_args<'a>(out: &'a Path, epochs: &'a str) -> Vec<&'a str> {
    sweep_args_of(out, "0", epochs, "200")
}

/// The arguments of a quiet PPO sweep on CartPole-v1 of `seeds` into `out`.
pub fn sweep_args_of<'a>(
    out: &'a Path,
    seeds: &'a str,
    epochs: &'a str,
    steps: &'a str,
) -> Vec<&'a str> {
    vec![
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--seeds",
        seeds,
        "--epochs",
        epochs,
        "--steps-per-epoch",
        steps,
        "--quiet",
        "--out",
        path(out),
    ]
}

pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The rows without their wall-clock columns.
pub fn timeless(dir: &Path) -> Vec<ProgressRow> {
    progress_csv::read(&dir.join("progress.csv"))
        .expect("progress.csv")
        .into_iter()
        .map(ProgressRow::timeless)
        .collect()
}

#[test]
fn same_seed_gives_identical_progress() {
    let tmp = tempfile::tempdir().expect("tempdir");
    for algo in ["apo", "ppo"] {
        let (a, b) = (
            tmp.path().join(format!("{algo}-a")),
            tmp.path().join(format!("{algo}-b")),
        );
        train(&a, algo, &[]);
        train(&b, algo, &[]);
        let (ra, rb) = (timeless(&a), timeless(&b));
        assert_eq!(ra.len(), 3);
        assert!(
            ra.iter().all(|r| r.episodes > 0 && r.kl.is_finite()),
            "{ra:?}"
        );
        assert_eq!(ra, rb, "{algo}: same seed, different rows");
    }
    let c = tmp.path().join("other-seed");
    ok(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "3",
        "--steps-per-epoch",
        "600",
        "--seed",
        "8",
        "--quiet",
        "--out",
        path(&c),
    ]);
    assert_ne!(
        timeless(&c),
        timeless(&tmp.path().join("ppo-a")),
        "another seed should give other rows"
    );
}

#[test]
fn environment_threads_do_not_change_the_run() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let rows: Vec<Vec<ProgressRow>> = ["1", "2", "3"]
        .iter()
        .map(|threads| {
            let dir = tmp.path().join(format!("threads-{threads}"));
            train(&dir, "apo", &["--num-envs", "4", "--threads", threads]);
            timeless(&dir)
        })
        .collect();
    assert_eq!(rows[0].len(), 3);
    assert!(rows[0].iter().all(|r| r.episodes > 0), "{:?}", rows[0]);
    assert_eq!(rows[0], rows[1], "2 threads changed the run");
    assert_eq!(rows[0], rows[2], "3 threads changed the run");
}

#[test]
fn evaluation_keeps_the_best_checkpoint_changes_no_training_number_and_resumes_exactly() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let evaluation = [
        "--set",
        "normalize_obs=true",
        "--set",
        "eval_every=1",
        "--set",
        "eval_episodes=3",
        "--set",
        "eval_best=\"worst\"",
    ];
    let whole = tmp.path().join("whole");
    train(&whole, "ppo", &evaluation);
    let plain = tmp.path().join("plain");
    train(&plain, "ppo", &evaluation[..2]);
    let rows = timeless(&whole);
    let without: Vec<ProgressRow> = rows
        .iter()
        .cloned()
        .map(ProgressRow::without_evaluation)
        .collect();
    assert_eq!(without, timeless(&plain), "evaluation changed training");
    assert!(rows.iter().all(|r| r.eval_ret_min.is_some()), "{rows:?}");
    // the best checkpoint is the epoch of the best worst evaluation return (the first of ties)
    let best = rows
        .iter()
        .fold(None, |b: Option<&ProgressRow>, r| match b {
            Some(b) if b.eval_ret_min >= r.eval_ret_min => Some(b),
            _ => Some(r),
        })
        .expect("rows")
        .epoch;
    let checkpoint_epoch = |run: &Path| {
        ok(&[
            "eval",
            "--run",
            path(run),
            "--checkpoint",
            "best",
            "--episodes",
            "1",
        ])
        .split("checkpoint_epoch=")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse::<usize>().ok())
        .expect("an epoch")
    };
    assert_eq!(checkpoint_epoch(&whole), best);
    // a run resumed after 2 epochs: the same rows, the same best checkpoint
    let parts = tmp.path().join("parts");
    let mut first = vec![
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "2",
        "--steps-per-epoch",
        "600",
        "--seed",
        "7",
        "--quiet",
        "--out",
        path(&parts),
    ];
    first.extend(evaluation);
    ok(&first);
    ok(&[
        "train",
        "--resume",
        path(&parts),
        "--epochs",
        "3",
        "--quiet",
    ]);
    assert_eq!(timeless(&parts), rows, "resumed run differs");
    assert_eq!(checkpoint_epoch(&parts), best);
    // the episode record: every episode of training and of evaluation, the same when resumed,
    // and what progress.csv's return columns are made of
    let episodes = std::fs::read_to_string(whole.join("episodes.csv")).expect("episodes.csv");
    assert_eq!(
        std::fs::read_to_string(parts.join("episodes.csv")).expect("episodes.csv"),
        episodes,
        "the resumed run's episode record differs"
    );
    let records = apo_train::episodes_csv::read(&whole.join("episodes.csv")).expect("records");
    for row in &rows {
        let of = |phase| {
            records
                .iter()
                .filter(|r| r.epoch == row.epoch && r.phase == phase)
                .map(|r| r.ret)
                .collect::<Vec<f64>>()
        };
        let (train, eval) = (
            of(apo_train::episodes_csv::Phase::Train),
            of(apo_train::episodes_csv::Phase::Eval),
        );
        assert_eq!(train.len(), row.episodes, "epoch {}", row.epoch);
        assert_eq!(eval.len(), 3, "epoch {}", row.epoch);
        let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        assert_eq!(Some(min(&train)), row.ep_ret_min, "epoch {}", row.epoch);
        assert_eq!(Some(min(&eval)), row.eval_ret_min, "epoch {}", row.epoch);
    }
    // a run without evaluation has no best checkpoint, and says so
    let err = fails(&["eval", "--run", path(&plain), "--checkpoint", "best"]);
    assert!(err.contains("no best checkpoint"), "{err}");
}

#[test]
fn resumed_run_matches_uninterrupted_run() {
    let tmp = tempfile::tempdir().expect("tempdir");
    // V-MPO: its learned η and α (columns eta, alpha) continue from the checkpoint
    for algo in ["trpo", "papo", "vmpo"] {
        let whole = tmp.path().join(format!("{algo}-whole"));
        train(&whole, algo, &["--set", "normalize_obs=true"]);
        let parts = tmp.path().join(format!("{algo}-parts"));
        let mut args = vec![
            "train",
            "--algo",
            algo,
            "--env",
            "CartPole-v1",
            "--epochs",
            "2",
            "--steps-per-epoch",
            "600",
        ];
        args.extend([
            "--seed",
            "7",
            "--quiet",
            "--set",
            "normalize_obs=true",
            "--out",
            path(&parts),
        ]);
        ok(&args);
        assert_eq!(timeless(&parts).len(), 2);
        ok(&[
            "train",
            "--resume",
            path(&parts),
            "--epochs",
            "3",
            "--quiet",
        ]);
        assert_eq!(
            timeless(&parts),
            timeless(&whole),
            "{algo}: resumed run differs"
        );
        assert_eq!(
            std::fs::read(parts.join("episodes.csv")).expect("episodes.csv"),
            std::fs::read(whole.join("episodes.csv")).expect("episodes.csv"),
            "{algo}: resumed episode record differs"
        );
    }
}

#[test]
fn sigint_writes_a_checkpoint_and_resume_completes_the_run() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let whole = tmp.path().join("whole");
    let args = |dir: &PathBuf| -> Vec<String> {
        [
            "train",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--epochs",
            "25",
            "--steps-per-epoch",
            "300",
            "--seed",
            "3",
            "--quiet",
            "--out",
        ]
        .iter()
        .map(|s| s.to_string())
        .chain([path(dir).to_string()])
        .collect()
    };
    let cut = tmp.path().join("cut");
    let mut child = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args(args(&cut))
        .spawn()
        .expect("spawn apo");
    let deadline = Instant::now() + Duration::from_secs(300);
    while !cut.join("progress.csv").exists() {
        assert!(Instant::now() < deadline, "no epoch finished in time");
        std::thread::sleep(Duration::from_millis(20));
    }
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    let exit = child.wait().expect("wait");
    assert_eq!(
        exit.code(),
        Some(130),
        "an interrupted run exits with 130 after SIGINT"
    );
    let done = timeless(&cut).len();
    assert!(done < 25, "the run should have stopped early");
    assert!(cut.join("checkpoints/latest/state.json").exists());
    let state: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(cut.join("checkpoints/latest/state.json")).expect("state"),
    )
    .expect("json");
    assert_eq!(state["epoch"].as_u64(), Some(done as u64));

    ok(&["train", "--resume", path(&cut), "--quiet"]);
    let out = apo(&args(&whole).iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.status.success());
    assert_eq!(timeless(&cut), timeless(&whole));
}

#[test]
fn bad_input_gets_clear_errors() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("run");
    let o = path(&out);
    let err = fails(&["train", "--algo", "apo", "--env", "CartPol-v1", "--out", o]);
    assert!(
        err.contains("unknown environment `CartPol-v1`") && err.contains("CartPole-v1"),
        "{err}"
    );
    // an Atari game in a build without the `atari` feature: how to get one; in a build with
    // it (as CI's), a misspelt game is a typo: the error lists the games and gives no hint
    if cfg!(feature = "atari") {
        let err = fails(&[
            "train",
            "--algo",
            "ppo",
            "--env",
            "ALE/Pongg-v5",
            "--out",
            o,
        ]);
        assert!(
            err.contains("unknown environment `ALE/Pongg-v5`")
                && err.contains("`ALE/Pong-v5`")
                && !err.contains("--features atari"),
            "{err}"
        );
    } else {
        let err = fails(&["train", "--algo", "ppo", "--env", "ALE/Pong-v5", "--out", o]);
        assert!(
            err.contains("unknown environment `ALE/Pong-v5`") && err.contains("--features atari"),
            "{err}"
        );
    }
    let err = fails(&["train", "--algo", "ppp", "--env", "CartPole-v1", "--out", o]);
    assert!(
        err.contains("unknown algorithm `ppp`") && err.contains("ppo"),
        "{err}"
    );
    for (set, field) in [
        ("algo.gamma=1.0", "`algo.apo.gamma` = 1"),
        ("algo.apo.k=-1", "`algo.apo.k` = -1"),
        (
            "algo.trust_region.max_kl=0",
            "`algo.apo.trust_region.max_kl` = 0",
        ),
        (
            "algo.clip=0.1",
            "apo has no setting `clip` (it is a setting of papo, ppo, mvpi, cvar, retcap, tailppo)",
        ),
        (
            "algo.lamda=0.9",
            "unknown config key `algo.apo.lamda`; did you mean `algo.apo.lambda`?",
        ),
        ("epochs=\"many\"", "config key `epochs`"),
    ] {
        let err = fails(&[
            "train",
            "--algo",
            "apo",
            "--env",
            "CartPole-v1",
            "--set",
            set,
            "--out",
            o,
        ]);
        assert!(err.contains(field), "{set}: {err}");
    }
    let missing = tmp.path().join("nope.toml");
    let err = fails(&[
        "train",
        "--algo",
        "apo",
        "--env",
        "CartPole-v1",
        "--config",
        path(&missing),
        "--out",
        o,
    ]);
    assert!(err.contains("cannot read config file"), "{err}");
    let garbage = tmp.path().join("garbage.toml");
    std::fs::write(&garbage, "gamma = [").expect("write");
    let err = fails(&[
        "train",
        "--algo",
        "apo",
        "--env",
        "CartPole-v1",
        "--config",
        path(&garbage),
        "--out",
        o,
    ]);
    assert!(err.contains("not valid TOML"), "{err}");
    assert!(
        !out.exists(),
        "a failed start must not create the run directory"
    );

    // an existing run is never overwritten without --force
    ok(&[
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
        o,
    ]);
    let before = std::fs::read(out.join("progress.csv")).expect("progress");
    let err = fails(&[
        "train",
        "--algo",
        "a2c",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--quiet",
        "--out",
        o,
    ]);
    assert!(
        err.contains("already exists") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(out.join("progress.csv")).expect("progress"),
        before
    );

    // a run's config.toml alone reruns it: its env and algorithm come from the file
    let again = tmp.path().join("again");
    ok(&[
        "train",
        "--config",
        path(&out.join("config.toml")),
        "--quiet",
        "--out",
        path(&again),
    ]);
    let read = |run: &std::path::Path, name: &str| {
        std::fs::read_to_string(run.join(name)).expect("run file")
    };
    assert_eq!(read(&again, "config.toml"), read(&out, "config.toml"));
    // the same seed, the same rollout: the first columns (epoch to ep_ret_max) agree
    let head = |text: String| -> Vec<String> {
        text.lines()
            .map(|l| l.split(',').take(6).collect::<Vec<_>>().join(","))
            .collect()
    };
    assert_eq!(
        head(read(&again, "progress.csv")),
        head(read(&out, "progress.csv"))
    );
    let bad_env = tmp.path().join("bad-env.toml");
    std::fs::write(&bad_env, "env = 3\n").expect("write");
    let err = fails(&[
        "train",
        "--algo",
        "a2c",
        "--config",
        path(&bad_env),
        "--out",
        o,
    ]);
    assert!(
        err.contains("config key `env`") && err.contains("bad-env.toml"),
        "{err}"
    );

    // a corrupt checkpoint
    std::fs::write(
        out.join("checkpoints/latest/policy.mpk"),
        b"not a checkpoint",
    )
    .expect("corrupt");
    let err = fails(&["train", "--resume", o, "--epochs", "2", "--quiet"]);
    assert!(err.contains("corrupt"), "{err}");
    let err = fails(&["eval", "--run", o]);
    assert!(err.contains("corrupt"), "{err}");
}

#[test]
fn eval_list_and_plot() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    train(&run, "trpo", &[]);
    let out = ok(&[
        "eval",
        "--run",
        path(&run),
        "--episodes",
        "3",
        "--deterministic",
    ]);
    assert!(
        out.contains("episodes=3 mean_return=") && out.contains("min_return="),
        "{out}"
    );
    let list = ok(&["list"]);
    assert!(
        list.contains("CartPole-v1") && list.contains("discrete(2)") && list.contains("papo"),
        "{list}"
    );
    for name in ["curves.png", "curves.svg"] {
        let image = tmp.path().join(name);
        ok(&["plot", path(&run), path(&run), "--out", path(&image)]);
        assert!(std::fs::metadata(&image).expect("image written").len() > 1000);
    }
    let err = fails(&["plot", path(&run), "--out", path(&tmp.path().join("x.gif"))]);
    assert!(err.contains(".png or .svg"), "{err}");
}

#[test]
fn wgpu_backend_trains() {
    let tmp = tempfile::tempdir().expect("tempdir");
    // V-MPO: its multipliers are learned through wgpu's autodiff graph too
    for algo in ["apo", "papo", "vmpo"] {
        let run = tmp.path().join(algo);
        let out = apo(&[
            "train",
            "--algo",
            algo,
            "--env",
            "Pendulum-v1",
            "--backend",
            "wgpu",
            "--epochs",
            "2",
            "--steps-per-epoch",
            "400",
            "--quiet",
            "--out",
            path(&run),
        ]);
        assert!(
            out.status.success(),
            "wgpu training failed (is a Vulkan driver installed, e.g. mesa-vulkan-drivers?): {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let rows = timeless(&run);
        assert_eq!(rows.len(), 2);
        assert!(
            rows.iter()
                .all(|r| r.kl.is_finite() && r.loss_v.is_finite() && r.episodes == 2),
            "{rows:?}"
        );
        if algo == "vmpo" {
            assert!(
                rows.iter()
                    .all(|r| r.eta.is_some_and(|e| e.is_finite() && e != 1.0)),
                "{rows:?}"
            );
        }
    }
}
