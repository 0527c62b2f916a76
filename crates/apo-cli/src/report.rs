//! `apo report`: the paper's metrics per environment and algorithm, mean ± std over seeds.
//!
//! Runs are grouped by environment, algorithm and *variant*: the run directory's name without
//! its `<env>-<algo>` prefix and `-s<seed>` suffix (`Hopper-v4-apo-omega1=0.003-s2` is the
//! variant `omega1=0.003`, `Hopper-apo-s0` the empty one), so the seeds of one setting form
//! one group. Per group, over its seeds (each seed's value first averaged over epochs):
//!
//! - the average of the epochs' mean return over all epochs and over the last N;
//! - the same for the worst (minimum) return;
//! - the empirical bound `J − k·Var` and its Selberg confidence over the last N epochs;
//! - the TRPO-normalized score of the mean (over seeds) of the last-N mean and worst returns
//!   (paper, appendix "Normalized Score Settings"): with `Δ1 = agent − random` and
//!   `Δ2 = TRPO − random`, `score = Δ2 / Δ1` when both are negative, else `Δ1 / Δ2`. TRPO is
//!   the TRPO group of the same environment and variant (else the environment's first TRPO
//!   group); random is a uniformly random policy's mean return (for the mean) and worst
//!   return (for the worst) over a number of episodes.
//!
//! The count of "best" per metric (the paper's summary table) counts, for each metric, the
//! environments where a group (algorithm and variant) has the highest value (ties all count).
//!
//! [`statistics`] adds what the paper's tables lack, uncertainty (see [`crate::stats`]): for
//! each per-run metric ([`RunMetric`]: the paper's four and the risk metrics CVaR 10 % and
//! 10 % quantile over the last N epochs), every run's value is normalized per environment
//! ([`Normalization`]), and over the environments that every group has, each group's mean,
//! median, IQM and optimality gap get stratified-bootstrap intervals, each pair its probability
//! of improvement, and each group a performance profile.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use apo_core::metrics::average_over_epochs;
use apo_core::Algorithm;
use rand::{Rng, SeedableRng};

use crate::stats::{self, Analysis, Comparison, Scores, StratifiedBootstrap};
use crate::summary::{mean_std, summarize_rows, RunSummary};
use apo_train::progress_csv;
use apo_train::run_dir;

/// A value over seeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stat {
    /// Mean over the seeds that have the value.
    pub mean: f64,
    /// Population standard deviation over them.
    pub std: f64,
    /// How many seeds have it.
    pub seeds: usize,
}

impl Stat {
    /// The statistic of `values`; `None` when empty.
    pub fn of(values: &[f64]) -> Option<Self> {
        let values: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
        (!values.is_empty()).then(|| {
            let (mean, std) = mean_std(&values);
            Self {
                mean,
                std,
                seeds: values.len(),
            }
        })
    }
}

/// A random policy's returns on an environment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Baseline {
    /// Mean return.
    pub mean: f64,
    /// Worst return.
    pub worst: f64,
    /// Lower CVaR at 10 % of the returns.
    pub cvar10: f64,
    /// 10 % quantile of the returns.
    pub q10: f64,
}

/// The metrics ranked in the summary of "best" counts, in column order.
pub const METRICS: [&str; 4] = [
    "mean (all)",
    "mean (last N)",
    "worst (all)",
    "worst (last N)",
];

/// One group's metrics.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupReport {
    /// Environment.
    pub env: String,
    /// Algorithm.
    pub algo: Algorithm,
    /// The variant (see the module's documentation); "" for none.
    pub variant: String,
    /// The group's run directories.
    pub runs: Vec<PathBuf>,
    /// How many of them have not reached their config's epochs (included, and marked).
    pub incomplete: usize,
    /// Each run's metrics, in the order of `runs`.
    pub summaries: Vec<RunSummary>,
    /// Average mean return over all epochs.
    pub mean_all: Option<Stat>,
    /// Average mean return over the last N epochs.
    pub mean_last: Option<Stat>,
    /// Average worst return over all epochs.
    pub worst_all: Option<Stat>,
    /// Average worst return over the last N epochs.
    pub worst_last: Option<Stat>,
    /// Average empirical bound `J − k·Var` over the last N epochs.
    pub bound_last: Option<Stat>,
    /// Average Selberg confidence of the bound over the last N epochs.
    pub confidence_last: Option<Stat>,
    /// TRPO-normalized score of `mean_last`.
    pub score_mean: Option<f64>,
    /// TRPO-normalized score of `worst_last`.
    pub score_worst: Option<f64>,
}

impl GroupReport {
    /// `algo` or `algo (variant)`.
    pub fn label(&self) -> String {
        if self.variant.is_empty() {
            self.algo.name().to_string()
        } else {
            format!("{} ({})", self.algo, self.variant)
        }
    }

