//! `apo sweep`: a grid of config values × seeds × algorithms × environments, each cell and
//! seed a separate run (a child `apo train`) under one directory, several at once, resumable.
//!
//! Runs are named `<env>-<algo>[-<key>=<value>…]-s<seed>` (the last part of each grid key).
//! A grid axis applies to the algorithms that have its key (`algo.omega1` to APO and PAPO,
//! not to TRPO, which then runs once per environment and seed). Running the same sweep again
//! skips finished runs, resumes interrupted ones from their checkpoint and restarts runs that
//! never finished an epoch; `sweep.toml` records the sweep so that another sweep cannot be
//! mixed into the directory. A run is finished when its checkpoint has reached the target
//! epoch (not when `progress.csv` has that many rows: a run killed between its last row and
//! its last checkpoint is resumed, which repairs it).
//!
//! The sweep is counted before anything is allocated (at most [`DEFAULT_MAX_RUNS`] runs
//! unless raised), lists may not repeat a value, and keys the sweep sets itself (`env`,
//! `seed`, `epochs`, `steps_per_epoch`) are refused in `--grid` and `--set`. Children run in
//! their own process group: a SIGINT or SIGTERM to the sweep is forwarded to each running
//! child (which checkpoints), and the sweep waits for all of them before it exits.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{bail, Context};
use apo_core::Algorithm;
use serde::{Deserialize, Serialize};

use crate::summary::{summarize, RunSummary};
use apo_train::progress_csv;
use apo_train::run_config::{Preset, RunConfig};
use apo_train::run_dir;

/// One axis of the grid: a config key and its values (TOML syntax, as for `--set`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Axis {
    /// The dotted config key, e.g. `algo.omega1`.
    pub key: String,
    /// Its values.
    pub values: Vec<String>,
}

impl Axis {
    /// Parses `key=v1,v2,…`; a value may be a TOML list or string with commas inside
    /// (`hidden=[32,32],[64,64]`). A value given twice (by its parsed TOML value: `0.01` and
    /// `0.010` are one value) is refused.
    pub fn parse(text: &str) -> anyhow::Result<Self> {
        let (key, values) = text
            .split_once('=')
            .with_context(|| format!("--grid expects key=v1,v2,…, got `{text}`"))?;
        let values: Vec<String> = split_top_level(values)
            .with_context(|| format!("--grid `{text}`"))?
            .into_iter()
            .map(|v| v.trim().to_string())
            .filter(|v| !v.is_empty())
            .collect();
        if key.trim().is_empty() || values.is_empty() {
            bail!("--grid expects key=v1,v2,…, got `{text}`");
        }
        let key = key.trim().to_string();
        let mut seen: Vec<(toml::Value, &str)> = Vec::new();
        for v in &values {
            let parsed = apo_train::run_config::parse_value(v)
                .map_err(|message| anyhow::anyhow!("--grid {key}: {message}"))?;
            if let Some((_, first)) = seen.iter().find(|(p, _)| same_value(p, &parsed)) {
                bail!("--grid {key}: the value `{v}` is given twice (as `{first}` and `{v}`)");
            }
            seen.push((parsed, v));
        }
        Ok(Self { key, values })
    }

    /// The name of the key in run names: its last dotted part.
    fn short(&self) -> &str {
        self.key.rsplit('.').next().unwrap_or(&self.key)
    }
}

/// Whether two TOML values are the same setting: numbers compare by value (`1` and `1.0`),
/// lists element by element, everything else exactly.
fn same_value(a: &toml::Value, b: &toml::Value) -> bool {
    use toml::Value::{Array, Float, Integer};
    match (a, b) {
        (Integer(x), Float(y)) | (Float(y), Integer(x)) => (*x as f64) == *y,
        (Array(x), Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same_value(x, y))
        }
        _ => a == b,
    }
}

/// Splits `text` at the commas outside brackets, braces and quotes.
fn split_top_level(text: &str) -> anyhow::Result<Vec<String>> {
    let (mut parts, mut current, mut depth, mut quote) = (Vec::new(), String::new(), 0i32, None);
    for c in text.chars() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, '"' | '\'') => quote = Some(c),
            (None, '[' | '{') => depth += 1,
            (None, ']' | '}') => depth -= 1,
            (None, ',') if depth == 0 => {
                parts.push(std::mem::take(&mut current));
                continue;
            }
            _ => {}
        }
        if depth < 0 {
            bail!("a `]` or `}}` without its opening bracket");
        }
        current.push(c);
    }
    if depth != 0 || quote.is_some() {
        bail!("an unclosed bracket or quote");
    }
    parts.push(current);
    Ok(parts)
}

