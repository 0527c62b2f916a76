//! `apo sweep`: a grid of config values × seeds × algorithms × environments, each cell and
//! seed a separate run (a child `apo train`) under one directory, several at once, resumable.
//!
//! Runs are named `<env>-<algo>[-<key>=<value>…]-s<seed>` (the last part of each grid key).
//! A grid axis applies to the algorithms that have its key (`algo.omega1` to APO and PAPO,
//! not to TRPO, which then runs once per environment and seed). Running the same sweep again
//! skips finished runs, resumes interrupted ones from their checkpoint and restarts runs that
//! never finished an epoch; `sweep.toml` records the sweep so that another sweep cannot be
//! mixed into the directory.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{bail, Context};
use apo_core::Algorithm;
use serde::{Deserialize, Serialize};

use crate::config::{Preset, RunConfig};
use crate::progress;
use crate::run_dir;
use crate::summary::{summarize, RunSummary};

/// One axis of the grid: a config key and its values (TOML syntax, as for `--set`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Axis {
    /// The dotted config key, e.g. `algo.omega1`.
    pub key: String,
    /// Its values.
    pub values: Vec<String>,
}

impl Axis {
    /// Parses `key=v1,v2,…`.
    pub fn parse(text: &str) -> anyhow::Result<Self> {
        let (key, values) = text
            .split_once('=')
            .with_context(|| format!("--grid expects key=v1,v2,…, got `{text}`"))?;
        let values: Vec<String> = values
            .split(',')
            .map(|v| v.trim().to_string())
            .filter(|v| !v.is_empty())
            .collect();
        if key.trim().is_empty() || values.is_empty() {
            bail!("--grid expects key=v1,v2,…, got `{text}`");
        }
        Ok(Self {
            key: key.trim().to_string(),
            values,
        })
    }

    /// The name of the key in run names: its last dotted part.
    fn short(&self) -> &str {
        self.key.rsplit('.').next().unwrap_or(&self.key)
    }
}

/// What a sweep runs (recorded as `sweep.toml`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepSpec {
    /// Environments.
    pub envs: Vec<String>,
    /// Algorithms, by name.
    pub algos: Vec<String>,
    /// Seeds.
    pub seeds: Vec<u64>,
    /// The grid.
    pub grid: Vec<Axis>,
    /// `--preset` of every run.
    pub preset: Option<String>,
    /// `--config` of every run.
    pub config: Option<PathBuf>,
    /// `--set` of every run.
    pub sets: Vec<String>,
    /// Environment steps per epoch of every run (`None`: the config's).
    pub steps_per_epoch: Option<usize>,
}

/// One run of a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRun {
    /// Environment.
    pub env: String,
    /// Algorithm.
    pub algo: Algorithm,
    /// The grid cell: `(key, value)` of the axes that apply to `algo`.
    pub cell: Vec<(String, String)>,
    /// Seed.
    pub seed: u64,
    /// The run directory's name.
    pub name: String,
}