    /// The ranked metrics' means, in [`METRICS`] order.
    pub fn ranked(&self) -> [Option<f64>; 4] {
        [
            self.mean_all,
            self.mean_last,
            self.worst_all,
            self.worst_last,
        ]
        .map(|s| s.map(|s| s.mean))
    }
}

/// A report: the groups, by environment then label, and the random baselines.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// N of "the last N epochs".
    pub last: usize,
    /// Every group.
    pub groups: Vec<GroupReport>,
    /// Each environment's random baseline (where it could be measured).
    pub baselines: BTreeMap<String, Baseline>,
    /// The statistics over environments and runs, one per metric (empty unless
    /// [`statistics`] filled it).
    pub statistics: Vec<MetricStatistics>,
}

/// [`apo_core::metrics::normalized_score`], `None` when it is not finite (TRPO at the
/// random policy's level).
fn normalized_score(agent: f64, trpo: f64, random: f64) -> Option<f64> {
    Some(apo_core::metrics::normalized_score(agent, trpo, random)).filter(|s| s.is_finite())
}

/// `paths` with each directory once, by its canonical path, in the order given (a run named
/// twice, e.g. as `runs/a` and `runs/./a`, is counted once, with a note). A path that does not
/// exist is kept as it is, for its reader to name.
fn distinct_runs(paths: &[PathBuf]) -> Vec<PathBuf> {
    let mut seen = std::collections::BTreeSet::new();
    let mut runs = Vec::new();
    for path in paths {
        let canonical = std::fs::canonicalize(path).unwrap_or_else(|_| path.clone());
        if seen.insert(canonical) {
            runs.push(path.clone());
        } else {
            apo_train::warnln!("note: {} is listed twice; it counts once", path.display());
        }
    }
    runs
}

/// The run directories among `paths`: a path that holds a run's records (`config.toml` or
/// `progress.csv`, read and checked by the caller), or, for a folder that holds neither, the
/// run directories directly inside it (a sweep's folder), sorted; each run once, by its
/// canonical path (a run named twice, e.g. as `runs/a` and `runs/./a`, counts once, with a
/// note).
///
/// # Errors
/// A path that does not exist or holds no run.
pub fn find_runs(paths: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut runs = Vec::new();
    for path in paths {
        if path.join(run_dir::CONFIG).exists() || path.join(run_dir::PROGRESS).exists() {
            runs.push(path.clone());
            continue;
        }
        match std::fs::metadata(path) {
            Err(e) => bail!(
                "{}: {e}: it is neither a run directory nor a folder of runs (a run directory has a {} or {})",
                path.display(),
                run_dir::CONFIG,
                run_dir::PROGRESS
            ),
            Ok(m) if !m.is_dir() => bail!(
                "{} is not a folder: it is neither a run directory nor a folder of runs",
                path.display()
            ),
            Ok(_) => {}
        }
        let entries = std::fs::read_dir(path)
            .with_context(|| format!("cannot list the runs of {}", path.display()))?;
        let mut inside: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| run_dir::is_run_dir(p))
            .collect();
        if inside.is_empty() {
            bail!(
                "{} is not a run directory (it has neither {} nor {}) and holds no run directory",
                path.display(),
                run_dir::PROGRESS,
                run_dir::CONFIG
            );
        }
        inside.sort();
        runs.extend(inside);
    }
    Ok(distinct_runs(&runs))
}

/// The variant of a run directory named `name` of `algo` on `env` (see the module's
/// documentation).
pub fn variant(name: &str, env: &str, algo: Algorithm) -> String {
    let without_seed = match name.rsplit_once("-s") {
        Some((head, seed)) if !seed.is_empty() && seed.bytes().all(|b| b.is_ascii_digit()) => head,
        _ => name,
    };
    let env = run_dir::env_label(env);
    let base = env.rsplit_once("-v").map_or(env.as_str(), |(b, _)| b);
    for prefix in [format!("{env}-{algo}"), format!("{base}-{algo}")] {
        if let Some(rest) = without_seed.strip_prefix(&prefix) {
            return rest.trim_start_matches('-').to_string();
        }
    }
    without_seed.to_string()
}

/// The average of one progress column over the last `last` epochs of a run's rows.
fn last_average(
    rows: &[progress_csv::ProgressRow],
    column: fn(&progress_csv::ProgressRow) -> Option<f64>,
    last: usize,
) -> Option<f64> {
    let values: Vec<f64> = rows.iter().filter_map(column).collect();
    average_over_epochs(&values, Some(last))
}