/// The keys a sweep sets in every run itself (from `--env`, `--seeds`, `--epochs`,
/// `--steps-per-epoch`): refused in `--grid` and `--set`, where they would be overridden.
const SWEEP_KEYS: [(&str, &str); 4] = [
    ("env", "--env"),
    ("seed", "--seeds"),
    ("epochs", "--epochs"),
    ("steps_per_epoch", "--steps-per-epoch"),
];

/// The most runs a sweep may have unless `--max-runs` raises it.
pub const DEFAULT_MAX_RUNS: u64 = 10_000;

/// The most `--max-runs` may allow: a run is a process and a directory, and the sweep holds
/// every run's description at once, so the count is bounded before anything is allocated.
pub const MAX_RUNS: u64 = 1_000_000;

/// Parses `--seeds`: a list (`0,1,2`) or a range (`0..5`, end excluded) of at most
/// `max` seeds, counted before anything is allocated; a seed listed twice is refused.
///
/// # Errors
/// Bad syntax, an empty or too long list, a seed above `i64::MAX`, or a repeated seed.
pub fn parse_seeds(text: &str, max: u64) -> anyhow::Result<Vec<u64>> {
    let max = max.min(MAX_RUNS);
    // the text as the errors quote it (an excerpt of a long one)
    let shown = apo_train::input::excerpt(text);
    let bad = || format!("--seeds expects a list (0,1,2) or a range (0..5), got `{shown}`");
    let seeds: Vec<u64> = match text.split_once("..") {
        Some((a, b)) => {
            let (a, b): (u64, u64) = (
                a.trim().parse().with_context(bad)?,
                b.trim().parse().with_context(bad)?,
            );
            if a > i64::MAX as u64 {
                bail!(
                    "--seeds {shown}: seed {a} is out of the range 0..={}",
                    i64::MAX
                );
            }
            if b <= a {
                bail!(
                    "--seeds {shown} is an empty range: its end is excluded, so it must be above its start \
                     (e.g. {a}..{} for the seed {a} alone)",
                    a.saturating_add(1)
                );
            }
            let count = b - a;
            if count > max.min(MAX_RUNS) {
                bail!(
                    "--seeds {shown} is {count} seeds, more than the {max} runs a sweep may have \
                     (raise the limit with --max-runs)"
                );
            }
            (a..b).collect()
        }
        None if text.split(',').count() as u64 > max => bail!(
            "--seeds {shown} lists {} seeds, more than the {max} runs a sweep may have \
             (raise the limit with --max-runs, up to {MAX_RUNS})",
            text.split(',').count()
        ),
        None => text
            .split(',')
            .map(|s| s.trim().parse::<u64>())
            .collect::<Result<_, _>>()
            .with_context(bad)?,
    };
    if seeds.is_empty() {
        bail!("{}", bad());
    }
    if let Some(s) = seeds.iter().find(|&&s| s > i64::MAX as u64) {
        bail!(
            "--seeds {shown}: seed {s} is out of the range 0..={}",
            i64::MAX
        );
    }
    let mut seen = BTreeSet::new();
    if let Some(s) = seeds.iter().find(|s| !seen.insert(**s)) {
        bail!("--seeds {shown}: seed {s} is listed twice");
    }
    Ok(seeds)
}

/// What a sweep runs (recorded as `sweep.toml`; a key it does not know is refused, so an
/// edited record never drops a setting silently).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
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
    /// The text of the `--config` file when the sweep was made ([`SweepSpec::config_text_of`]):
    /// a sweep run again with an edited file is refused, since its runs hold the old one
    /// (absent in records of sweeps made before it was kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub config_text: Option<String>,
    /// `--set` of every run.
    pub sets: Vec<String>,
    /// Environment steps per epoch of every run (`None`: the config's).
    pub steps_per_epoch: Option<usize>,
}

impl SweepSpec {
    /// The text of `config` (the sweep's `--config` file), to record in [`SweepSpec::config_text`].
    ///
    /// # Errors
    /// A file that cannot be read, naming it.
    pub fn config_text_of(config: Option<&Path>) -> anyhow::Result<Option<String>> {
        config
            .map(|path| {
                apo_train::input::read_text(path, "config file", apo_train::input::SMALL_FILE)
            })
            .transpose()
    }

