//! `apo sweep --launcher slurm` on a real single-node Slurm (Debian's slurm-wlm and munge,
//! started by `bash scripts/slurm-local.sh start`; `scripts/test.sh` starts one, runs these
//! with `--ignored slurm::` and stops it):
//!
//! * a sweep submitted as a job array finishes, `--status` says so, and a second submission
//!   launches nothing;
//! * a task cancelled mid-run (`scancel --batch --signal=TERM`) leaves its run at a checkpoint,
//!   `--status` says it is interrupted, and the next submission resumes it to a
//!   `progress.csv` equal to the uninterrupted run's;
//! * the time-limit warning (`SIGUSR1`) makes the task checkpoint and requeue itself, and the
//!   requeued task finishes the run exactly;
//! * `srun --mpi=pmix -n 2 apo train` equals `mpirun -n 2 apo train` (the `mpi` feature);
//! * no Slurm on PATH and options sbatch refuses are errors before anything is created.
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use apo_train::progress_csv::ProgressRow;

use super::{apo, ok, path, text, timeless, train_args};

/// The job id in `apo sweep --launcher slurm`'s "submitted job <id>: …" line.
fn submitted_job(stdout: &str) -> String {
    stdout
        .lines()
        .find_map(|l| l.strip_prefix("submitted job "))
        .and_then(|l| l.split(':').next())
        .unwrap_or_else(|| panic!("no job submitted: {stdout}"))
        .to_string()
}

/// The states of the job's tasks that squeue still shows.
fn states(job: &str) -> Vec<String> {
    let out = Command::new("squeue")
        .args(["--noheader", "--array", "--states=all", "--format=%T"])
        .arg(format!("--jobs={job}"))
        .output()
        .expect("squeue runs");
    text(&out.stdout)
        .lines()
        .map(|l| l.trim().to_string())
        .collect()
}

