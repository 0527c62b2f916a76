//! Sweeps on a Slurm cluster (`apo sweep --launcher slurm`): the runs of a sweep that are not
//! finished, queued or running are submitted as one job array, one array task per run, and
//! `apo sweep --status` says where each run stands.
//!
//! Each array task runs `apo sweep-task`, which trains its run the way a local sweep would
//! (new, resumed from its checkpoint, or started again when it never finished an epoch) and
//! passes every stop signal on to it. The job asks Slurm for `SIGUSR1` some time before its
//! time limit (`--signal=B:USR1@<warn>`): the task then stops the run, which writes its
//! checkpoint, and requeues itself (`scontrol requeue`), so the run resumes exactly where it
//! stopped when the task runs again. A task cancelled or preempted (`SIGTERM`) checkpoints
//! too; the next submission of the same sweep resumes it. Two tasks never train the same run
//! at once: the run's lock refuses the second.
//!
//! What is kept in `<out>/slurm/`: each job's script (`job-<id>.sh`), each task's output
//! (`<job>_<task>.out`, appended to when the task is requeued), and `submissions.csv`
//! (`job,task,run,epochs`: which run each task trains), which `--status` reads to ask
//! `squeue` about the runs' tasks.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{bail, Context};

use crate::sweep::{self, Received, RunStatus, SweepOptions, SweepRun, SweepSpec};
use apo_train::run_dir;

/// The folder of a sweep's Slurm files, inside the sweep's directory.
pub const FOLDER: &str = "slurm";

/// The record of every submitted task: `job,task,run,epochs`.
pub const SUBMISSIONS: &str = "submissions.csv";

/// How runs are submitted.
#[derive(Debug, Clone)]
pub struct SlurmOptions {
    /// The user's `sbatch` options, given after apo's (so they win): `--partition=…`,
    /// `--account=…`, `--time=…`, `--mem=…`, ….
    pub sbatch: Vec<String>,
    /// Seconds before the time limit at which Slurm sends the warning signal.
    pub warn_s: u64,
    /// The most array tasks running at once (`--array=0-N%limit`); `None`: as many as Slurm
    /// allows.
    pub limit: Option<usize>,
}

/// A task of a run as `squeue` shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct QueueEntry {
    /// The task's id, `<job>_<task>`.
    pub id: String,
    /// Slurm's state (`PENDING`, `RUNNING`, `COMPLETED`, …).
    pub state: String,
    /// Slurm's reason (why it is pending or ended; `None` without one).
    pub reason: String,
}

impl QueueEntry {
    /// Whether the task is still queued or running (it will train its run).
    pub fn active(&self) -> bool {
        !matches!(
            self.state.as_str(),
            "COMPLETED"
                | "FAILED"
                | "CANCELLED"
                | "TIMEOUT"
                | "NODE_FAIL"
                | "OUT_OF_MEMORY"
                | "BOOT_FAIL"
                | "DEADLINE"
                | "PREEMPTED"
                | "REVOKED"
        )
    }
}

/// One submitted task, as recorded in [`SUBMISSIONS`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Submission {
    /// Slurm's job id of the array.
    pub job: String,
    /// The task's index in the array.
    pub task: usize,
    /// The run it trains.
    pub run: String,
    /// Its epoch target.
    pub epochs: usize,
}

impl Submission {
    /// The task's id as `squeue` shows it, `<job>_<task>`.
    pub fn id(&self) -> String {
        format!("{}_{}", self.job, self.task)
    }
}

/// The program `name` on `PATH`.
pub fn find_program(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(name))
        .find(|p| p.is_file())
}