/// The report of the runs in `runs` with the last `last` epochs; `baseline(env, options)`
/// gives an environment's random baseline, built as the first of its runs builds it (its
/// action mapping and time limit; episodes seeded by the baseline), and an error leaves that
/// environment's scores out.
///
/// # Errors
/// A run whose `config.toml` or `progress.csv` cannot be read. A run that has an
/// `episodes.csv` has its return statistics recomputed from it (every episode counted).
pub fn report(
    runs: &[PathBuf],
    last: usize,
    baseline: &mut dyn FnMut(&str, &apo_envs::MakeOptions) -> anyhow::Result<Baseline>,
) -> anyhow::Result<Report> {
    // (environment, algorithm, variant, epoch target): runs of another target are never seeds
    // of one group
    type Key = (String, String, String, usize);
    let mut by_target: BTreeMap<Key, (Algorithm, Vec<PathBuf>)> = BTreeMap::new();
    let mut options = BTreeMap::new();
    let mut targets = BTreeMap::new();
    // a run's identity is what it learned with, not its path: a copy counts once
    let mut identities: BTreeMap<BTreeMap<String, String>, PathBuf> = BTreeMap::new();
    for dir in runs {
        let config = run_dir::load_config(dir)?;
        // a run is reported with the config it learned with
        apo_train::checkpoint::check_bound(dir, &config)
            .with_context(|| format!("run {}", dir.display()))?;
        targets.insert(
            dir.clone(),
            (config.train.epochs, config.train.algo.probability_factor()),
        );
        // `CartPole` and `cartpole-v1` are one environment
        let env = apo_envs::registry::canonical_name(&config.train.env)
            .unwrap_or_else(|_| config.train.env.clone());
        options.entry(env.clone()).or_insert(apo_envs::MakeOptions {
            fixed_reset_seed: None,
            ..config.train.make_options()
        });
        let algo = config.train.algo.algorithm();
        let name = dir
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let variant = variant(&name, &config.train.env, algo);
        let mut identity = config.learned_with();
        identity.insert("\u{0}variant".into(), variant.clone());
        if let Some(first) = identities.get(&identity) {
            apo_train::warnln!(
                "note: {} is the same run as {} (the same environment, algorithm, settings and seed); it counts once",
                dir.display(),
                first.display()
            );
            continue;
        }
        identities.insert(identity, dir.clone());
        by_target
            .entry((env, algo.name().to_string(), variant, config.train.epochs))
            .or_insert_with(|| (algo, Vec::new()))
            .1
            .push(dir.clone());
    }
    // a setting run to several epoch targets is reported once per target, its label saying
    // which
    let mut targets_of: BTreeMap<(String, String, String), Vec<usize>> = BTreeMap::new();
    for (env, algo, variant, epochs) in by_target.keys() {
        targets_of
            .entry((env.clone(), algo.clone(), variant.clone()))
            .or_default()
            .push(*epochs);
    }
    let mut groups: BTreeMap<(String, String, String), (Algorithm, Vec<PathBuf>)> = BTreeMap::new();
    for ((env, algo_name, variant, epochs), group) in by_target {
        let several = &targets_of[&(env.clone(), algo_name.clone(), variant.clone())];
        let variant = if several.len() > 1 {
            if epochs == several[0] {
                apo_train::warnln!(
                "note: the runs of {env} {algo_name}{} have different epoch targets ({}); they are reported apart",
                if variant.is_empty() { String::new() } else { format!(" ({variant})") },
                several.iter().map(usize::to_string).collect::<Vec<_>>().join(", ")
                );
            }
            if variant.is_empty() {
                format!("epochs={epochs}")
            } else {
                format!("{variant} epochs={epochs}")
            }
        } else {
            variant
        };
        groups.insert((env, algo_name, variant), group);
    }
    let mut reports = Vec::new();
    for ((env, _, variant), (algo, dirs)) in groups {
        let mut columns: [Vec<f64>; 6] = Default::default();
        let mut incomplete = 0;
        let mut summaries = Vec::new();
        for dir in &dirs {
            let (target, k) = targets.get(dir).copied().unwrap_or((0, 0.0));
            let mut rows =
                crate::summary::run_rows(dir).with_context(|| format!("run {}", dir.display()))?;
            // the episodes, where the run recorded them, are what its statistics are made of
            apo_train::episodes_csv::recompute_rows(&mut rows, dir, k)
                .with_context(|| format!("run {}", dir.display()))?;
            if rows.last().map_or(0, |r| r.epoch) < target {
                incomplete += 1;
            }
            let s = summarize_rows(&rows, last);
            let bound = last_average(&rows, |r| r.bound, last);
            let confidence = last_average(&rows, |r| r.confidence, last);
            for (column, value) in columns.iter_mut().zip([
                s.mean_all,
                s.mean_last,
                s.worst_all,
                s.worst_last,
                bound,
                confidence,
            ]) {
                column.extend(value);
            }
            summaries.push(s);
        }
        let [mean_all, mean_last, worst_all, worst_last, bound_last, confidence_last] =
            columns.map(|c| Stat::of(&c));
        reports.push(GroupReport {
            env,
            algo,
            variant,
            runs: dirs,
            incomplete,
            summaries,
            mean_all,
            mean_last,
            worst_all,
            worst_last,
            bound_last,
            confidence_last,
            score_mean: None,
            score_worst: None,
        });
    }
    let mut baselines = BTreeMap::new();
    for (env, options) in options {
        match baseline(&env, &options) {
            Ok(b) => {
                baselines.insert(env, b);
            }
            Err(e) => apo_train::warnln!("note: no random baseline for {env}, so no scores: {e:#}"),
        }
    }
    let reference: Vec<Option<(f64, f64)>> = reports
        .iter()
        .map(|g| {
            let trpo = |same_variant: bool| {
                reports.iter().find(|t| {
                    t.env == g.env
                        && t.algo == Algorithm::Trpo
                        && (!same_variant || t.variant == g.variant)
                })
            };
            let t = trpo(true).or_else(|| trpo(false))?;
            Some((t.mean_last?.mean, t.worst_last?.mean))
        })
        .collect();
    for (g, reference) in reports.iter_mut().zip(reference) {
        let (Some((trpo_mean, trpo_worst)), Some(random)) = (reference, baselines.get(&g.env))
        else {
            continue;
        };
        g.score_mean = g
            .mean_last
            .and_then(|s| normalized_score(s.mean, trpo_mean, random.mean));
        g.score_worst = g
            .worst_last
            .and_then(|s| normalized_score(s.mean, trpo_worst, random.worst));
    }
    Ok(Report {
        last,
        groups: reports,
        baselines,
        statistics: Vec::new(),
    })
}