    /// The parts of the sweep in which `self` and `other` differ, by their flag.
    fn differences(&self, other: &SweepSpec) -> Vec<&'static str> {
        let mut differ = Vec::new();
        let mut check = |same: bool, what: &'static str| {
            if !same {
                differ.push(what);
            }
        };
        check(self.envs == other.envs, "--env");
        check(self.algos == other.algos, "--algo");
        check(self.seeds == other.seeds, "--seeds");
        check(self.grid == other.grid, "--grid");
        check(self.preset == other.preset, "--preset");
        check(self.config == other.config, "--config (the file's path)");
        check(
            self.config_text.is_none()
                || other.config_text.is_none()
                || self.config_text == other.config_text,
            "--config (the file's contents: it was edited since the sweep was made)",
        );
        check(self.sets == other.sets, "--set");
        check(
            self.steps_per_epoch == other.steps_per_epoch,
            "--steps-per-epoch",
        );
        differ
    }
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
    /// What the run learns with ([`RunConfig::learned_with`]): a folder of this name that holds
    /// a run of other settings is not the sweep's, and is left alone.
    pub learned_with: BTreeMap<String, String>,
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
    use apo_train::run_config::ConfigFileError as E;
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
pub fn expand(spec: &SweepSpec, epochs: usize, max_runs: u64) -> anyhow::Result<Vec<SweepRun>> {
    let preset = parse_preset(&spec.preset)?;
    let algos = spec
        .algos
        .iter()
        .map(|a| a.parse::<Algorithm>().map_err(anyhow::Error::msg))
        .collect::<anyhow::Result<Vec<_>>>()?;
    check_distinct(
        "--algo",
        algos.iter().map(|a| a.name().to_string()).zip(&spec.algos),
    )?;
    let env_names = spec
        .envs
        .iter()
        .map(|e| Ok(apo_envs::registry::spec(e)?.name))
        .collect::<anyhow::Result<Vec<String>>>()?;
    check_distinct("--env", env_names.iter().cloned().zip(&spec.envs))?;
    for (text, flag) in spec.grid.iter().map(|a| (a.key.as_str(), "--grid")).chain(
        spec.sets
            .iter()
            .map(|s| (s.split('=').next().unwrap_or(s), "--set")),
    ) {
        let key = text.trim();
        if let Some((_, own)) = SWEEP_KEYS.iter().find(|(k, _)| *k == key) {
            bail!("{flag} {key}: the sweep sets `{key}` of every run itself; use {own}");
        }
    }
    let mut keys = BTreeSet::new();
    if let Some(axis) = spec.grid.iter().find(|a| !keys.insert(a.key.as_str())) {
        bail!(
            "--grid {}: the axis is given twice; give its values in one --grid",
            axis.key
        );
    }
    apo_train::run_config::check_repeated_sets(&spec.sets)?;
    for axis in &spec.grid {
        let key = apo_train::run_config::same_key(&axis.key);
        if let Some(set) = spec.sets.iter().find(|s| {
            s.split_once('=')
                .is_some_and(|(k, _)| apo_train::run_config::same_key(k) == key)
        }) {
            bail!(
                "--grid {} and --set {set} set one key twice: the grid gives each run its value; drop the --set",
                axis.key
            );
        }
    }
    if let Some(config) = &spec.config {
        if let Some(section) = apo_train::run_config::file_algorithm(config)? {
            if let Some(other) = algos.iter().find(|a| **a != section) {
                bail!(
                    "--config {} holds the section [algo.{section}], which the runs of {other} cannot use: a sweep \
                     with a config file that has an algorithm section runs that algorithm only (--algo {section}); \
                     for several algorithms, give a file without [algo.*] and set their keys with --grid or --set",
                    config.display()
                );
            }
        }
    }
    let count = count_runs(spec, &algos)?;
    let max_runs = max_runs.min(MAX_RUNS);
    if count > max_runs {
        bail!(
            "the sweep has {count} runs ({} environments × {} algorithms × their grid cells × {} seeds), more \
             than {max_runs}; raise the limit with --max-runs (up to {MAX_RUNS}) if that is meant",
            spec.envs.len(),
            algos.len(),
            spec.seeds.len()
        );
    }
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
    for env_name in &env_names {
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
                    let mut name = format!("{}-{algo}", run_dir::env_label(env_name));
                    for ((_, v), axis) in cell.iter().zip(&axes) {
                        let v: String = v
                            .chars()
                            .filter(|c| !c.is_whitespace())
                            .map(|c| if matches!(c, '/' | '\\') { '_' } else { c })
                            .collect();
                        name.push_str(&format!("-{}={v}", axis.short()));
                    }
                    name.push_str(&format!("-s{seed}"));
                    let mut run = SweepRun {
                        env: env_name.clone(),
                        algo,
                        cell: cell.clone(),
                        seed,
                        name,
                        learned_with: BTreeMap::new(),
                    };
                    let mut sets = run.sets(spec);
                    sets.push(format!("seed={seed}"));
                    sets.push(format!("epochs={epochs}"));
                    sets.extend(spec.steps_per_epoch.map(|n| format!("steps_per_epoch={n}")));
                    let config = RunConfig::build_with_preset(
                        algo,
                        env_name,
                        preset,
                        spec.config.as_deref(),
                        &sets,
                    )
                    .with_context(|| format!("run {}", run.name))?;
                    run.learned_with = config.learned_with();
                    let env = apo_envs::registry::spec(env_name)?;
                    config
                        .check_memory(
                            env.observation_dim,
                            apo_train::action_kind(&env.action_space),
                        )
                        .with_context(|| format!("run {}", run.name))?;
                    runs.push(run);
                }
            }
        }
    }
    let mut names = BTreeSet::new();
    if let Some(run) = runs.iter().find(|r| !names.insert(r.name.as_str())) {
        bail!(
            "two runs of the sweep would share the directory {} (grid keys with the same last part?); \
             sweep them separately",
            run.name
        );
    }
    Ok(runs)
}