/// Checks that Slurm's commands are on `PATH`.
///
/// # Errors
/// Naming the missing command and where to get one.
pub fn check_slurm() -> anyhow::Result<()> {
    for program in ["sbatch", "squeue", "scontrol"] {
        if find_program(program).is_none() {
            bail!(
                "--launcher slurm needs Slurm's `{program}` on PATH, and it is not there: run the sweep on a \
                 cluster's login node, or start a single-node Slurm on this machine with \
                 `bash scripts/slurm-local.sh install && bash scripts/slurm-local.sh start` (docs/cluster.md)"
            );
        }
    }
    Ok(())
}

/// The tasks submitted so far for the sweep in `out` (none without a record).
///
/// # Errors
/// A record that cannot be read or parsed, naming its line.
pub fn submissions(out: &Path) -> anyhow::Result<Vec<Submission>> {
    let path = out.join(FOLDER).join(SUBMISSIONS);
    if std::fs::symlink_metadata(&path).is_err() {
        return Ok(Vec::new());
    }
    let text = apo_train::input::read_text(&path, "the sweep's Slurm record", 64 << 20)?;
    let mut found = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let fields: Vec<&str> = line.splitn(4, ',').collect();
        let parsed = match fields.as_slice() {
            [job, task, run, epochs] => {
                task.parse()
                    .ok()
                    .zip(epochs.parse().ok())
                    .map(|(task, epochs)| Submission {
                        job: (*job).to_string(),
                        task,
                        run: (*run).to_string(),
                        epochs,
                    })
            }
            _ => None,
        };
        match parsed {
            Some(s) => found.push(s),
            None => bail!(
                "{} line {}: `{line}` is not job,task,run,epochs",
                path.display(),
                i + 1
            ),
        }
    }
    Ok(found)
}

/// Where the latest task of each run submitted for the sweep in `out` stands in Slurm's queue
/// (runs whose task `squeue` no longer shows are left out).
///
/// # Errors
/// A record that cannot be read, or `squeue` failing.
pub fn queue(out: &Path) -> anyhow::Result<BTreeMap<String, QueueEntry>> {
    let latest = latest_submissions(&submissions(out)?);
    if latest.is_empty() {
        return Ok(BTreeMap::new());
    }
    let mut jobs: Vec<&str> = latest.values().map(|s| s.job.as_str()).collect();
    jobs.sort_unstable();
    jobs.dedup();
    // an id no longer known to Slurm makes squeue fail; the others are then asked one by one
    let lines = match squeue_lines(&jobs)? {
        Some(lines) => lines,
        None => {
            let mut lines = Vec::new();
            for job in &jobs {
                lines.extend(squeue_lines(&[*job])?.unwrap_or_default());
            }
            lines
        }
    };
    let mut by_id: BTreeMap<String, QueueEntry> = BTreeMap::new();
    for line in lines {
        let fields: Vec<&str> = line.trim().splitn(3, '|').collect();
        if let [id, state, reason] = fields.as_slice() {
            by_id.insert(
                (*id).to_string(),
                QueueEntry {
                    id: (*id).to_string(),
                    state: (*state).to_string(),
                    reason: (*reason).to_string(),
                },
            );
        }
    }
    Ok(latest
        .into_iter()
        .filter_map(|(run, s)| by_id.get(&s.id()).map(|e| (run, e.clone())))
        .collect())
}

/// `squeue`'s lines `<job>_<task>|<state>|<reason>` for every task of the arrays `jobs`;
/// `None` when `squeue` refuses the list (one of the ids is no longer known to Slurm).
///
/// # Errors
/// `squeue` that cannot be run.
fn squeue_lines(jobs: &[&str]) -> anyhow::Result<Option<Vec<String>>> {
    let listed = Command::new("squeue")
        .args(["--noheader", "--array", "--states=all", "--format=%i|%T|%r"])
        .arg(format!("--jobs={}", jobs.join(",")))
        .stdin(Stdio::null())
        .output()
        .context("running squeue")?;
    Ok(listed.status.success().then(|| {
        String::from_utf8_lossy(&listed.stdout)
            .lines()
            .map(str::to_string)
            .collect()
    }))
}