/// A uniformly random policy's returns on `env` built with `options` over `episodes` episodes
/// seeded from `seed` (actions uniform in the action box, or uniform over the discrete
/// actions).
///
/// # Errors
/// When the environment cannot be made.
pub fn random_baseline(
    env: &str,
    options: &apo_envs::MakeOptions,
    episodes: usize,
    seed: u64,
) -> anyhow::Result<Baseline> {
    use apo_envs::{Action, Space};
    let mut e = apo_envs::make_with(env, options)?;
    let mut obs = vec![0.0f32; e.observation_space().flat_dim()];
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let space = e.action_space().clone();
    let mut action = vec![0.0f32; space.flat_dim()];
    let mut returns = Vec::with_capacity(episodes);
    for episode in 0..episodes {
        e.reset(Some(seed.wrapping_add(episode as u64)), &mut obs);
        let mut total = 0.0;
        loop {
            let t = match &space {
                Space::Discrete { n } => {
                    e.step(Action::Discrete(rng.random_range(0..*n)), &mut obs)
                }
                Space::Box { low, high, .. } => {
                    // in the box the policy acts in: [-1, 1] when rescaled, else the
                    // environment's own bounds ([-1, 1] where those are not finite)
                    for ((a, &lo), &hi) in action.iter_mut().zip(low).zip(high) {
                        let (lo, hi) = if lo.is_finite() && hi.is_finite() && lo <= hi {
                            (lo, hi)
                        } else {
                            (-1.0, 1.0)
                        };
                        *a = rng.random_range(lo..=hi);
                    }
                    e.step(Action::Continuous(&action), &mut obs)
                }
            };
            total += t.reward;
            if t.terminated || t.truncated {
                break;
            }
        }
        returns.push(total);
    }
    let (mean, _) = mean_std(&returns);
    returns.sort_by(f64::total_cmp);
    let worst = returns.first().copied().unwrap_or(f64::NAN);
    if !(mean.is_finite() && worst.is_finite() && returns.iter().all(|r| r.is_finite())) {
        bail!("the random policy's returns on {env} are not finite");
    }
    Ok(Baseline {
        mean,
        worst,
        cvar10: apo_core::metrics::lower_cvar(&returns, apo_core::metrics::RISK_LEVEL),
        q10: apo_core::metrics::quantile(&returns, apo_core::metrics::RISK_LEVEL),
    })
}

/// For each group label, how many environments it is best in, per metric ([`METRICS`]).
pub fn best_counts(report: &Report) -> Vec<(String, [usize; 4])> {
    let mut labels: Vec<String> = report.groups.iter().map(GroupReport::label).collect();
    labels.sort();
    labels.dedup();
    let mut counts: Vec<(String, [usize; 4])> = labels.into_iter().map(|l| (l, [0; 4])).collect();
    let envs: Vec<&str> = {
        let mut e: Vec<&str> = report.groups.iter().map(|g| g.env.as_str()).collect();
        e.dedup();
        e
    };
    for env in envs {
        let groups: Vec<&GroupReport> = report.groups.iter().filter(|g| g.env == env).collect();
        for m in 0..METRICS.len() {
            let best = groups
                .iter()
                .filter_map(|g| g.ranked()[m])
                .fold(f64::NEG_INFINITY, f64::max);
            for g in &groups {
                if g.ranked()[m] == Some(best) {
                    if let Some((_, c)) = counts.iter_mut().find(|(l, _)| *l == g.label()) {
                        c[m] += 1;
                    }
                }
            }
        }
    }
    counts
}