/// Refuses a list with two entries that mean the same (`canonical`, as given).
fn check_distinct<'a>(
    flag: &str,
    items: impl Iterator<Item = (String, &'a String)>,
) -> anyhow::Result<()> {
    let mut seen: BTreeMap<String, &String> = BTreeMap::new();
    for (canonical, given) in items {
        if let Some(first) = seen.insert(canonical.clone(), given) {
            bail!("{flag}: `{first}` and `{given}` are the same ({canonical}); give each once");
        }
    }
    Ok(())
}

/// The number of runs of the sweep, counted without building them (an overflow counts as
/// too many).
fn count_runs(spec: &SweepSpec, algos: &[Algorithm]) -> anyhow::Result<u64> {
    let mut total: u64 = 0;
    for &algo in algos {
        let mut cells: u64 = 1;
        for axis in spec
            .grid
            .iter()
            .filter(|axis| applies(algo, &axis.key, &axis.values[0]))
        {
            cells = cells.saturating_mul(axis.values.len() as u64);
        }
        total = total.saturating_add(cells.saturating_mul(spec.seeds.len() as u64));
    }
    Ok(total.saturating_mul(spec.envs.len() as u64))
}

/// Where a run of the sweep stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunStatus {
    /// No run directory yet.
    New,
    /// A run directory whose checkpoint is at epoch `done`, before the target: resumed.
    Interrupted {
        /// Epochs done.
        done: usize,
    },
    /// A run directory without a checkpoint: started again with `--force` (which removes only
    /// what apo created there).
    Failed,
    /// The checkpoint has reached the target epoch, or, for a run kept without its
    /// checkpoints (results committed as `config.toml` and `progress.csv`), its progress file
    /// has.
    Finished,
}

/// Refuses, before anything starts, a folder at a run's place that the sweep would not have
/// made: a symbolic link (the sweep would train through it, outside its folder), or a run
/// whose `config.toml` learns with other settings than the sweep gives `run` (it would be
/// continued and reported as the sweep's).
///
/// # Errors
/// Naming the folder and, for another run, the first setting that differs with both values.
pub fn check_own(dir: &Path, run: &SweepRun) -> anyhow::Result<()> {
    if apo_train::removal::is_link(dir) {
        bail!(
            "{} is a symbolic link: a sweep trains only in the folders it made inside --out; the sweep stops \
             and touches nothing (move the link away)",
            dir.display()
        );
    }
    match std::fs::symlink_metadata(dir) {
        Err(_) => return Ok(()),
        Ok(meta) if !meta.is_dir() => bail!(
            "{} is a file, not a run of the sweep; the sweep stops and touches nothing (move it away)",
            dir.display()
        ),
        Ok(_) => {}
    }
    let config = dir.join(run_dir::CONFIG);
    if std::fs::symlink_metadata(&config).is_err() {
        // a folder of the user's at the run's place (apo made neither its marker nor a run)
        let empty = std::fs::read_dir(dir).is_ok_and(|mut e| e.next().is_none());
        if !empty && run_dir::created_entries(dir)?.is_none() {
            bail!(
                "{} holds files apo did not make and no run; the sweep stops and touches nothing \
                 (move the folder away, or use a new --out)",
                dir.display()
            );
        }
        return Ok(());
    }
    let found = run_dir::load_config(dir)
        .map_err(|e| anyhow::anyhow!("{e:#}; the sweep stops and touches nothing"))?
        .learned_with();
    let keys: BTreeSet<&String> = found.keys().chain(run.learned_with.keys()).collect();
    if let Some(key) = keys
        .into_iter()
        .find(|k| found.get(*k) != run.learned_with.get(*k))
    {
        let shown = |v: Option<&String>| v.map_or_else(|| "(none)".to_string(), |v| v.clone());
        bail!(
            "{} holds a run of other settings than the sweep gives it ({key}: the run has {}, the sweep {}); \
             the sweep stops and touches nothing (move the run away, or use a new --out)",
            dir.display(),
            shown(found.get(key)),
            shown(run.learned_with.get(key))
        );
    }
    Ok(())
}