/// The latest submission of each run.
fn latest_submissions(all: &[Submission]) -> BTreeMap<String, Submission> {
    all.iter().map(|s| (s.run.clone(), s.clone())).collect()
}

/// Single-quotes `text` for bash.
fn quote(text: &str) -> String {
    format!("'{}'", text.replace('\'', r"'\''"))
}

/// The batch script of a job array whose task `i` trains the run `names[i]` of the sweep in
/// `out` to `epochs` epochs with `threads` threads, by `exe sweep-task`.
pub fn job_script(
    exe: &Path,
    out: &Path,
    names: &[&str],
    epochs: usize,
    threads: usize,
    options: &SlurmOptions,
) -> String {
    let last = names.len().saturating_sub(1);
    let limit = options.limit.map_or_else(String::new, |l| format!("%{l}"));
    let folder = out.join(FOLDER);
    let mut script = String::from("#!/bin/bash\n");
    script.push_str("# an apo sweep's runs, one per array task (apo sweep --launcher slurm)\n");
    script.push_str("#SBATCH --job-name=apo-sweep\n");
    script.push_str(&format!("#SBATCH --array=0-{last}{limit}\n"));
    script.push_str("#SBATCH --ntasks=1\n");
    script.push_str(&format!("#SBATCH --cpus-per-task={threads}\n"));
    // the warning before the time limit, to the batch process only: the task stops its run,
    // which checkpoints, and requeues itself
    script.push_str(&format!("#SBATCH --signal=B:USR1@{}\n", options.warn_s));
    script.push_str("#SBATCH --requeue\n");
    script.push_str("#SBATCH --open-mode=append\n");
    script.push_str(&format!(
        "#SBATCH --output={}\n",
        folder.join("%A_%a.out").display()
    ));
    script.push_str("runs=(\n");
    for name in names {
        script.push_str(&format!("  {}\n", quote(name)));
    }
    script.push_str(")\n");
    script.push_str(&format!(
        "exec {} sweep-task --out {} --run \"${{runs[$SLURM_ARRAY_TASK_ID]}}\" --epochs {epochs} --threads {threads}\n",
        quote(&exe.display().to_string()),
        quote(&out.display().to_string()),
    ));
    script
}

/// The sbatch options apo sets itself, because the sweep depends on them: the long name, the
/// short one, and what to use instead.
const OWN_OPTIONS: [(&str, &str, &str); 8] = [
    (
        "--array",
        "-a",
        "one task per unfinished run; --jobs N caps the tasks at once",
    ),
    ("--wrap", "", "the job script runs the sweep's tasks"),
    (
        "--output",
        "-o",
        "each task's output is <out>/slurm/<job>_<task>.out, which --status reads",
    ),
    (
        "--error",
        "-e",
        "each task's output is <out>/slurm/<job>_<task>.out, which --status reads",
    ),
    ("--open-mode", "", "a requeued task appends to its output"),
    (
        "--signal",
        "",
        "--slurm-warn sets the warning before the time limit",
    ),
    (
        "--cpus-per-task",
        "-c",
        "--threads sets each task's CPUs and its run's threads",
    ),
    ("--parsable", "", "apo reads the job id"),
];

/// Refuses the sbatch options that would break the sweep's job (apo sets them itself: the
/// array, the script, the output files, the warning signal, the CPUs) and empty ones.
///
/// # Errors
/// Naming the option and what to use instead.
pub fn check_sbatch_options(options: &[String]) -> anyhow::Result<()> {
    for option in options {
        if option.trim().is_empty() {
            bail!("--sbatch is empty: give an sbatch option, e.g. --sbatch=--partition=cpu");
        }
        let name = option.split('=').next().unwrap_or(option);
        for (long, short, instead) in OWN_OPTIONS {
            let is_short = !short.is_empty() && option.starts_with(short);
            if name == long || is_short {
                bail!("--sbatch={option}: apo sets {long} itself ({instead}); leave it out");
            }
        }
    }
    Ok(())
}