/// A per-run metric of [`statistics`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RunMetric {
    /// Average of the epochs' mean return over all epochs.
    MeanAll,
    /// Over the last N epochs.
    MeanLast,
    /// Average of the epochs' worst return over all epochs.
    WorstAll,
    /// Over the last N epochs.
    WorstLast,
    /// Average of the epochs' lower CVaR at 10 % over the last N epochs.
    Cvar10Last,
    /// Average of the epochs' 10 % quantile over the last N epochs.
    Q10Last,
}

impl RunMetric {
    /// All, in report order.
    pub const ALL: [RunMetric; 6] = [
        RunMetric::MeanAll,
        RunMetric::MeanLast,
        RunMetric::WorstAll,
        RunMetric::WorstLast,
        RunMetric::Cvar10Last,
        RunMetric::Q10Last,
    ];

    /// The name in file names (`worst_last`).
    pub fn name(self) -> &'static str {
        match self {
            RunMetric::MeanAll => "mean_all",
            RunMetric::MeanLast => "mean_last",
            RunMetric::WorstAll => "worst_all",
            RunMetric::WorstLast => "worst_last",
            RunMetric::Cvar10Last => "cvar10_last",
            RunMetric::Q10Last => "q10_last",
        }
    }

    /// Words for titles, with N.
    pub fn title(self, last: usize) -> String {
        match self {
            RunMetric::MeanAll => "mean return (all epochs)".to_string(),
            RunMetric::MeanLast => format!("mean return (last {last} epochs)"),
            RunMetric::WorstAll => "worst return (all epochs)".to_string(),
            RunMetric::WorstLast => format!("worst return (last {last} epochs)"),
            RunMetric::Cvar10Last => format!("CVaR 10 % of the returns (last {last} epochs)"),
            RunMetric::Q10Last => format!("10 % quantile of the returns (last {last} epochs)"),
        }
    }

    /// The run's value.
    pub fn of(self, s: &RunSummary) -> Option<f64> {
        match self {
            RunMetric::MeanAll => s.mean_all,
            RunMetric::MeanLast => s.mean_last,
            RunMetric::WorstAll => s.worst_all,
            RunMetric::WorstLast => s.worst_last,
            RunMetric::Cvar10Last => s.cvar10_last,
            RunMetric::Q10Last => s.q10_last,
        }
        .filter(|v| v.is_finite())
    }

    /// The random policy's value of the same statistic of its returns.
    fn random(self, b: &Baseline) -> f64 {
        match self {
            RunMetric::MeanAll | RunMetric::MeanLast => b.mean,
            RunMetric::WorstAll | RunMetric::WorstLast => b.worst,
            RunMetric::Cvar10Last => b.cvar10,
            RunMetric::Q10Last => b.q10,
        }
    }
}

/// How [`statistics`] makes scores comparable across environments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Normalization {
    /// The paper's TRPO-normalized score of each run
    /// ([`apo_core::metrics::normalized_score`]) against the random policy's value of the
    /// metric and the TRPO group's mean over seeds (the TRPO group of the same variant, else
    /// the environment's first): 0 is random, 1 is TRPO.
    Trpo,
    /// `(x − min) / (max − min)` with the lowest and highest value of any run of the compared
    /// groups on the environment.
    MinMax,
}

impl Normalization {
    /// Words for the report.
    fn describe(self) -> &'static str {
        match self {
            Normalization::Trpo => "TRPO-normalized per run (0: the random policy, 1: TRPO's mean over seeds)",
            Normalization::MinMax => "min–max normalized per environment over every run of the compared groups (0: the lowest run, 1: the highest)",
        }
    }
}

/// The options of [`statistics`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StatsOptions {
    /// The scores.
    pub normalization: Normalization,
    /// The intervals.
    pub bootstrap: StratifiedBootstrap,
}

/// The statistics of one metric.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MetricStatistics {
    /// The metric.
    pub metric: RunMetric,
    /// How its values were normalized.
    pub normalization: Normalization,
    /// The analysis over the environments kept; `None` when none was.
    pub analysis: Option<Analysis>,
    /// The environments left out, each with why.
    pub left_out: Vec<String>,
}

/// The statistics of every [`RunMetric`] over the report's groups (see the module's
/// documentation). An environment enters only where every group has runs with a value and
/// the normalization is defined; the others are listed in [`MetricStatistics::left_out`].
pub fn statistics(report: &Report, options: &StatsOptions) -> Vec<MetricStatistics> {
    statistics_with_progress(report, options, &mut |_, _| {})
}