/// Epochs recorded in `dir/progress.csv` (0 without one, or when it cannot be read): for the
/// progress bar only.
pub fn epochs_done(dir: &Path) -> usize {
    progress_csv::read_lenient(&dir.join(run_dir::PROGRESS), true).map_or(0, |p| p.rows.len())
}

/// The status of the run in `dir` whose target is `epochs` epochs, decided by its checkpoint;
/// without one, a run whose `config.toml` is there and whose `progress.csv` has reached the
/// target is finished (a finished run kept without its checkpoints), any other has failed.
///
/// # Errors
/// A checkpoint whose state cannot be read, or recorded epochs without a checkpoint short of
/// the target (the run is then left alone).
pub fn status(dir: &Path, epochs: usize) -> anyhow::Result<RunStatus> {
    if std::fs::symlink_metadata(dir).is_err() {
        return Ok(RunStatus::New);
    }
    Ok(match apo_train::checkpoint::latest_epoch(dir)? {
        Some(done) if done >= epochs => RunStatus::Finished,
        Some(done) if done > 0 => RunStatus::Interrupted { done },
        Some(_) => RunStatus::Failed,
        None => {
            let recorded = progress_csv::read_lenient(&dir.join(run_dir::PROGRESS), false)
                .map_or(0, |p| p.rows.last().map_or(0, |r| r.epoch));
            if recorded >= epochs && dir.join(run_dir::CONFIG).is_file() {
                RunStatus::Finished
            } else if recorded > 0 {
                // recorded epochs are never trained over: the run cannot continue without its
                // checkpoint, and replacing it would lose them
                bail!(
                    "{} records {recorded} epoch(s) but has no checkpoint, so it cannot continue to {epochs}; \
                     a sweep never replaces recorded epochs (restore its checkpoints, or move the run away)",
                    dir.display()
                )
            } else {
                RunStatus::Failed
            }
        }
    })
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

/// The copy of the sweep's `--config` text its runs are made from (`sweep.toml`'s
/// `config_text`), so that a file edited while the sweep runs changes none of them.
pub const CONFIG_COPY: &str = "sweep-config.toml";

/// Writes `out/`[`CONFIG_COPY`] with the recorded config text, or checks the one there.
fn write_config_copy(out: &Path, spec: &SweepSpec) -> anyhow::Result<()> {
    let Some(text) = &spec.config_text else {
        return Ok(());
    };
    let path = out.join(CONFIG_COPY);
    if std::fs::symlink_metadata(&path).is_ok() {
        let there =
            apo_train::input::read_text(&path, "sweep config copy", apo_train::input::SMALL_FILE)?;
        if &there != text {
            bail!(
                "{} differs from the --config text the sweep recorded; apo does not overwrite it: move it away",
                path.display()
            );
        }
        return Ok(());
    }
    apo_train::atomic::write(&path, text.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Checks `out/sweep.toml` against `spec` (writing it for a new sweep), and the copy of the
/// config text the runs are made from.
pub(crate) fn record(out: &Path, spec: &SweepSpec) -> anyhow::Result<()> {
    record_spec(out, spec)?;
    write_config_copy(out, spec)
}

/// Checks `out/sweep.toml` against `spec` (writing it for a new sweep).
fn record_spec(out: &Path, spec: &SweepSpec) -> anyhow::Result<()> {
    let path = out.join("sweep.toml");
    let text = toml::to_string_pretty(spec).context("serializing the sweep")?;
    if std::fs::symlink_metadata(out).is_ok() && !out.is_dir() {
        bail!(
            "--out {} exists and is not a directory; use a new --out",
            out.display()
        );
    }
    if std::fs::symlink_metadata(&path).is_ok() {
        let old = read_record(out)?;
        let differ = old.differences(spec);
        if !differ.is_empty() {
            bail!(
                "{} holds another sweep: its sweep.toml differs in {}; use a new --out",
                out.display(),
                differ.join(", ")
            );
        }
        return Ok(());
    }
    let occupied = std::fs::read_dir(out).is_ok_and(|mut entries| entries.next().is_some());
    if occupied {
        bail!(
            "--out {} exists and is not a sweep directory (no sweep.toml); use a new --out",
            out.display()
        );
    }
    let created = apo_train::input::prepare_output_dir(out, "--out")?;
    apo_train::atomic::write(&path, text.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))
        .inspect_err(|_| created.remove_if_empty())
}

/// Checks, before the sweep creates anything, that every run's folder name fits the file
/// system of `out` (a run's name holds its grid values, which can be long).
///
/// # Errors
/// Naming the first run whose name is too long, its length and the limit.
pub fn check_run_names(out: &Path, runs: &[SweepRun]) -> anyhow::Result<()> {
    for run in runs {
        if let Some((name, length, max)) = apo_train::input::too_long_name(&out.join(&run.name)) {
            bail!(
                "--out {}: the folder name {name} is {length} bytes long; its file system takes at most {max}{}",
                out.display(),
                if name == run.name {
                    " (a run's name holds its grid values: give them with fewer digits)"
                } else {
                    ""
                }
            );
        }
    }
    Ok(())
}

/// The lock file of a sweep's directory, held while a sweep runs or submits its runs.
pub const SWEEP_LOCK: &str = "apo-sweep.lock";

/// Locks the sweep's directory `out` (made by [`record`]): a second sweep of it, local or
/// submitting to Slurm, is refused while this one holds it.
///
/// # Errors
/// Another apo holds it (naming its process).
pub(crate) fn lock_sweep(out: &Path) -> anyhow::Result<run_dir::RunLock> {
    run_dir::RunLock::acquire_at(
        &out.join(SWEEP_LOCK),
        &format!("sweep directory {}", out.display()),
    )
}

/// The sweep recorded in `out/sweep.toml`.
///
/// # Errors
/// No record, or one that cannot be read or parsed, naming the file.
pub fn read_record(out: &Path) -> anyhow::Result<SweepSpec> {
    let path = out.join("sweep.toml");
    let text = apo_train::input::read_text(&path, "sweep record", apo_train::input::SMALL_FILE)?;
    toml::from_str(&text).with_context(|| format!("{} is not a sweep record", path.display()))
}

/// The child `apo train` command of `run`, whose directory `dir` has `status`.
pub(crate) fn command(
    exe: &Path,
    spec: &SweepSpec,
    run: &SweepRun,
    options: &SweepOptions,
    dir: &Path,
    status: RunStatus,
) -> Command {
    let mut cmd = Command::new(exe);
    cmd.arg("train").arg("--quiet");
    cmd.arg("--threads").arg(options.threads.to_string());
    match status {
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
    match (&spec.config, &spec.config_text) {
        // the text the sweep recorded, not the file as it is now (it may be edited mid-sweep)
        (Some(_), Some(_)) => {
            cmd.arg("--config").arg(options.out.join(CONFIG_COPY));
        }
        (Some(config), None) => {
            cmd.arg("--config").arg(config);
        }
        (None, _) => {}
    }
    for set in run.sets(spec) {
        cmd.arg("--set").arg(set);
    }
    cmd.arg("--out").arg(dir);
    cmd
}

/// The signals a sweep has received: how many, and the last one's number. Each is forwarded
/// to every running child.
#[derive(Debug, Default)]
pub struct Received {
    /// Signals received so far.
    pub count: AtomicUsize,
    /// The number of the last one (SIGINT 2, SIGTERM 15).
    pub which: AtomicUsize,
}

impl Received {
    fn stopped(&self) -> bool {
        self.count.load(Ordering::SeqCst) > 0
    }
}

/// The last lines of a child's stderr kept for the failure message.
const TAIL_LINES: usize = 3;

/// Runs one child to its end: spawned in its own process group (a terminal's Ctrl-C reaches
/// the sweep only, which forwards it), registered in `running` so that signals reach it, its
/// stderr drained (only the last lines kept).
fn run_child(
    mut cmd: Command,
    slot: usize,
    running: &Mutex<BTreeMap<usize, (u32, usize)>>,
) -> std::io::Result<(std::process::ExitStatus, String)> {
    cmd.stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    own_process_group(&mut cmd);
    let mut child = cmd.spawn()?;
    lock(running).insert(slot, (child.id(), 0));
    let mut tail: std::collections::VecDeque<String> = std::collections::VecDeque::new();
    if let Some(stderr) = child.stderr.take() {
        for line in BufReader::new(stderr).lines() {
            let Ok(line) = line else { break };
            if tail.len() == TAIL_LINES {
                tail.pop_front();
            }
            tail.push_back(line);
        }
    }
    let status = child.wait();
    lock(running).remove(&slot);
    Ok((status?, Vec::from(tail).join(" | ")))
}

/// Starts `cmd` in its own process group (a terminal's Ctrl-C reaches the sweep only, which
/// passes it on) with SIGTERM as its parent-death signal: a sweep killed outright (SIGKILL,
/// OOM) stops its runs, which checkpoint, instead of leaving them training as orphans.
pub(crate) fn own_process_group(cmd: &mut Command) {
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        cmd.process_group(0);
    }
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::process::CommandExt;
        // SAFETY: prctl is async-signal-safe; it only sets this child's parent-death signal
        unsafe {
            cmd.pre_exec(|| {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) == -1 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
    }
}

/// Sends the signal `which` to the child `pid` (one not waited for yet: its pid stays
/// reserved).
pub(crate) fn send(pid: u32, which: usize) {
    #[cfg(unix)]
    if let (Ok(pid), Ok(sig)) = (i32::try_from(pid), i32::try_from(which)) {
        // SAFETY: kill(2) with a child's pid, which stays reserved until it is waited for
        unsafe {
            libc::kill(pid, sig);
        }
    }
}

/// Sends each running child the signals it has not been sent yet.
fn forward(signals: &Received, running: &Mutex<BTreeMap<usize, (u32, usize)>>) {
    let count = signals.count.load(Ordering::SeqCst);
    let which = signals.which.load(Ordering::SeqCst);
    for (pid, sent) in lock(running).values_mut() {
        while *sent < count {
            send(*pid, which);
            *sent += 1;
        }
    }
}

/// Runs the sweep: `runs` (from [`expand`]) under `options.out`, `options.jobs` at a time,
/// each as `exe train …`. `tick(epochs_done_over_all_runs, runs_done)` is called about every
/// second. Once a signal is received (`signals`), no run is launched, each running child gets
/// the signal (and every later one) and the sweep waits for all of them to end.
///
/// Before anything is launched, every existing run's checkpoint is read: one that cannot be
/// read stops the sweep with its path, and nothing is touched.
///
/// # Errors
/// When the directory holds another sweep or cannot be written, or a run's checkpoint
/// cannot be read.
pub fn run(
    exe: &Path,
    spec: &SweepSpec,
    runs: &[SweepRun],
    options: &SweepOptions,
    signals: &Received,
    tick: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<SweepOutcome> {
    check_run_names(&options.out, runs)?;
    record(&options.out, spec)?;
    let _lock = lock_sweep(&options.out)?;
    let statuses = runs
        .iter()
        .map(|r| {
            let dir = options.out.join(&r.name);
            check_own(&dir, r)?;
            status(&dir, options.epochs).with_context(|| {
                format!(
                    "run {}: the sweep stops and touches nothing (repair or move the run)",
                    dir.display()
                )
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let outcome = Mutex::new(SweepOutcome::default());
    let running = Mutex::new(BTreeMap::new());
    let workers_left = AtomicUsize::new(options.jobs.max(1));
    std::thread::scope(|scope| {
        for _ in 0..options.jobs.max(1) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    let (Some(run), Some(&status)) = (runs.get(i), statuses.get(i)) else {
                        break;
                    };
                    if signals.stopped() {
                        break;
                    }
                    let dir = options.out.join(&run.name);
                    if status == RunStatus::Finished {
                        lock(&outcome).skipped += 1;
                        done.fetch_add(1, Ordering::SeqCst);
                        continue;
                    }
                    let result =
                        run_child(command(exe, spec, run, options, &dir, status), i, &running);
                    let mut outcome = lock(&outcome);
                    match result {
                        Ok((exit, _)) if exit.success() => outcome.finished += 1,
                        Ok(_) | Err(_) if signals.stopped() => {}
                        Ok((exit, tail)) => {
                            let tail = if tail.is_empty() {
                                "(nothing on stderr)".to_string()
                            } else {
                                tail
                            };
                            outcome
                                .failed
                                .push((run.name.clone(), format!("{exit}: {tail}")))
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
        let mut last_tick = std::time::Instant::now() - std::time::Duration::from_secs(1);
        while workers_left.load(Ordering::SeqCst) > 0 {
            forward(signals, &running);
            if last_tick.elapsed() >= std::time::Duration::from_secs(1) {
                let epochs: usize = runs
                    .iter()
                    .map(|r| epochs_done(&options.out.join(&r.name)).min(options.epochs))
                    .sum();
                tick(epochs, done.load(Ordering::SeqCst));
                last_tick = std::time::Instant::now();
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
    });
    let mut outcome = outcome
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    outcome.interrupted = signals.stopped();
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

/// One cell's result: the metric's mean and standard deviation over its finished seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct CellResult {
    /// Environment.
    pub env: String,
    /// Algorithm.
    pub algo: Algorithm,
    /// The cell's label (`omega1=0.001 omega2=0.003`, `-` without axes).
    pub cell: String,
    /// Finished seeds with a value.
    pub seeds: usize,
    /// Runs of the cell that have not finished (left out of the statistics).
    pub incomplete: usize,
    /// Finished runs trained to another number of epochs than the sweep's (an earlier sweep
    /// with a larger `--epochs`): left out, never mixed with runs of the sweep's target.
    pub other_target: usize,
    /// Finished runs whose records cannot give the metric (`progress.csv` missing or
    /// unreadable, no finite value): left out, each named in a warning.
    pub unreadable: usize,
    /// Mean over seeds (`None` without any).
    pub mean: Option<f64>,
    /// Population standard deviation over seeds (`None` without any).
    pub std: Option<f64>,
}

/// Each cell's `metric` (over the last `last` epochs where it says so), mean ± std over the
/// seeds whose run has finished exactly `epochs` epochs and has a finite value. The other runs
/// are counted apart, never mixed in: unfinished ones (`incomplete`), ones trained to another
/// epoch target (`other_target`) and finished ones whose records are missing or unreadable
/// (`unreadable`, each named in a warning on stderr). Every cell of `runs` is listed, with or
/// without a value. Sorted by environment, algorithm, then best first (cells without a value
/// last).
pub fn cell_results(
    out: &Path,
    runs: &[SweepRun],
    epochs: usize,
    metric: Metric,
    last: usize,
) -> Vec<CellResult> {
    let mut cells: BTreeMap<(String, String, String), CellResult> = BTreeMap::new();
    let mut values: BTreeMap<(String, String, String), Vec<f64>> = BTreeMap::new();
    for run in runs {
        let dir = out.join(&run.name);
        let key = (
            run.env.clone(),
            run.algo.name().to_string(),
            run.cell_label(),
        );
        let cell = cells.entry(key.clone()).or_insert_with(|| CellResult {
            env: run.env.clone(),
            algo: run.algo,
            cell: run.cell_label(),
            seeds: 0,
            incomplete: 0,
            other_target: 0,
            unreadable: 0,
            mean: None,
            std: None,
        });
        if status(&dir, epochs).ok() != Some(RunStatus::Finished) {
            cell.incomplete += 1;
            continue;
        }
        let summary = match summarize(&dir, last) {
            Ok(summary) => summary,
            Err(e) => {
                apo_train::warnln!(
                    "warning: {}: finished, but its records cannot be read, so it is left out: {e:#}",
                    dir.display()
                );
                cell.unreadable += 1;
                continue;
            }
        };
        if summary.epochs != epochs {
            apo_train::warnln!(
                "warning: {}: trained to {} epochs, not this sweep's {epochs}; left out (run the sweep with --epochs {} to count it)",
                dir.display(),
                summary.epochs,
                summary.epochs
            );
            cell.other_target += 1;
            continue;
        }
        match metric.of(&summary).filter(|v| v.is_finite()) {
            Some(v) => values.entry(key).or_default().push(v),
            None => {
                apo_train::warnln!(
                    "warning: {}: finished, but its records hold no finite value of the metric; left out",
                    dir.display()
                );
                cell.unreadable += 1;
            }
        }
    }
    let mut results: Vec<CellResult> = cells
        .into_iter()
        .map(|(key, mut cell)| {
            if let Some(values) = values.get(&key) {
                let (mean, std) = crate::summary::mean_std(values);
                cell.seeds = values.len();
                cell.mean = Some(mean);
                cell.std = Some(std);
            }
            cell
        })
        .collect();
    results.sort_by(|a, b| {
        (a.env.as_str(), a.algo.name())
            .cmp(&(b.env.as_str(), b.algo.name()))
            .then_with(|| match (a.mean, b.mean) {
                (Some(x), Some(y)) => y.total_cmp(&x),
                (Some(_), None) => std::cmp::Ordering::Less,
                (None, Some(_)) => std::cmp::Ordering::Greater,
                (None, None) => a.cell.cmp(&b.cell),
            })
    });
    results
}

/// The cells as CSV: `env,algo,cell,seeds,incomplete,other_target,unreadable,mean,std,best`
/// (mean and std empty for a cell without a value; best: the first of its environment and
/// algorithm with a value).
pub fn cells_csv(results: &[CellResult]) -> String {
    let mut out =
        String::from("env,algo,cell,seeds,incomplete,other_target,unreadable,mean,std,best\n");
    let mut previous: Option<(&str, Algorithm)> = None;
    let number = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
    for r in results {
        let best = r.mean.is_some() && previous != Some((r.env.as_str(), r.algo));
        if r.mean.is_some() {
            previous = Some((r.env.as_str(), r.algo));
        }
        out.push_str(&format!(
            "{},{},\"{}\",{},{},{},{},{},{},{}\n",
            r.env,
            r.algo,
            r.cell,
            r.seeds,
            r.incomplete,
            r.other_target,
            r.unreadable,
            number(r.mean),
            number(r.std),
            best
        ));
    }
    out
}