/// Runs `sbatch --parsable <args>` with `script` on its standard input; its output.
fn sbatch(args: &[String], script: &str, asked: &str) -> anyhow::Result<String> {
    let mut child = Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .context("running sbatch")?;
    if let Some(mut stdin) = child.stdin.take() {
        // sbatch may refuse its options and exit before it reads the script: its own message
        // and status below say why, not the broken pipe
        let _ = stdin.write_all(script.as_bytes());
    }
    let output = child.wait_with_output().context("running sbatch")?;
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    if !output.status.success() {
        bail!(
            "sbatch refused the job ({}): {}. apo asked for {asked}; your options: {}",
            output.status,
            said.trim(),
            if args.is_empty() {
                "none".to_string()
            } else {
                args.join(" ")
            }
        );
    }
    Ok(said)
}

/// What a submission did.
#[derive(Debug, Default)]
pub struct SubmitOutcome {
    /// The job id of the array submitted (`None`: nothing to submit).
    pub job: Option<String>,
    /// The runs submitted, in task order.
    pub submitted: Vec<String>,
    /// Runs finished before.
    pub finished: usize,
    /// Runs whose task is still queued or running (not submitted again).
    pub in_queue: usize,
}

/// Submits the runs of the sweep that are not finished and have no task queued or running as
/// one job array (see the module's documentation); `exe` is the apo executable the tasks run
/// (on a path the compute nodes see). The sweep's directory is made and recorded only once
/// `sbatch --test-only` has accepted the job with the user's options.
///
/// # Errors
/// No Slurm on `PATH`, `sbatch` refusing the options (its message), a run's directory the
/// sweep may not use, or a record that cannot be written.
pub fn submit(
    exe: &Path,
    spec: &SweepSpec,
    runs: &[SweepRun],
    options: &SweepOptions,
    slurm: &SlurmOptions,
) -> anyhow::Result<SubmitOutcome> {
    check_sbatch_options(&slurm.sbatch)?;
    sweep::check_run_names(&options.out, runs)?;
    check_slurm()?;
    let out = std::path::absolute(&options.out)
        .with_context(|| format!("the absolute path of {}", options.out.display()))?;
    let exe = std::path::absolute(exe).context("the absolute path of apo")?;
    let in_queue = queue(&out)?;
    let mut outcome = SubmitOutcome::default();
    let mut names = Vec::new();
    for run in runs {
        let dir = out.join(&run.name);
        sweep::check_own(&dir, run)?;
        if in_queue.get(&run.name).is_some_and(QueueEntry::active) {
            outcome.in_queue += 1;
            continue;
        }
        match sweep::status(&dir, options.epochs).with_context(|| {
            format!(
                "run {}: nothing was submitted (repair or move the run)",
                dir.display()
            )
        })? {
            RunStatus::Finished => outcome.finished += 1,
            _ => names.push(run.name.as_str()),
        }
    }
    if names.is_empty() {
        return Ok(outcome);
    }
    let asked = |n: usize| {
        format!(
            "--array=0-{} (one task per run), --cpus-per-task={} (--threads), --signal=B:USR1@{} (--slurm-warn)",
            n.saturating_sub(1),
            options.threads,
            slurm.warn_s
        )
    };
    let script = job_script(&exe, &out, &names, options.epochs, options.threads, slurm);
    let mut test = vec!["--test-only".to_string()];
    test.extend(slurm.sbatch.iter().cloned());
    sbatch(&test, &script, &asked(names.len()))?;
    sweep::record(&out, spec)?;
    let _lock = sweep::lock_sweep(&out)?;
    // what another submission may have launched since the check above
    let in_queue = queue(&out)?;
    let before = names.len();
    names.retain(|n| !in_queue.get(*n).is_some_and(QueueEntry::active));
    outcome.in_queue += before - names.len();
    if names.is_empty() {
        return Ok(outcome);
    }
    let script = job_script(&exe, &out, &names, options.epochs, options.threads, slurm);
    let folder = out.join(FOLDER);
    std::fs::create_dir_all(&folder)
        .with_context(|| format!("cannot create {}", folder.display()))?;
    let said = sbatch(&slurm.sbatch, &script, &asked(names.len()))?;
    let job = said
        .lines()
        .next()
        .and_then(|l| l.split(';').next())
        .map(str::trim)
        .filter(|j| !j.is_empty() && j.bytes().all(|b| b.is_ascii_digit()))
        .with_context(|| format!("sbatch did not print a job id: {}", said.trim()))?
        .to_string();
    let script_path = folder.join(format!("job-{job}.sh"));
    apo_train::atomic::write(&script_path, script.as_bytes())
        .with_context(|| format!("cannot write {}", script_path.display()))?;
    let record = folder.join(SUBMISSIONS);
    let mut text = if std::fs::symlink_metadata(&record).is_ok() {
        apo_train::input::read_text(&record, "the sweep's Slurm record", 64 << 20)?
    } else {
        "job,task,run,epochs\n".to_string()
    };
    for (task, name) in names.iter().enumerate() {
        text.push_str(&format!("{job},{task},{name},{}\n", options.epochs));
    }
    apo_train::atomic::write(&record, text.as_bytes())
        .with_context(|| format!("cannot write {}", record.display()))?;
    outcome.job = Some(job);
    outcome.submitted = names.into_iter().map(str::to_string).collect();
    Ok(outcome)
}