/// [`statistics`], calling `progress(done, total)` as the bootstrap advances (in units of
/// [`stats::analysis_work`], over every metric).
pub fn statistics_with_progress(
    report: &Report,
    options: &StatsOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Vec<MetricStatistics> {
    let mut labels: Vec<String> = report.groups.iter().map(GroupReport::label).collect();
    labels.sort();
    labels.dedup();
    let mut envs: Vec<&str> = report.groups.iter().map(|g| g.env.as_str()).collect();
    envs.dedup();
    // every metric compares the same labels: the same work each
    let per_metric = stats::analysis_work(labels.len(), &options.bootstrap);
    let total = per_metric.saturating_mul(RunMetric::ALL.len() as u64);
    let mut done = 0u64;
    RunMetric::ALL
        .iter()
        .map(|&metric| {
            let mut tasks = Vec::new();
            let mut scores: Vec<Vec<Vec<f64>>> = vec![Vec::new(); labels.len()];
            let mut left_out = Vec::new();
            for env in &envs {
                match env_scores(report, env, &labels, metric, options.normalization) {
                    Ok(per_label) => {
                        tasks.push(env.to_string());
                        for (s, runs) in scores.iter_mut().zip(per_label) {
                            s.push(runs);
                        }
                    }
                    Err(why) => left_out.push(format!("{env}: {why}")),
                }
            }
            let analysis = (!tasks.is_empty()).then(|| {
                let comparison = Comparison {
                    tasks,
                    algorithms: labels
                        .iter()
                        .cloned()
                        .zip(scores.into_iter().map(|tasks| Scores { tasks }))
                        .collect(),
                };
                let taus = stats::default_taus(&comparison);
                stats::analyze_with_progress(&comparison, &options.bootstrap, &taus, &mut |n| {
                    done = done.saturating_add(n);
                    progress(done, total);
                })
            });
            if analysis.is_none() {
                done = done.saturating_add(per_metric);
                progress(done, total);
            }
            MetricStatistics {
                metric,
                normalization: options.normalization,
                analysis,
                left_out,
            }
        })
        .collect()
}

/// The normalized scores of each label's runs on `env`, or why the environment cannot enter.
fn env_scores(
    report: &Report,
    env: &str,
    labels: &[String],
    metric: RunMetric,
    normalization: Normalization,
) -> Result<Vec<Vec<f64>>, String> {
    let group = |label: &str| {
        report
            .groups
            .iter()
            .find(|g| g.env == env && g.label() == label)
    };
    let values =
        |g: &GroupReport| -> Vec<f64> { g.summaries.iter().filter_map(|s| metric.of(s)).collect() };
    let mut raw = Vec::new();
    for label in labels {
        let runs = group(label).map(values).unwrap_or_default();
        if runs.is_empty() {
            return Err(format!("{label} has no run with this metric"));
        }
        raw.push((label, runs));
    }
    match normalization {
        Normalization::MinMax => {
            let all = raw.iter().flat_map(|(_, r)| r.iter().copied());
            let (low, high) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
            if high <= low {
                return Err("every run has the same value".to_string());
            }
            Ok(raw
                .into_iter()
                .map(|(_, runs)| runs.iter().map(|v| (v - low) / (high - low)).collect())
                .collect())
        }
        Normalization::Trpo => {
            let random = report
                .baselines
                .get(env)
                .map(|b| metric.random(b))
                .filter(|r| r.is_finite())
                .ok_or("no random baseline")?;
            raw.into_iter()
                .map(|(label, runs)| {
                    let variant = group(label).map_or("", |g| g.variant.as_str());
                    let trpo = |same_variant: bool| {
                        report.groups.iter().find(|t| {
                            t.env == env
                                && t.algo == Algorithm::Trpo
                                && (!same_variant || t.variant == variant)
                        })
                    };
                    let reference = trpo(true)
                        .or_else(|| trpo(false))
                        .map(values)
                        .filter(|v| !v.is_empty())
                        .ok_or("no TRPO run to normalize by")?;
                    let reference = reference.iter().sum::<f64>() / reference.len() as f64;
                    runs.iter()
                        .map(|&v| {
                            normalized_score(v, reference, random).ok_or_else(|| {
                                "TRPO's value equals the random policy's: the score is not finite"
                                    .to_string()
                            })
                        })
                        .collect()
                })
                .collect()
        }
    }
}

/// The statistics section of the report in Markdown (empty without statistics).
fn statistics_markdown(report: &Report) -> String {
    let Some(first) = report.statistics.first() else {
        return String::new();
    };
    let mut out = format!(
        "## Statistics over environments and runs\n\nScores {}. Mean and median are over environments of each environment's mean over runs; IQM and optimality gap (to 1) over all runs of all environments; P(X > Y) is the probability that a run of X scores higher than a run of Y on the same environment, averaged over environments.\n\n",
        first.normalization.describe()
    );
    for m in &report.statistics {
        out.push_str(&format!("### {}\n\n", m.metric.title(report.last)));
        if let Some(analysis) = &m.analysis {
            out.push_str(&stats::markdown(analysis));
            out.push('\n');
        }
        if !m.left_out.is_empty() {
            out.push_str(&format!("Left out: {}.\n\n", m.left_out.join("; ")));
        }
    }
    out
}

/// The file names of the statistics' figures of `metric`: profiles and intervals, PNG and SVG.
fn statistics_figures(metric: RunMetric) -> [String; 4] {
    let m = metric.name();
    [
        format!("profile-{m}.png"),
        format!("profile-{m}.svg"),
        format!("intervals-{m}.png"),
        format!("intervals-{m}.svg"),
    ]
}

fn stat_cell(s: Option<Stat>) -> String {
    s.map_or("-".to_string(), |s| format!("{:.2} ± {:.2}", s.mean, s.std))
}

fn score_cell(s: Option<f64>) -> String {
    s.map_or("-".to_string(), |s| format!("{s:.3}"))
}

/// The report as Markdown: one table per environment (the best value of each metric in
/// bold), then the counts of "best".
pub fn markdown(report: &Report) -> String {
    let n = report.last;
    let mut out = String::new();
    let mut envs: Vec<&str> = report.groups.iter().map(|g| g.env.as_str()).collect();
    envs.dedup();
    for env in envs {
        out.push_str(&format!("### {env}\n\n"));
        if let Some(b) = report.baselines.get(env) {
            out.push_str(&format!(
                "Random policy: mean return {:.2}, worst {:.2}.\n\n",
                b.mean, b.worst
            ));
        }
        out.push_str(&format!(
            "| algorithm | seeds | mean return (all) | mean return (last {n}) | worst return (all) | worst return (last {n}) | bound J − k·Var (last {n}) | confidence (last {n}) | score, mean | score, worst |\n"
        ));
        out.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
        let groups: Vec<&GroupReport> = report.groups.iter().filter(|g| g.env == env).collect();
        let best: Vec<f64> = (0..4)
            .map(|m| {
                groups
                    .iter()
                    .filter_map(|g| g.ranked()[m])
                    .fold(f64::NEG_INFINITY, f64::max)
            })
            .collect();
        for g in groups {
            let ranked = g.ranked();
            let cells: Vec<String> = [g.mean_all, g.mean_last, g.worst_all, g.worst_last]
                .into_iter()
                .enumerate()
                .map(|(m, s)| {
                    let text = stat_cell(s);
                    if ranked[m] == Some(best[m]) {
                        format!("**{text}**")
                    } else {
                        text
                    }
                })
                .collect();
            let seeds = if g.incomplete > 0 {
                format!("{} ({} incomplete)", g.runs.len(), g.incomplete)
            } else {
                g.runs.len().to_string()
            };
            out.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} |\n",
                g.label(),
                seeds,
                cells.join(" | "),
                stat_cell(g.bound_last),
                g.confidence_last
                    .map_or("-".to_string(), |s| format!("{:.3}", s.mean)),
                score_cell(g.score_mean),
                score_cell(g.score_worst),
            ));
        }
        out.push('\n');
    }
    out.push_str("### Best per metric (environments)\n\n| algorithm |");
    for m in METRICS {
        out.push_str(&format!(" {} |", m.replace('N', &n.to_string())));
    }
    out.push_str("\n|---|---|---|---|---|\n");
    for (label, counts) in best_counts(report) {
        out.push_str(&format!(
            "| {label} | {} | {} | {} | {} |\n",
            counts[0], counts[1], counts[2], counts[3]
        ));
    }
    let statistics = statistics_markdown(report);
    if !statistics.is_empty() {
        out.push('\n');
        out.push_str(&statistics);
    }
    out
}