impl SweepRun {
    /// The cell as `key=value` pairs joined by spaces (short keys), `-` when empty.
    pub fn cell_label(&self) -> String {
        if self.cell.is_empty() {
            return "-".to_string();
        }
        self.cell
            .iter()
            .map(|(k, v)| format!("{}={v}", k.rsplit('.').next().unwrap_or(k)))
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// The `--set` arguments of the run: the sweep's, then the cell's.
    fn sets(&self, spec: &SweepSpec) -> Vec<String> {
        spec.sets
            .iter()
            .cloned()
            .chain(self.cell.iter().map(|(k, v)| format!("{k}={v}")))
            .collect()
    }
}

fn parse_preset(name: &Option<String>) -> anyhow::Result<Option<Preset>> {
    name.as_deref()
        .map(|p| {
            <Preset as clap::ValueEnum>::from_str(p, true)
                .map_err(|e| anyhow::anyhow!("--preset {p}: {e}"))
        })
        .transpose()
}

/// Whether `key` is a setting of `algo` (a bad `value` for a key it has still counts: the
/// run's config check names it).
fn applies(algo: Algorithm, key: &str, value: &str) -> bool {
    use crate::config::ConfigFileError as E;
    !matches!(
        RunConfig::build(algo, "", None, &[format!("{key}={value}")]),
        Err(E::UnknownKey { .. } | E::NotOfAlgorithm { .. } | E::OtherAlgorithm { .. })
    )
}

/// Expands the sweep into its runs, in order: environment, algorithm, cell, seed. Checks
/// every run's config (with `epochs` and `steps_per_epoch`), so a bad value fails before
/// anything starts.
///
/// # Errors
/// An unknown algorithm or environment, a grid key no algorithm of the sweep has, or a
/// config that does not build.
pub fn expand(spec: &SweepSpec) -> anyhow::Result<Vec<SweepRun>> {
    let preset = parse_preset(&spec.preset)?;
    let algos = spec
        .algos
        .iter()
        .map(|a| a.parse::<Algorithm>().map_err(anyhow::Error::msg))
        .collect::<anyhow::Result<Vec<_>>>()?;
    for axis in &spec.grid {
        if !algos
            .iter()
            .any(|&a| applies(a, &axis.key, &axis.values[0]))
        {
            bail!(
                "--grid {}: no algorithm of the sweep ({}) has this key (see `apo config --algo <name>`)",
                axis.key,
                spec.algos.join(", ")
            );
        }
    }
    let mut runs = Vec::new();
    for env in &spec.envs {
        let env_name = apo_envs::registry::spec(env)?.name;
        for &algo in &algos {
            let axes: Vec<&Axis> = spec
                .grid
                .iter()
                .filter(|axis| applies(algo, &axis.key, &axis.values[0]))
                .collect();
            let mut cells: Vec<Vec<(String, String)>> = vec![vec![]];
            for axis in &axes {
                cells = cells
                    .into_iter()
                    .flat_map(|cell| {
                        axis.values.iter().map(move |v| {
                            let mut c = cell.clone();
                            c.push((axis.key.clone(), v.clone()));
                            c
                        })
                    })
                    .collect();
            }
            for cell in cells {
                for &seed in &spec.seeds {
                    let mut name = format!("{}-{algo}", run_dir::env_label(&env_name));
                    for ((_, v), axis) in cell.iter().zip(&axes) {
                        name.push_str(&format!("-{}={v}", axis.short()));
                    }
                    name.push_str(&format!("-s{seed}"));
                    let run = SweepRun {
                        env: env_name.clone(),
                        algo,
                        cell: cell.clone(),
                        seed,
                        name,
                    };
                    let mut sets = run.sets(spec);
                    sets.push(format!("seed={seed}"));
                    sets.extend(spec.steps_per_epoch.map(|n| format!("steps_per_epoch={n}")));
                    RunConfig::build_with_preset(
                        algo,
                        &env_name,
                        preset,
                        spec.config.as_deref(),
                        &sets,
                    )
                    .with_context(|| format!("run {}", run.name))?;
                    runs.push(run);
                }
            }
        }
    }
    Ok(runs)
}

/// Where a run of the sweep stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunStatus {
    /// No run directory yet.
    New,
    /// A run directory with `done` of `epochs` epochs and a checkpoint to resume from.
    Interrupted {
        /// Epochs done.
        done: usize,
    },
    /// A run directory that finished no epoch or has no checkpoint: started again.
    Failed,
    /// All epochs done.
    Finished,
}

/// Epochs recorded in `dir/progress.csv` (0 without one).
pub fn epochs_done(dir: &Path) -> usize {
    progress::read(&dir.join(run_dir::PROGRESS)).map_or(0, |rows| rows.len())
}

/// The status of the run in `dir` whose target is `epochs` epochs.
pub fn status(dir: &Path, epochs: usize) -> RunStatus {
    if !dir.exists() {
        return RunStatus::New;
    }
    let done = epochs_done(dir);
    if done >= epochs {
        RunStatus::Finished
    } else if done > 0 && dir.join(run_dir::CHECKPOINTS).join("latest").exists() {
        RunStatus::Interrupted { done }
    } else {
        RunStatus::Failed
    }
}

/// How to run a sweep.
#[derive(Debug, Clone)]
pub struct SweepOptions {
    /// The sweep's directory.
    pub out: PathBuf,
    /// Epochs of every run (a sweep run again with more epochs extends its runs).
    pub epochs: usize,
    /// Runs at once.
    pub jobs: usize,
    /// `--threads` of each run.
    pub threads: usize,
}