/// Where a run of a sweep stands, for `apo sweep --status`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Standing {
    /// Its checkpoint has reached the target.
    Finished,
    /// Its task is running in Slurm.
    Running {
        /// The task's id.
        id: String,
    },
    /// An apo process holds its run's lock: it is training now, outside Slurm's queue (a
    /// local sweep, `apo train --resume`, a task whose queue entry is gone).
    Training {
        /// What the lock file names (`pid <n>`), or empty.
        holder: String,
    },
    /// Its task waits in Slurm's queue.
    Queued {
        /// The task's id.
        id: String,
        /// Slurm's reason.
        reason: String,
    },
    /// Stopped at a checkpoint short of the target: a submission resumes it.
    Interrupted {
        /// Epochs done.
        done: usize,
    },
    /// Started but without a checkpoint, or its task ended in failure: a submission starts it
    /// (again).
    Failed {
        /// Why, as far as known (Slurm's state, the last error of its output or log).
        reason: String,
    },
    /// Not started.
    New,
    /// Its directory cannot be used (another run, a link, an unreadable checkpoint).
    Blocked {
        /// Why.
        reason: String,
    },
}

impl Standing {
    /// Whether a submission of the sweep would launch the run.
    pub fn would_launch(&self) -> bool {
        matches!(
            self,
            Standing::Interrupted { .. } | Standing::Failed { .. } | Standing::New
        )
    }
}