/// The report as CSV, one row per group.
///
/// # Errors
/// Only if writing to memory fails.
pub fn csv(report: &Report) -> anyhow::Result<String> {
    let mut w = ::csv::Writer::from_writer(Vec::new());
    let n = report.last;
    let mut header = vec![
        "env".to_string(),
        "algo".into(),
        "variant".into(),
        "seeds".into(),
        "incomplete".into(),
    ];
    for m in [
        "mean_all",
        &format!("mean_last{n}"),
        "worst_all",
        &format!("worst_last{n}"),
        &format!("bound_last{n}"),
        &format!("confidence_last{n}"),
    ] {
        header.push(m.to_string());
        header.push(format!("{m}_std"));
    }
    header.extend([
        "score_mean".into(),
        "score_worst".into(),
        "random_mean".into(),
        "random_worst".into(),
    ]);
    w.write_record(&header)?;
    let num = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
    for g in &report.groups {
        let mut row = vec![
            g.env.clone(),
            g.algo.name().to_string(),
            g.variant.clone(),
            g.runs.len().to_string(),
            g.incomplete.to_string(),
        ];
        for s in [
            g.mean_all,
            g.mean_last,
            g.worst_all,
            g.worst_last,
            g.bound_last,
            g.confidence_last,
        ] {
            row.push(num(s.map(|s| s.mean)));
            row.push(num(s.map(|s| s.std)));
        }
        let b = report.baselines.get(&g.env);
        row.extend([
            num(g.score_mean),
            num(g.score_worst),
            num(b.map(|b| b.mean)),
            num(b.map(|b| b.worst)),
        ]);
        w.write_record(&row)?;
    }
    let bytes = w.into_inner().map_err(|e| anyhow::anyhow!("csv: {e}"))?;
    Ok(String::from_utf8(bytes)?)
}