/// Waits until no task of `job` is queued, running or completing (at most `secs`).
fn wait_job(job: &str, secs: u64) {
    let start = Instant::now();
    let done = |s: &String| {
        matches!(
            s.as_str(),
            "COMPLETED" | "FAILED" | "CANCELLED" | "TIMEOUT" | "NODE_FAIL" | "OUT_OF_MEMORY"
        )
    };
    loop {
        let now = states(job);
        if now.iter().all(done) {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(secs),
            "job {job} still at {now:?} after {secs} s"
        );
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// Waits until `file` has at least `rows` data rows.
fn wait_rows(file: &Path, rows: usize, secs: u64) {
    let start = Instant::now();
    while std::fs::read_to_string(file).map_or(0, |t| t.lines().count().saturating_sub(1)) < rows {
        assert!(
            start.elapsed() < Duration::from_secs(secs),
            "{} has fewer than {rows} rows after {secs} s",
            file.display()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The arguments of a sweep submitted to Slurm ([`super::sweep_args_of`]).
fn sweep_args<'a>(out: &'a Path, seeds: &'a str, epochs: &'a str, steps: &'a str) -> Vec<&'a str> {
    let mut args = super::sweep_args_of(out, seeds, epochs, steps);
    args.extend(["--launcher", "slurm"]);
    args
}

/// The one-run sweep the stop tests use (seed 0, 16 epochs of 1 000 steps) in `out`: submits
/// it, waits for two recorded epochs, sends its task `signal` through `scancel --batch` (the
/// batch process only, as Slurm's time-limit warning is sent) and returns the sweep's
/// arguments, the job id and the run's directory.
fn submit_and_signal<'a>(
    out: &'a Path,
    signal: &str,
) -> (Vec<&'a str>, String, std::path::PathBuf) {
    let args = sweep_args(out, "0", "16", "1000");
    let job = submitted_job(&ok(&args));
    let run = out.join("CartPole-v1-ppo-s0");
    wait_rows(&run.join("progress.csv"), 2, 240);
    let sent = Command::new("scancel")
        .args([
            "--batch",
            &format!("--signal={signal}"),
            &format!("{job}_0"),
        ])
        .status()
        .expect("scancel runs");
    assert!(sent.success());
    (args, job, run)
}

/// The run trained the way the sweep's task trains it, without Slurm.
fn reference(dir: &Path, seed: &str, epochs: &str, steps: &str) -> Vec<ProgressRow> {
    let mut args = train_args(dir, "ppo", "CartPole-v1", epochs, steps);
    args.extend(["--seed", seed, "--threads", "1"]);
    ok(&args);
    timeless(dir)
}

#[test]
#[ignore = "needs a running Slurm (scripts/test.sh starts one)"]
fn a_sweep_finishes_through_slurm_and_a_second_submission_launches_nothing() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let args = sweep_args(&out, "0..2", "3", "600");
    let job = submitted_job(&ok(&args));
    let status = ok(&["sweep", "--status", "--out", path(&out), "--epochs", "3"]);
    assert!(
        status.contains("queued") || status.contains("running") || status.contains("finished"),
        "{status}"
    );
    wait_job(&job, 300);
    let status = ok(&["sweep", "--status", "--out", path(&out), "--epochs", "3"]);
    assert_eq!(status.matches("finished (3 epochs)").count(), 2, "{status}");
    assert!(status.contains("would launch nothing"), "{status}");
    let record = std::fs::read(out.join("slurm/submissions.csv")).expect("record");
    let again = ok(&args);
    assert!(again.contains("nothing to submit"), "{again}");
    assert!(again.contains("2 finished"), "{again}");
    assert!(
        out.join("cells.csv").exists(),
        "the cells of a finished sweep"
    );
    assert_eq!(
        std::fs::read(out.join("slurm/submissions.csv")).expect("record"),
        record,
        "nothing submitted the second time"
    );
    // the runs are those a local training makes
    let whole = reference(&tmp.path().join("reference"), "1", "3", "600");
    assert_eq!(timeless(&out.join("CartPole-v1-ppo-s1")), whole);
}

#[test]
#[ignore = "needs a running Slurm (scripts/test.sh starts one)"]
fn a_cancelled_task_is_resumed_exactly_by_the_next_submission() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let (epochs, steps) = ("16", "1000");
    let (args, job, run) = submit_and_signal(&out, "TERM");
    wait_job(&job, 120);
    let status = ok(&["sweep", "--status", "--out", path(&out), "--epochs", epochs]);
    assert!(status.contains("interrupted at epoch"), "{status}");
    assert!(status.contains("would launch 1 run"), "{status}");
    let done_before = timeless(&run).len();
    assert!(done_before < 16, "stopped mid-way: {done_before} epochs");
    let resumed = submitted_job(&ok(&args));
    assert_ne!(resumed, job);
    wait_job(&resumed, 300);
    let whole = reference(&tmp.path().join("reference"), "0", epochs, steps);
    assert_eq!(
        timeless(&run),
        whole,
        "the resumed run equals the uninterrupted one"
    );
}

#[test]
#[ignore = "needs a running Slurm (scripts/test.sh starts one)"]
fn the_time_limit_warning_checkpoints_and_requeues_the_task() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let (epochs, steps) = ("16", "1000");
    // what Slurm sends --slurm-warn seconds before the time limit
    let (_, job, run) = submit_and_signal(&out, "USR1");
    wait_job(&job, 400);
    let log = std::fs::read_to_string(out.join(format!("slurm/{job}_0.out"))).expect("task output");
    assert!(log.contains("requeued"), "{log}");
    let whole = reference(&tmp.path().join("reference"), "0", epochs, steps);
    assert_eq!(
        timeless(&run),
        whole,
        "the requeued run equals the uninterrupted one"
    );
}

#[test]
#[ignore = "needs a running Slurm (scripts/test.sh starts one)"]
fn bad_input_is_refused_before_anything_is_created() {
    let tmp = tempfile::tempdir().expect("tempdir");
    // no Slurm on PATH
    let out = tmp.path().join("no-slurm");
    let empty = tmp.path().join("empty-bin");
    std::fs::create_dir(&empty).expect("dir");
    let refused = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args(sweep_args(&out, "0", "1", "200"))
        .env("PATH", &empty)
        .output()
        .expect("apo runs");
    assert!(!refused.status.success());
    let err = text(&refused.stderr);
    assert!(
        err.contains("sbatch") && err.contains("slurm-local.sh"),
        "{err}"
    );
    assert!(!out.exists(), "nothing created");
    // a partition that does not exist, an option sbatch does not know, options apo sets
    // itself (they would break the job), an empty option, a task larger than the node
    for (option, said) in [
        ("--sbatch=--partition=nosuch", "partition"),
        ("--sbatch=--no-such-option", "no-such-option"),
        ("--sbatch=--array=0-1", "apo sets --array itself"),
        ("--sbatch=-o/tmp/x.out", "apo sets --output itself"),
        ("--sbatch=--wrap=echo", "apo sets --wrap itself"),
        ("--sbatch=", "--sbatch is empty"),
        ("--threads=64", "--cpus-per-task=64 (--threads)"),
    ] {
        let out = tmp.path().join("bad-option");
        let mut args = sweep_args(&out, "0", "1", "200");
        args.push(option);
        let refused = apo(&args);
        assert!(!refused.status.success(), "{option}");
        let err = text(&refused.stderr);
        assert!(err.contains(said), "{option}: {err}");
        assert!(!out.exists(), "{option}: nothing created");
    }
}

#[cfg(feature = "mpi")]
#[test]
#[ignore = "needs a running Slurm (scripts/test.sh starts one)"]
fn srun_two_ranks_train_as_mpirun_does() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let train = |dir: &Path| -> Vec<String> {
        train_args(dir, "apo", "CartPole-v1", "3", "800")
            .into_iter()
            .chain(["--threads", "1"])
            .map(str::to_string)
            .collect()
    };
    let by_srun = tmp.path().join("srun");
    let out = Command::new("srun")
        .args(["--mpi=pmix", "-n", "2", "--cpus-per-task=1"])
        .arg(env!("CARGO_BIN_EXE_apo"))
        .args(train(&by_srun))
        .output()
        .expect("srun runs");
    assert!(
        out.status.success(),
        "srun: {}\n{}",
        text(&out.stdout),
        text(&out.stderr)
    );
    let by_mpirun = tmp.path().join("mpirun");
    let out = Command::new("mpirun")
        .args(["--allow-run-as-root", "--oversubscribe", "-n", "2"])
        .arg(env!("CARGO_BIN_EXE_apo"))
        .args(train(&by_mpirun))
        .output()
        .expect("mpirun runs");
    assert!(out.status.success(), "mpirun: {}", text(&out.stderr));
    let config = std::fs::read_to_string(by_srun.join("config.toml")).expect("config");
    assert_eq!(
        config,
        std::fs::read_to_string(by_mpirun.join("config.toml")).expect("config")
    );
    assert_eq!(timeless(&by_srun), timeless(&by_mpirun));
    // two ranks, not one: the checkpoint records them
    let state =
        std::fs::read_to_string(by_srun.join("checkpoints/latest/state.json")).expect("state");
    assert!(
        state.contains("\"ranks\":2") || state.contains("\"ranks\": 2"),
        "{state}"
    );
}

#[test]
#[ignore = "needs a running Slurm (scripts/test.sh starts one)"]
fn a_task_that_fails_is_reported_with_its_error() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let (args, job, run) = submit_and_signal(&out, "TERM");
    wait_job(&job, 120);
    // a damaged checkpoint: the resumed task fails on it
    let policy = run.join("checkpoints/latest/policy.mpk");
    let bytes = std::fs::read(&policy).expect("policy");
    std::fs::write(&policy, &bytes[..bytes.len() / 2]).expect("truncate");
    let again = submitted_job(&ok(&args));
    wait_job(&again, 120);
    let status = ok(&["sweep", "--status", "--out", path(&out)]);
    assert!(status.contains("target: 16 epochs"), "{status}");
    assert!(
        status.contains("failed:") && status.contains("policy.mpk"),
        "{status}"
    );
    assert!(status.contains("1 run(s) failed"), "{status}");
}