/// Where each run of the sweep in `out` stands for a target of `epochs`: its directory, and
/// under Slurm its latest task in the queue.
///
/// # Errors
/// A Slurm record that cannot be read, or `squeue` failing.
pub fn standings(
    out: &Path,
    runs: &[SweepRun],
    epochs: usize,
) -> anyhow::Result<Vec<(String, Standing)>> {
    let submitted = latest_submissions(&submissions(out)?);
    let in_queue = if submitted.is_empty() || find_program("squeue").is_none() {
        BTreeMap::new()
    } else {
        queue(out)?
    };
    let mut found = Vec::new();
    for run in runs {
        let dir = out.join(&run.name);
        let entry = in_queue.get(&run.name);
        let holder = run_dir::lock_holder(&dir);
        let standing = match entry {
            Some(e) if e.active() && e.state == "PENDING" => Standing::Queued {
                id: e.id.clone(),
                reason: e.reason.clone(),
            },
            Some(e) if e.active() => Standing::Running { id: e.id.clone() },
            _ if holder.is_some() => Standing::Training {
                holder: holder.clone().unwrap_or_default(),
            },
            _ => {
                let submission = submitted.get(&run.name);
                // the latest task ended on an error (not on a stop signal, which checkpoints)
                let error = submission.and_then(|s| task_error(out, s));
                match sweep::check_own(&dir, run).and_then(|()| sweep::status(&dir, epochs)) {
                    Err(e) => Standing::Blocked {
                        reason: format!("{e:#}"),
                    },
                    Ok(RunStatus::Finished) => Standing::Finished,
                    Ok(RunStatus::Interrupted { .. } | RunStatus::New) if error.is_some() => {
                        Standing::Failed {
                            reason: failure(out, &dir, submission, entry),
                        }
                    }
                    Ok(RunStatus::Interrupted { done }) => Standing::Interrupted { done },
                    Ok(RunStatus::New) => Standing::New,
                    Ok(RunStatus::Failed) => Standing::Failed {
                        reason: failure(out, &dir, submission, entry),
                    },
                }
            }
        };
        found.push((run.name.clone(), standing));
    }
    Ok(found)
}