/// What a sweep did.
#[derive(Debug, Default)]
pub struct SweepOutcome {
    /// Runs skipped because they had finished before.
    pub skipped: usize,
    /// Runs that finished now.
    pub finished: usize,
    /// Runs that failed: name and the end of their error output.
    pub failed: Vec<(String, String)>,
    /// Whether the sweep was interrupted.
    pub interrupted: bool,
}

/// Checks `out/sweep.toml` against `spec` (writing it for a new sweep).
fn record(out: &Path, spec: &SweepSpec) -> anyhow::Result<()> {
    let path = out.join("sweep.toml");
    let text = toml::to_string_pretty(spec).context("serializing the sweep")?;
    if path.exists() {
        let old = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let old: SweepSpec = toml::from_str(&old)
            .with_context(|| format!("{} is not a sweep record", path.display()))?;
        if &old != spec {
            bail!(
                "{} holds another sweep (its sweep.toml differs: environments, algorithms, seeds, grid, preset, config or --set); use a new --out",
                out.display()
            );
        }
        return Ok(());
    }
    if out.exists() && std::fs::read_dir(out)?.next().is_some() {
        bail!(
            "{} exists and is not a sweep directory (no sweep.toml); use a new --out",
            out.display()
        );
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    crate::atomic::write(&path, text.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))
}

/// The child `apo train` command of `run`.
fn command(
    exe: &Path,
    spec: &SweepSpec,
    run: &SweepRun,
    options: &SweepOptions,
    dir: &Path,
) -> Command {
    let mut cmd = Command::new(exe);
    cmd.arg("train").arg("--quiet");
    cmd.arg("--threads").arg(options.threads.to_string());
    match status(dir, options.epochs) {
        RunStatus::Interrupted { .. } => {
            cmd.arg("--resume").arg(dir);
            cmd.arg("--epochs").arg(options.epochs.to_string());
            return cmd;
        }
        RunStatus::Failed => {
            cmd.arg("--force");
        }
        RunStatus::New | RunStatus::Finished => {}
    }
    cmd.arg("--algo").arg(run.algo.name());
    cmd.arg("--env").arg(&run.env);
    cmd.arg("--seed").arg(run.seed.to_string());
    cmd.arg("--epochs").arg(options.epochs.to_string());
    if let Some(steps) = spec.steps_per_epoch {
        cmd.arg("--steps-per-epoch").arg(steps.to_string());
    }
    if let Some(preset) = &spec.preset {
        cmd.arg("--preset").arg(preset);
    }
    if let Some(config) = &spec.config {
        cmd.arg("--config").arg(config);
    }
    for set in run.sets(spec) {
        cmd.arg("--set").arg(set);
    }
    cmd.arg("--out").arg(dir);
    cmd
}

/// Runs the sweep: `runs` (from [`expand`]) under `options.out`, `options.jobs` at a time,
/// each as `exe train …`. `tick(epochs_done_over_all_runs, runs_done)` is called about every
/// second. Stops launching runs once `stop` is raised (the running ones get the signal
/// themselves and checkpoint).
///
/// # Errors
/// When the directory holds another sweep or cannot be written.
pub fn run(
    exe: &Path,
    spec: &SweepSpec,
    runs: &[SweepRun],
    options: &SweepOptions,
    stop: &AtomicBool,
    tick: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<SweepOutcome> {
    record(&options.out, spec)?;
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let outcome = Mutex::new(SweepOutcome::default());
    let workers_left = AtomicUsize::new(options.jobs.max(1));
    std::thread::scope(|scope| {
        for _ in 0..options.jobs.max(1) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    let Some(run) = runs.get(i) else { break };
                    if stop.load(Ordering::SeqCst) {
                        break;
                    }
                    let dir = options.out.join(&run.name);
                    if status(&dir, options.epochs) == RunStatus::Finished {
                        lock(&outcome).skipped += 1;
                        done.fetch_add(1, Ordering::SeqCst);
                        continue;
                    }
                    let result = command(exe, spec, run, options, &dir).output();
                    let mut outcome = lock(&outcome);
                    match result {
                        Ok(out) if out.status.success() => outcome.finished += 1,
                        Ok(_) | Err(_) if stop.load(Ordering::SeqCst) => {}
                        Ok(out) => {
                            let text = String::from_utf8_lossy(&out.stderr);
                            let tail: Vec<&str> = text.lines().rev().take(3).collect();
                            let tail: Vec<&str> = tail.into_iter().rev().collect();
                            outcome.failed.push((run.name.clone(), tail.join(" | ")));
                        }
                        Err(e) => outcome
                            .failed
                            .push((run.name.clone(), format!("cannot start: {e}"))),
                    }
                    done.fetch_add(1, Ordering::SeqCst);
                }
                workers_left.fetch_sub(1, Ordering::SeqCst);
            });
        }
        while workers_left.load(Ordering::SeqCst) > 0 {
            let epochs: usize = runs
                .iter()
                .map(|r| epochs_done(&options.out.join(&r.name)).min(options.epochs))
                .sum();
            tick(epochs, done.load(Ordering::SeqCst));
            std::thread::sleep(std::time::Duration::from_millis(500));
        }
    });
    let mut outcome = outcome
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    outcome.interrupted = stop.load(Ordering::SeqCst);
    Ok(outcome)
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A metric of [`RunSummary`] by which cells are ranked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Metric {
    /// Average mean return over the last N epochs.
    MeanLast,
    /// Average worst return over the last N epochs.
    WorstLast,
    /// Average mean return over all epochs.
    MeanAll,
    /// Average worst return over all epochs.
    WorstAll,
}