/// The statistics of a report, as JSON ([`MetricStatistics`] per metric).
pub const STATISTICS_JSON: &str = "statistics.json";

/// The files [`write()`] may write into its folder whatever the runs are (all but the
/// per-environment curves): for a command to check them before any work.
pub fn fixed_outputs() -> Vec<String> {
    let mut names = vec![
        "report.md".to_string(),
        "report.csv".to_string(),
        STATISTICS_JSON.to_string(),
    ];
    for metric in RunMetric::ALL {
        names.extend(statistics_figures(metric));
    }
    names
}

/// The marker of a report folder: the files `apo report` wrote there.
pub const REPORT_MARKER: &str = ".apo-report";

/// Writes `report.md`, `report.csv` and one `curves-<env>.<ext>` per environment into `out`
/// (created if missing), returning the files written. A file of one of these names that an
/// earlier report did not write (see [`REPORT_MARKER`]) is never overwritten: that is an error
/// before anything is written.
///
/// # Errors
/// When a file cannot be written or a plot drawn.
pub fn write(
    report: &Report,
    out: &Path,
    image: &str,
    smooth: usize,
) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut envs: Vec<&str> = report.groups.iter().map(|g| g.env.as_str()).collect();
    envs.dedup();
    let curves = |env: &str| format!("curves-{}.{image}", run_dir::env_label(env));
    let mut names = vec!["report.md".to_string(), "report.csv".to_string()];
    names.extend(envs.iter().map(|env| curves(env)));
    if !report.statistics.is_empty() {
        names.push(STATISTICS_JSON.to_string());
        for m in &report.statistics {
            if m.analysis.is_some() {
                names.extend(statistics_figures(m.metric));
            }
        }
    }
    let places = run_dir::claim_outputs(out, REPORT_MARKER, &names)?;
    let mut written = Vec::new();
    for (name, text) in [
        ("report.md", markdown(report)),
        ("report.csv", csv(report)?),
    ] {
        let path = out.join(name);
        apo_train::atomic::write_placed(&path, text.as_bytes(), places.of(name))
            .with_context(|| format!("cannot write {}", path.display()))?;
        written.push(path);
    }
    if !report.statistics.is_empty() {
        let path = out.join(STATISTICS_JSON);
        let text = serde_json::to_string_pretty(&report.statistics)?;
        apo_train::atomic::write_placed(&path, text.as_bytes(), places.of(STATISTICS_JSON))
            .with_context(|| format!("cannot write {}", path.display()))?;
        written.push(path);
    }
    for m in &report.statistics {
        let Some(analysis) = &m.analysis else {
            continue;
        };
        let title = m.metric.title(report.last);
        let figures = statistics_figures(m.metric);
        let [profile_png, profile_svg, intervals_png, intervals_svg] =
            figures.clone().map(|name| out.join(name));
        for (path, name) in [&profile_png, &profile_svg].into_iter().zip(&figures[..2]) {
            crate::stats_plot::profiles(
                analysis,
                &title,
                "normalized score τ",
                path,
                places.of(name),
            )?;
        }
        for (path, name) in [&intervals_png, &intervals_svg]
            .into_iter()
            .zip(&figures[2..])
        {
            crate::stats_plot::intervals(analysis, &title, path, places.of(name))?;
        }
        written.extend([profile_png, profile_svg, intervals_png, intervals_svg]);
    }
    for env in envs {
        let groups: Vec<(String, Vec<PathBuf>)> = report
            .groups
            .iter()
            .filter(|g| g.env == env && g.mean_all.is_some())
            .map(|g| (g.label(), g.runs.clone()))
            .collect();
        if groups.is_empty() {
            continue;
        }
        let path = out.join(curves(env));
        crate::plot::plot_seed_groups(
            &groups,
            &path,
            &crate::plot::PlotOptions {
                smooth,
                column: None,
                place: places.of(&curves(env)),
            },
        )?;
        written.push(path);
    }
    Ok(written)
}