/// Whether Slurm has requeued the job `job` since this task started: its restart count
/// (`Restarts=` of `scontrol show job`) is above the one the task started with
/// (`SLURM_RESTART_COUNT`, unset before the first requeue).
fn requeued_since_start(job: &str) -> bool {
    let before: u64 = std::env::var("SLURM_RESTART_COUNT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let Ok(shown) = Command::new("scontrol")
        .args(["show", "job", job, "-o"])
        .stdin(Stdio::null())
        .output()
    else {
        return false;
    };
    String::from_utf8_lossy(&shown.stdout)
        .split_whitespace()
        .find_map(|field| field.strip_prefix("Restarts="))
        .and_then(|n| n.parse::<u64>().ok())
        .is_some_and(|n| n > before)
}

/// The error the task of `submission` ended on: the last `error:` line of its output when no
/// line after it says the run was stopped by a signal (and checkpointed); `None` otherwise.
fn task_error(out: &Path, submission: &Submission) -> Option<String> {
    let path = out
        .join(FOLDER)
        .join(format!("{}_{}.out", submission.job, submission.task));
    last_line(&path, |l| {
        l.starts_with("error:")
            || l.starts_with("interrupted by SIG")
            || l.contains("requeued as job")
    })
    .filter(|l| l.starts_with("error:"))
}

/// The last line of the text file at `path` that `matches`, trimmed; `None` when there is none
/// or the file cannot be read.
fn last_line(path: &Path, matches: impl Fn(&str) -> bool) -> Option<String> {
    let text = apo_train::input::read_text(path, "a log", 64 << 20).ok()?;
    text.lines()
        .rev()
        .find(|l| matches(l))
        .map(|l| l.trim().to_string())
}

/// Why the run in `dir` failed, as far as its records say: Slurm's final state of its task,
/// then the last error line of the task's output or of the run's `train.log`.
fn failure(
    out: &Path,
    dir: &Path,
    submission: Option<&Submission>,
    entry: Option<&QueueEntry>,
) -> String {
    let mut why = Vec::new();
    if let Some(e) = entry {
        why.push(format!("task {} {}", e.id, e.state));
    }
    if let Some(line) = submission.and_then(|s| task_error(out, s)).or_else(|| {
        last_line(&dir.join(run_dir::LOG), |l| {
            l.contains("error") || l.contains("ERROR")
        })
    }) {
        why.push(line);
    }
    if why.is_empty() {
        "no checkpoint and no error recorded (stopped before its first epoch)".to_string()
    } else {
        why.join(": ")
    }
}

/// How a task ended.
#[derive(Debug)]
pub struct TaskEnd {
    /// The training's exit status (`None`: the run had finished before).
    pub status: Option<ExitStatus>,
    /// Whether the task requeued itself after the time-limit warning.
    pub requeued: bool,
}

/// The array task that trains the run `name` of the sweep in `out` (its `sweep.toml`) to
/// `epochs` epochs: as a local sweep would (new, resumed, or started again), the training a
/// child in its own process group, its output this task's. Every stop signal counted in
/// `received` is passed on; once `warned` is raised (Slurm's warning before the time limit)
/// the run is sent `SIGTERM`, and when it has stopped short of its target the task requeues
/// itself with `scontrol requeue $SLURM_JOB_ID`.
///
/// # Errors
/// A sweep record that cannot be read, a run the sweep does not have, a run directory the
/// sweep may not use, the training that cannot be started, or a failed requeue.
pub fn task(
    exe: &Path,
    out: &Path,
    name: &str,
    epochs: usize,
    threads: usize,
    received: &Received,
    warned: &AtomicBool,
) -> anyhow::Result<TaskEnd> {
    let spec = sweep::read_record(out)?;
    let runs = sweep::expand(&spec, epochs, u64::MAX)?;
    let run = runs
        .iter()
        .find(|r| r.name == name)
        .with_context(|| format!("the sweep in {} has no run {name}", out.display()))?;
    let dir = out.join(&run.name);
    sweep::check_own(&dir, run)?;
    let status = sweep::status(&dir, epochs)?;
    if status == RunStatus::Finished {
        apo_train::warnln!("{name}: finished before; nothing to do");
        return Ok(TaskEnd {
            status: None,
            requeued: false,
        });
    }
    let options = SweepOptions {
        out: out.to_path_buf(),
        epochs,
        jobs: 1,
        threads,
    };
    let mut cmd = sweep::command(exe, &spec, run, &options, &dir, status);
    cmd.stdin(Stdio::null());
    sweep::own_process_group(&mut cmd);
    let mut child = cmd.spawn().context("starting apo train")?;
    let mut sent = 0;
    let mut warned_sent = false;
    let exit = loop {
        let count = received.count.load(Ordering::SeqCst);
        while sent < count {
            sweep::send(child.id(), received.which.load(Ordering::SeqCst));
            sent += 1;
        }
        if warned.load(Ordering::SeqCst) && !warned_sent {
            apo_train::warnln!(
                "{name}: Slurm's time-limit warning: the run checkpoints and the task requeues itself"
            );
            sweep::send(child.id(), libc::SIGTERM as usize);
            warned_sent = true;
        }
        if let Some(exit) = child.try_wait().context("waiting for apo train")? {
            break exit;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut requeued = false;
    if warned_sent && sweep::status(&dir, epochs).ok() != Some(RunStatus::Finished) {
        let job = std::env::var("SLURM_JOB_ID")
            .context("requeueing the task: SLURM_JOB_ID is not set (not in a Slurm job)")?;
        let done = Command::new("scontrol")
            .args(["requeue", &job])
            .stdin(Stdio::null())
            .output()
            .context("running scontrol requeue")?;
        // Slurm ends a job's processes as it requeues the job, so the `scontrol` run from inside
        // it may be ended by that signal before it reports its success: the job's restart count
        // tells whether the requeue took place
        let ended_by_the_requeue = || {
            use std::os::unix::process::ExitStatusExt;
            done.status.signal().is_some() && requeued_since_start(&job)
        };
        if !done.status.success() && !ended_by_the_requeue() {
            bail!(
                "scontrol requeue {job} failed ({}): {}; the run stopped at its checkpoint and the next \
                 submission of the sweep resumes it",
                done.status,
                String::from_utf8_lossy(&done.stderr).trim()
            );
        }
        apo_train::warnln!("{name}: requeued as job {job}; it resumes from its checkpoint");
        requeued = true;
    }
    Ok(TaskEnd {
        status: Some(exit),
        requeued,
    })
}