impl Metric {
    /// The metric's value in `s`.
    pub fn of(self, s: &RunSummary) -> Option<f64> {
        match self {
            Metric::MeanLast => s.mean_last,
            Metric::WorstLast => s.worst_last,
            Metric::MeanAll => s.mean_all,
            Metric::WorstAll => s.worst_all,
        }
    }
}

/// One cell's result: the metric's mean and standard deviation over its seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct CellResult {
    /// Environment.
    pub env: String,
    /// Algorithm.
    pub algo: Algorithm,
    /// The cell's label (`omega1=0.001 omega2=0.003`, `-` without axes).
    pub cell: String,
    /// Seeds with a value.
    pub seeds: usize,
    /// Mean over seeds.
    pub mean: f64,
    /// Population standard deviation over seeds.
    pub std: f64,
}

/// Each cell's `metric` (over the last `last` epochs where it says so), mean ± std over the
/// seeds whose run has episodes; cells without any are left out. Sorted by environment,
/// algorithm, then best first.
pub fn cell_results(out: &Path, runs: &[SweepRun], metric: Metric, last: usize) -> Vec<CellResult> {
    let mut cells: BTreeMap<(String, String, String), Vec<f64>> = BTreeMap::new();
    for run in runs {
        let value = summarize(&out.join(&run.name), last)
            .ok()
            .and_then(|s| metric.of(&s));
        let entry = cells
            .entry((
                run.env.clone(),
                run.algo.name().to_string(),
                run.cell_label(),
            ))
            .or_default();
        entry.extend(value);
    }
    let mut results: Vec<CellResult> = cells
        .into_iter()
        .filter(|(_, values)| !values.is_empty())
        .filter_map(|((env, algo, cell), values)| {
            let (mean, std) = crate::summary::mean_std(&values);
            Some(CellResult {
                env,
                algo: algo.parse().ok()?,
                cell,
                seeds: values.len(),
                mean,
                std,
            })
        })
        .collect();
    results.sort_by(|a, b| {
        (a.env.as_str(), a.algo.name())
            .cmp(&(b.env.as_str(), b.algo.name()))
            .then(b.mean.total_cmp(&a.mean))
    });
    results
}

/// The cells as CSV: `env,algo,cell,seeds,mean,std,best` (best: the first of its
/// environment and algorithm).
pub fn cells_csv(results: &[CellResult]) -> String {
    let mut out = String::from("env,algo,cell,seeds,mean,std,best\n");
    let mut previous: Option<(&str, Algorithm)> = None;
    for r in results {
        let best = previous != Some((r.env.as_str(), r.algo));
        previous = Some((r.env.as_str(), r.algo));
        out.push_str(&format!(
            "{},{},\"{}\",{},{:.4},{:.4},{}\n",
            r.env, r.algo, r.cell, r.seeds, r.mean, r.std, best
        ));
    }
    out
}
