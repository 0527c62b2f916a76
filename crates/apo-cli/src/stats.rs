//! Statistics across runs and tasks as Agarwal et al. recommend ("Deep Reinforcement Learning
//! at the Edge of the Statistical Precipice", NeurIPS 2021; the Python library `rliable`):
//! aggregate scores with stratified-bootstrap confidence intervals, the probability of
//! improvement, and performance profiles. `docs/statistics.md` gives every definition with its
//! source; `scripts/check_rliable.py` compares these numbers with `rliable` itself.
//!
//! An algorithm's scores are a [`Scores`]: for each task, the scores of its runs (the
//! `runs × tasks` matrix of rliable, read by column; tasks may have different numbers of runs).
//!
//! - [`Aggregate::Mean`]: the mean over tasks of each task's mean over runs;
//! - [`Aggregate::Median`]: the median over tasks of each task's mean over runs;
//! - [`Aggregate::Iqm`]: the interquartile mean of all runs of all tasks, the mean of the
//!   sorted scores from index `⌊n/4⌋` to `n − ⌊n/4⌋` (SciPy's `trim_mean(·, 0.25)`);
//! - [`Aggregate::OptimalityGap`]: `1 − mean(min(score, 1))` over all runs of all tasks.
//!
//! A confidence interval resamples, [`StratifiedBootstrap::reps`] times, the runs of each task
//! with replacement (the tasks stay fixed), computes the statistic of each resample, and takes
//! the `(1 − level)/2` and `(1 + level)/2` quantiles of those values (the percentile method,
//! quantiles by linear interpolation).

use std::collections::BTreeMap;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use apo_core::metrics::quantile;

/// One algorithm's scores: `tasks[t]` holds the scores of the runs on task `t`.
#[derive(Debug, Clone, PartialEq)]
pub struct Scores {
    /// Per task, the runs' scores.
    pub tasks: Vec<Vec<f64>>,
}

impl Scores {
    /// Scores from a `runs × tasks` matrix (`rows[r][t]`, rliable's layout).
    pub fn from_rows(rows: &[Vec<f64>]) -> Self {
        let tasks = rows.first().map_or(0, Vec::len);
        Self {
            tasks: (0..tasks)
                .map(|t| rows.iter().map(|r| r[t]).collect())
                .collect(),
        }
    }

    /// Every run's score of every task, in task order.
    fn all(&self) -> impl Iterator<Item = f64> + '_ {
        self.tasks.iter().flatten().copied()
    }

    /// Each task's mean over its runs.
    fn task_means(&self) -> Vec<f64> {
        self.tasks
            .iter()
            .map(|runs| runs.iter().sum::<f64>() / runs.len() as f64)
            .collect()
    }

    /// A resample: each task's runs drawn with replacement from its own runs.
    fn resample(&self, rng: &mut StdRng) -> Self {
        Self {
            tasks: self
                .tasks
                .iter()
                .map(|runs| {
                    (0..runs.len())
                        .map(|_| runs[rng.random_range(0..runs.len())])
                        .collect()
                })
                .collect(),
        }
    }
}

/// An aggregate score over tasks and runs (see the module's documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Aggregate {
    /// Mean over tasks of the task means.
    Mean,
    /// Median over tasks of the task means.
    Median,
    /// Interquartile mean of all runs.
    Iqm,
    /// `1 − mean(min(score, 1))` over all runs.
    OptimalityGap,
}

impl Aggregate {
    /// The four, in table order.
    pub const ALL: [Aggregate; 4] = [
        Aggregate::Mean,
        Aggregate::Median,
        Aggregate::Iqm,
        Aggregate::OptimalityGap,
    ];

    /// Short name (`mean`, `median`, `iqm`, `optimality_gap`).
    pub fn name(self) -> &'static str {
        match self {
            Aggregate::Mean => "mean",
            Aggregate::Median => "median",
            Aggregate::Iqm => "iqm",
            Aggregate::OptimalityGap => "optimality_gap",
        }
    }

    /// Its value on `scores` (`NaN` without scores).
    pub fn of(self, scores: &Scores) -> f64 {
        match self {
            Aggregate::Mean => mean(&scores.task_means()),
            Aggregate::Median => median(scores.task_means()),
            Aggregate::Iqm => interquartile_mean(scores.all().collect()),
            Aggregate::OptimalityGap => {
                let clipped: Vec<f64> = scores.all().map(|s| s.min(1.0)).collect();
                1.0 - mean(&clipped)
            }
        }
    }

    /// Its value on `scores` without each task in turn (the leave-one-task-out values, task
    /// order), all of them in `O(n log n)` of the `n` runs: a sum of the others is a prefix
    /// and a suffix sum (no difference of large values), the median skips one place of the
    /// sorted task means, and the interquartile mean finds its window in the sorted runs by a
    /// binary search and sums it in a tree of pairwise sums.
    fn without_each_task(self, scores: &Scores) -> Vec<f64> {
        let tasks = scores.tasks.len();
        match self {
            Aggregate::Mean => {
                let sums = PrefixSuffix::new(&scores.task_means());
                (0..tasks)
                    .map(|t| sums.without(t) / (tasks - 1) as f64)
                    .collect()
            }
            Aggregate::Median => {
                let means = scores.task_means();
                let mut order: Vec<usize> = (0..tasks).collect();
                order.sort_by(|&a, &b| means[a].total_cmp(&means[b]));
                let mut place = vec![0; tasks];
                for (i, &t) in order.iter().enumerate() {
                    place[t] = i;
                }
                (0..tasks)
                    .map(|t| {
                        // the sorted means without the one at place[t]
                        let at = |i: usize| means[order[if i < place[t] { i } else { i + 1 }]];
                        quantile_by(tasks - 1, 0.5, at)
                    })
                    .collect()
            }
            Aggregate::Iqm => iqm_without_each_task(scores),
            Aggregate::OptimalityGap => {
                let clipped: Vec<f64> = scores
                    .tasks
                    .iter()
                    .map(|runs| runs.iter().map(|s| s.min(1.0)).sum())
                    .collect();
                let sums = PrefixSuffix::new(&clipped);
                let runs: usize = scores.tasks.iter().map(Vec::len).sum();
                (0..tasks)
                    .map(|t| 1.0 - sums.without(t) / (runs - scores.tasks[t].len()) as f64)
                    .collect()
            }
        }
    }
}

/// The sums of a list without one entry, each `O(1)` after `O(n)`: the sum before it plus the
/// sum after it.
struct PrefixSuffix {
    /// `prefix[i]`: the sum of the entries before `i`.
    prefix: Vec<f64>,
    /// `suffix[i]`: the sum of the entries from `i` on.
    suffix: Vec<f64>,
}

impl PrefixSuffix {
    fn new(values: &[f64]) -> Self {
        let mut prefix = vec![0.0; values.len() + 1];
        let mut suffix = vec![0.0; values.len() + 1];
        for (i, v) in values.iter().enumerate() {
            prefix[i + 1] = prefix[i] + v;
        }
        for (i, v) in values.iter().enumerate().rev() {
            suffix[i] = suffix[i + 1] + v;
        }
        Self { prefix, suffix }
    }

    /// The sum of every entry but the `i`-th.
    fn without(&self, i: usize) -> f64 {
        self.prefix[i] + self.suffix[i + 1]
    }
}

/// [`quantile`] of the `n` sorted values `at(0), …, at(n − 1)` (linear interpolation).
fn quantile_by(n: usize, p: f64, at: impl Fn(usize) -> f64) -> f64 {
    if n == 0 {
        return f64::NAN;
    }
    let position = p.clamp(0.0, 1.0) * (n - 1) as f64;
    let below = position.floor() as usize;
    let above = (below + 1).min(n - 1);
    let fraction = position - below as f64;
    at(below) + fraction * (at(above) - at(below))
}

/// [`interquartile_mean`] of all runs but those of each task in turn, in `O(n log n)`: the
/// runs sorted once; without task `t` (its runs at the sorted places `r`), the `j`-th of the
/// others is at place `j + i` with `i` the first index where `r[i] − i > j` (a binary search,
/// `r[i] − i` never decreases); the window's sum is the range sum of a tree of pairwise sums
/// less the runs of `t` inside it.
fn iqm_without_each_task(scores: &Scores) -> Vec<f64> {
    let mut runs: Vec<(f64, usize)> = scores
        .tasks
        .iter()
        .enumerate()
        .flat_map(|(t, runs)| runs.iter().map(move |&s| (s, t)))
        .collect();
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = runs.len();
    let tree = RangeSum::new(runs.iter().map(|r| r.0));
    let mut places: Vec<Vec<usize>> = vec![Vec::new(); scores.tasks.len()];
    for (place, &(_, t)) in runs.iter().enumerate() {
        places[t].push(place);
    }
    places
        .iter()
        .map(|r| {
            let left = n - r.len();
            if left == 0 {
                return f64::NAN;
            }
            let cut = left / 4;
            let (first, last) = (cut, left - cut - 1);
            // the place of the j-th run that is not one of r
            let place = |j: usize| {
                let (mut lo, mut hi) = (0, r.len());
                while lo < hi {
                    let mid = (lo + hi) / 2;
                    if r[mid] - mid > j {
                        hi = mid;
                    } else {
                        lo = mid + 1;
                    }
                }
                j + lo
            };
            let (from, to) = (place(first), place(last));
            let inside = &r[r.partition_point(|&p| p < from)..r.partition_point(|&p| p <= to)];
            let own: f64 = inside.iter().map(|&p| runs[p].0).sum();
            (tree.sum(from, to + 1) - own) / (last - first + 1) as f64
        })
        .collect()
}

/// Sums of ranges of a list in `O(log n)` each, as a tree of pairwise sums (so a range's sum
/// has the rounding error of the values in it, not of a running total before it).
pub(crate) struct RangeSum {
    size: usize,
    /// The tree, `1` its root, leaves from `size`.
    nodes: Vec<f64>,
}

impl RangeSum {
    pub(crate) fn new(values: impl ExactSizeIterator<Item = f64>) -> Self {
        let size = values.len().next_power_of_two().max(1);
        let mut nodes = vec![0.0; 2 * size];
        for (i, v) in values.enumerate() {
            nodes[size + i] = v;
        }
        for i in (1..size).rev() {
            nodes[i] = nodes[2 * i] + nodes[2 * i + 1];
        }
        Self { size, nodes }
    }

    /// The sum of the values at `from..to`.
    pub(crate) fn sum(&self, from: usize, to: usize) -> f64 {
        let (mut lo, mut hi) = (from + self.size, to + self.size);
        let (mut left, mut right) = (0.0, 0.0);
        while lo < hi {
            if lo % 2 == 1 {
                left += self.nodes[lo];
                lo += 1;
            }
            if hi % 2 == 1 {
                hi -= 1;
                right += self.nodes[hi];
            }
            lo /= 2;
            hi /= 2;
        }
        left + right
    }
}

fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

fn sorted(mut values: Vec<f64>) -> Vec<f64> {
    values.sort_by(f64::total_cmp);
    values
}

/// The median (the mean of the two middle values for an even count; `NaN` for none).
pub fn median(values: Vec<f64>) -> f64 {
    quantile(&sorted(values), 0.5)
}

/// The 25 % trimmed mean: the mean of the sorted values from index `⌊n/4⌋` to `n − ⌊n/4⌋`.
pub fn interquartile_mean(values: Vec<f64>) -> f64 {
    let values = sorted(values);
    let cut = values.len() / 4;
    mean(&values[cut..values.len() - cut])
}

/// `P(X > Y)` on one task: the share of pairs (x, y) of runs with `x > y`, ties counting
/// one half (the Mann–Whitney U statistic over `n_x · n_y`), counted in `O((n_x + n_y) log n_y)`
/// with `y` sorted: each `x` wins against the `y` below it and ties the `y` equal to it.
pub fn task_improvement(x: &[f64], y: &[f64]) -> f64 {
    let y = sorted(y.to_vec());
    // twice the wins, a whole number (exact in u128)
    let twice: u128 = x
        .iter()
        .map(|&a| {
            let below = y.partition_point(|&b| b < a);
            let equal = y[below..].partition_point(|&b| b <= a);
            2 * below as u128 + equal as u128
        })
        .sum();
    twice as f64 / 2.0 / (x.len() as f64 * y.len() as f64)
}

/// The probability of improvement of `x` over `y`: [`task_improvement`] averaged over the
/// tasks (both must have the same tasks, in the same order).
pub fn probability_of_improvement(x: &Scores, y: &Scores) -> f64 {
    let per_task: Vec<f64> = x
        .tasks
        .iter()
        .zip(&y.tasks)
        .map(|(x, y)| task_improvement(x, y))
        .collect();
    mean(&per_task)
}

/// The fraction of all runs of all tasks with a score above each of `taus` (a performance
/// profile of the run-score distribution).
pub fn score_distribution(scores: &Scores, taus: &[f64]) -> Vec<f64> {
    let all = sorted(scores.all().collect());
    taus.iter()
        .map(|&tau| {
            let above = all.len() - all.partition_point(|&s| s <= tau);
            above as f64 / all.len() as f64
        })
        .collect()
}

/// A point estimate with its confidence interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// The statistic on the scores themselves.
    pub point: f64,
    /// Lower end of the interval.
    pub lower: f64,
    /// Upper end of the interval.
    pub upper: f64,
    /// The smallest and largest point estimate over the comparisons that leave one task out
    /// (how much the figure rests on a single task); `None` with fewer than two tasks, and for
    /// the profiles.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub leave_one_task_out: Option<[f64; 2]>,
}

/// The range of `statistic` over the scores that leave out one task at a time (`None` with
/// fewer than two tasks).
fn leave_one_task_out(tasks: usize, statistic: impl Fn(usize) -> f64) -> Option<[f64; 2]> {
    (tasks >= 2).then(|| {
        (0..tasks)
            .map(statistic)
            .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], v| {
                [lo.min(v), hi.max(v)]
            })
    })
}

/// The stratified bootstrap's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StratifiedBootstrap {
    /// Resamples.
    pub reps: usize,
    /// Coverage of the intervals (0.95).
    pub level: f64,
    /// Seed of the resampling: every estimate starts a generator from it, so a report is
    /// reproducible and an estimate does not depend on which others were computed.
    pub seed: u64,
}

impl StratifiedBootstrap {
    /// The percentile interval of `values` (the statistic of each resample).
    fn interval(&self, mut values: Vec<f64>) -> (f64, f64) {
        values.sort_by(f64::total_cmp);
        let tail = (1.0 - self.level) / 2.0;
        (quantile(&values, tail), quantile(&values, 1.0 - tail))
    }

    /// `aggregate` of `scores` with its interval: each resample draws every task's runs
    /// with replacement.
    pub fn estimate(&self, scores: &Scores, aggregate: Aggregate) -> Estimate {
        let mut rng = StdRng::seed_from_u64(self.seed);
        let values = (0..self.reps)
            .map(|_| aggregate.of(&scores.resample(&mut rng)))
            .collect();
        let (lower, upper) = self.interval(values);
        let without = (scores.tasks.len() >= 2).then(|| aggregate.without_each_task(scores));
        Estimate {
            point: aggregate.of(scores),
            lower,
            upper,
            leave_one_task_out: leave_one_task_out(scores.tasks.len(), |t| {
                without.as_ref().map_or(f64::NAN, |w| w[t])
            }),
        }
    }

    /// [`probability_of_improvement`] of `x` over `y` with its interval: each resample draws
    /// the runs of `x` and of `y` independently, task by task.
    pub fn improvement(&self, x: &Scores, y: &Scores) -> Estimate {
        let mut rng = StdRng::seed_from_u64(self.seed);
        let values = (0..self.reps)
            .map(|_| probability_of_improvement(&x.resample(&mut rng), &y.resample(&mut rng)))
            .collect();
        let (lower, upper) = self.interval(values);
        Estimate {
            point: probability_of_improvement(x, y),
            lower,
            upper,
            leave_one_task_out: {
                let per_task: Vec<f64> = x
                    .tasks
                    .iter()
                    .zip(&y.tasks)
                    .map(|(x, y)| task_improvement(x, y))
                    .collect();
                let sums = PrefixSuffix::new(&per_task);
                leave_one_task_out(per_task.len(), |t| {
                    sums.without(t) / (per_task.len() - 1) as f64
                })
            },
        }
    }

    /// [`score_distribution`] of `scores` at `taus` with a pointwise interval at each τ.
    pub fn profile(&self, scores: &Scores, taus: &[f64]) -> Vec<Estimate> {
        let mut rng = StdRng::seed_from_u64(self.seed);
        let resampled: Vec<Vec<f64>> = (0..self.reps)
            .map(|_| score_distribution(&scores.resample(&mut rng), taus))
            .collect();
        score_distribution(scores, taus)
            .into_iter()
            .enumerate()
            .map(|(i, point)| {
                let (lower, upper) = self.interval(resampled.iter().map(|r| r[i]).collect());
                Estimate {
                    point,
                    lower,
                    upper,
                    leave_one_task_out: None,
                }
            })
            .collect()
    }
}

/// `n` evenly spaced values from `low` to `high` inclusive (`[low]` for `n = 1`), computed as
/// NumPy's `linspace` does (`low + i·step`, the last exactly `high`), so that thresholds agree
/// to the bit with a profile computed in Python.
pub fn linspace(low: f64, high: f64, n: usize) -> Vec<f64> {
    if n <= 1 {
        return vec![low];
    }
    let step = (high - low) / (n - 1) as f64;
    let mut values: Vec<f64> = (0..n).map(|i| low + i as f64 * step).collect();
    values[n - 1] = high;
    values
}

/// Algorithms' scores on the same tasks: the input of [`analyze`].
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// The tasks, in the order of every [`Scores::tasks`].
    pub tasks: Vec<String>,
    /// Each algorithm's label and scores.
    pub algorithms: Vec<(String, Scores)>,
}

/// `P(x > y)` with its interval.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Improvement {
    /// The algorithm that improves.
    pub x: String,
    /// The one it is compared with.
    pub y: String,
    /// The probability and its interval.
    #[serde(flatten)]
    pub estimate: Estimate,
}

/// One algorithm's performance profile: at each τ, the fraction of runs above τ and its
/// pointwise interval.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Profile {
    /// Fraction of all runs of all tasks with a score above τ.
    pub fraction: Vec<f64>,
    /// Lower ends of the intervals.
    pub lower: Vec<f64>,
    /// Upper ends.
    pub upper: Vec<f64>,
}

/// Performance profiles at common thresholds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Profiles {
    /// The thresholds τ.
    pub taus: Vec<f64>,
    /// Each algorithm's profile, by label.
    #[serde(flatten)]
    pub curves: BTreeMap<String, Profile>,
}

/// Everything [`analyze`] computes (serialized as `apo stats --json` prints it).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analysis {
    /// Bootstrap resamples.
    pub reps: usize,
    /// Coverage of the intervals.
    pub confidence: f64,
    /// The tasks.
    pub tasks: Vec<String>,
    /// The algorithms, in the comparison's order.
    #[serde(skip)]
    pub algorithms: Vec<String>,
    /// Per algorithm, its runs over all tasks.
    pub runs: BTreeMap<String, usize>,
    /// Per algorithm, per [`Aggregate::name`], the estimate.
    pub aggregates: BTreeMap<String, BTreeMap<&'static str, Estimate>>,
    /// Every ordered pair of distinct algorithms.
    pub probability_of_improvement: Vec<Improvement>,
    /// Performance profiles.
    pub profiles: Profiles,
}

/// The largest magnitude of a score: sums and squares of a million such scores stay finite in
/// `f64` (the statistics add, subtract and square them).
pub const MAX_SCORE: f64 = 1e150;

/// The longest algorithm or task name of a score file, in bytes (the tables print each).
pub const MAX_NAME: usize = 200;

/// The most algorithms a comparison may have: it estimates every ordered pair's probability
/// of improvement, `a (a − 1)` estimates.
pub const MAX_ALGORITHMS: usize = 100;

/// Reads a score file: CSV with the header `algorithm,task,score` (in any column order; other
/// columns are ignored) and one row per run. Tasks and algorithms keep their first-seen order.
///
/// # Errors
/// A missing column, a score that is not a number in [−[`MAX_SCORE`], [`MAX_SCORE`]] (naming
/// its line and the range), no rows, or an
/// algorithm without runs on a task that another has (the statistics compare algorithms on the
/// same tasks).
pub fn read_scores(text: &str) -> anyhow::Result<Comparison> {
    use apo_train::input::excerpt;
    use std::collections::HashMap;
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let headers = reader.headers()?.clone();
    let column = |name: &str| {
        headers
            .iter()
            .position(|h| h.trim() == name)
            .ok_or_else(|| {
                let found: Vec<&str> = headers.iter().collect();
                anyhow::anyhow!(
                    "the score file has no `{name}` column: its header is `{}`; the columns needed are algorithm,task,score (in any order)",
                    excerpt(&found.join(","))
                )
            })
    };
    let (a, t, v) = (column("algorithm")?, column("task")?, column("score")?);
    // tasks and algorithms in first-seen order, found by name in O(log n) (a hash map)
    let mut tasks: Vec<String> = Vec::new();
    let mut task_index: HashMap<String, usize> = HashMap::new();
    let mut runs: Vec<(String, Vec<Vec<f64>>)> = Vec::new();
    let mut algorithm_index: HashMap<String, usize> = HashMap::new();
    for (i, record) in reader.records().enumerate() {
        let line = i + 2;
        let record = record.map_err(|e| anyhow::anyhow!("line {line}: {e}"))?;
        let field = |c: usize| record.get(c).unwrap_or("").trim();
        let score: f64 = field(v)
            .parse()
            .ok()
            .filter(|s: &f64| s.abs() <= MAX_SCORE)
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "line {line}: the score `{}` is not a number in [-{MAX_SCORE:e}, {MAX_SCORE:e}]",
                    excerpt(field(v))
                )
            })?;
        let (algorithm, task) = (field(a), field(t));
        if algorithm.is_empty() || task.is_empty() {
            anyhow::bail!("line {line}: empty algorithm or task");
        }
        if let Some(long) = [algorithm, task].into_iter().find(|n| n.len() > MAX_NAME) {
            anyhow::bail!(
                "line {line}: the name `{}` is {} bytes; an algorithm's or a task's name is 1..={MAX_NAME} bytes",
                excerpt(long),
                long.len()
            );
        }
        let t = match task_index.get(task) {
            Some(&t) => t,
            None => {
                tasks.push(task.to_string());
                task_index.insert(task.to_string(), tasks.len() - 1);
                tasks.len() - 1
            }
        };
        let index = match algorithm_index.get(algorithm) {
            Some(&i) => i,
            None => {
                if runs.len() == MAX_ALGORITHMS {
                    anyhow::bail!(
                        "line {line}: `{}` is an algorithm beyond the {MAX_ALGORITHMS} a comparison may have \
                         (1..={MAX_ALGORITHMS}: every ordered pair is an estimate of its own)",
                        excerpt(algorithm)
                    );
                }
                runs.push((algorithm.to_string(), Vec::new()));
                algorithm_index.insert(algorithm.to_string(), runs.len() - 1);
                runs.len() - 1
            }
        };
        let by_task = &mut runs[index].1;
        if by_task.len() <= t {
            by_task.resize(t + 1, Vec::new());
        }
        by_task[t].push(score);
    }
    if runs.is_empty() {
        anyhow::bail!("the score file has no rows");
    }
    let algorithms = runs
        .into_iter()
        .map(|(label, mut by_task)| {
            by_task.resize(tasks.len(), Vec::new());
            if let Some(t) = by_task.iter().position(Vec::is_empty) {
                anyhow::bail!(
                    "{} has no run on the task {}; every algorithm needs runs on every task",
                    excerpt(&label),
                    excerpt(&tasks[t])
                );
            }
            Ok((label, Scores { tasks: by_task }))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Comparison { tasks, algorithms })
}

/// The number of thresholds of the default performance profiles.
pub const DEFAULT_TAUS: usize = 101;

/// The thresholds of a profile when none are given: [`DEFAULT_TAUS`] from the lowest to the
/// highest score of all algorithms.
pub fn default_taus(comparison: &Comparison) -> Vec<f64> {
    let all = comparison
        .algorithms
        .iter()
        .flat_map(|(_, s)| s.all())
        .filter(|s| s.is_finite());
    let (low, high) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
        (lo.min(s), hi.max(s))
    });
    if low.is_finite() {
        linspace(low, high, DEFAULT_TAUS)
    } else {
        vec![0.0]
    }
}

/// Aggregates with intervals, the probability of improvement of every ordered pair and the
/// performance profiles at `taus` of the algorithms of `comparison`.
pub fn analyze(comparison: &Comparison, bootstrap: &StratifiedBootstrap, taus: &[f64]) -> Analysis {
    analyze_with_progress(comparison, bootstrap, taus, &mut |_| {})
}

/// The bytes [`analyze`] holds at once for the performance profiles of one algorithm: every
/// resample's fraction at every threshold (`reps × taus` values), which its intervals need.
/// Checked against the machine's memory before any work (`input::check_fits`).
pub fn profile_memory(bootstrap: &StratifiedBootstrap, taus: usize) -> f64 {
    bootstrap.reps as f64 * taus as f64 * std::mem::size_of::<f64>() as f64
}

/// The bootstrap resamples [`analyze`] draws for a comparison of `algorithms` algorithms: its
/// work, in the units of [`analyze_with_progress`]'s progress (for bars and estimates).
pub fn analysis_work(algorithms: usize, bootstrap: &StratifiedBootstrap) -> u64 {
    let algorithms = algorithms as u64;
    let estimates = algorithms
        .saturating_mul(Aggregate::ALL.len() as u64 + 1)
        .saturating_add(algorithms.saturating_mul(algorithms.saturating_sub(1)));
    estimates.saturating_mul(bootstrap.reps as u64)
}

/// [`analyze`], calling `progress(resamples)` after each estimate with the resamples it drew
/// (they add up to [`analysis_work`]).
pub fn analyze_with_progress(
    comparison: &Comparison,
    bootstrap: &StratifiedBootstrap,
    taus: &[f64],
    progress: &mut dyn FnMut(u64),
) -> Analysis {
    let reps = bootstrap.reps as u64;
    let aggregates = comparison
        .algorithms
        .iter()
        .map(|(label, scores)| {
            let estimates = Aggregate::ALL
                .iter()
                .map(|&a| {
                    let estimate = bootstrap.estimate(scores, a);
                    progress(reps);
                    (a.name(), estimate)
                })
                .collect();
            (label.clone(), estimates)
        })
        .collect();
    let mut probability_of_improvement = Vec::new();
    for (x, sx) in &comparison.algorithms {
        for (y, sy) in &comparison.algorithms {
            if x != y {
                probability_of_improvement.push(Improvement {
                    x: x.clone(),
                    y: y.clone(),
                    estimate: bootstrap.improvement(sx, sy),
                });
                progress(reps);
            }
        }
    }
    let curves = comparison
        .algorithms
        .iter()
        .map(|(label, scores)| {
            let estimates = bootstrap.profile(scores, taus);
            progress(reps);
            let profile = Profile {
                fraction: estimates.iter().map(|e| e.point).collect(),
                lower: estimates.iter().map(|e| e.lower).collect(),
                upper: estimates.iter().map(|e| e.upper).collect(),
            };
            (label.clone(), profile)
        })
        .collect();
    Analysis {
        reps: bootstrap.reps,
        confidence: bootstrap.level,
        tasks: comparison.tasks.clone(),
        algorithms: comparison
            .algorithms
            .iter()
            .map(|(l, _)| l.clone())
            .collect(),
        runs: comparison
            .algorithms
            .iter()
            .map(|(l, s)| (l.clone(), s.tasks.iter().map(Vec::len).sum()))
            .collect(),
        aggregates,
        probability_of_improvement,
        profiles: Profiles {
            taus: taus.to_vec(),
            curves,
        },
    }
}

/// `point [lower, upper]` with three decimals, and the leave-one-task-out range when there is
/// one: `… (LOTO lo–hi)`.
fn cell(e: &Estimate) -> String {
    let loto = e
        .leave_one_task_out
        .map_or_else(String::new, |[lo, hi]| format!(" (LOTO {lo:.3}–{hi:.3})"));
    format!("{:.3} [{:.3}, {:.3}]{loto}", e.point, e.lower, e.upper)
}

/// The analysis as Markdown: a table of the aggregates (each with its interval) and one of
/// the probability of improvement of each pair (each unordered pair once, the first-listed
/// algorithm as X).
pub fn markdown(analysis: &Analysis) -> String {
    let percent = analysis.confidence * 100.0;
    let mut out = format!(
        "Over {} task(s) ({}); {percent:.0} % stratified-bootstrap intervals, {} resamples; LOTO: the range of the point estimate over the comparisons that leave one task out.\n\n",
        analysis.tasks.len(),
        analysis.tasks.join(", "),
        analysis.reps
    );
    out.push_str(
        "| algorithm | runs | mean | median | IQM | optimality gap |\n|---|---|---|---|---|---|\n",
    );
    for label in &analysis.algorithms {
        let Some(estimates) = analysis.aggregates.get(label) else {
            continue;
        };
        let cells: Vec<String> = Aggregate::ALL
            .iter()
            .map(|a| estimates.get(a.name()).map_or("-".to_string(), cell))
            .collect();
        let runs = analysis.runs.get(label).copied().unwrap_or(0);
        out.push_str(&format!("| {label} | {runs} | {} |\n", cells.join(" | ")));
    }
    if analysis.algorithms.len() > 1 {
        out.push_str("\n| X | Y | P(X > Y) |\n|---|---|---|\n");
        for (i, x) in analysis.algorithms.iter().enumerate() {
            for y in &analysis.algorithms[i + 1..] {
                if let Some(p) = analysis
                    .probability_of_improvement
                    .iter()
                    .find(|p| &p.x == x && &p.y == y)
                {
                    out.push_str(&format!("| {x} | {y} | {} |\n", cell(&p.estimate)));
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_score_beyond_the_range_is_refused_naming_its_line_and_the_range() {
        for score in ["1.7e308", "-1e151", "inf", "NaN", "x"] {
            let text = format!("algorithm,task,score\na,t,1\na,t,{score}\n");
            let Err(err) = read_scores(&text) else {
                panic!("{score} accepted");
            };
            let err = err.to_string();
            assert!(
                err.contains("line 3") && err.contains("1e150"),
                "{score}: {err}"
            );
        }
        assert!(read_scores("algorithm,task,score\na,t,-1e150\nb,t,1e150\n").is_ok());
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    /// Two tasks × four runs, by hand.
    fn example() -> Scores {
        Scores {
            tasks: vec![vec![0.0, 1.0, 2.0, 9.0], vec![0.5, 0.5, 1.5, 3.0]],
        }
    }

    #[test]
    fn aggregates_by_hand() {
        let s = example();
        // task means 3 and 1.375
        assert!(close(Aggregate::Mean.of(&s), (3.0 + 1.375) / 2.0));
        assert!(close(Aggregate::Median.of(&s), (3.0 + 1.375) / 2.0));
        // eight values sorted 0 .5 .5 1 1.5 2 3 9: cut 2 each side → (.5 + 1 + 1.5 + 2) / 4
        assert!(close(Aggregate::Iqm.of(&s), 1.25));
        // clipped at 1: 0 1 1 1 .5 .5 1 1 → mean 6/8
        assert!(close(Aggregate::OptimalityGap.of(&s), 0.25));
        // three tasks: the median is the middle task mean
        let three = Scores {
            tasks: vec![vec![5.0], vec![1.0, 3.0], vec![-4.0]],
        };
        assert!(close(Aggregate::Median.of(&three), 2.0));
        // nine values: ⌊9/4⌋ = 2 cut each side
        assert!(close(
            interquartile_mean((1..=9).map(f64::from).collect()),
            5.0
        ));
    }

    #[test]
    fn score_files_are_read_and_checked() {
        let c =
            read_scores("task,algorithm,score,seed\nA,x,1,0\nB,x,2,0\nA,y,3,0\nA,x,4,1\nB,y,5,0\n")
                .unwrap();
        assert_eq!(c.tasks, ["A", "B"]);
        assert_eq!(c.algorithms[0].0, "x");
        assert_eq!(c.algorithms[0].1.tasks, vec![vec![1.0, 4.0], vec![2.0]]);
        assert_eq!(c.algorithms[1].1.tasks, vec![vec![3.0], vec![5.0]]);
        let error = |text: &str| format!("{:#}", read_scores(text).unwrap_err());
        assert!(error("algorithm,task\nx,A\n").contains("`score`"));
        assert!(error("algorithm,task,score\nx,A,nan\n").contains("line 2"));
        assert!(
            error("algorithm,task,score\nx,A,1\ny,B,2\n").contains("x has no run on the task B")
        );
        assert!(error("algorithm,task,score\n").contains("no rows"));
    }

    #[test]
    fn rows_become_tasks() {
        let s = Scores::from_rows(&[vec![1.0, 2.0], vec![3.0, 4.0], vec![5.0, 6.0]]);
        assert_eq!(s.tasks, vec![vec![1.0, 3.0, 5.0], vec![2.0, 4.0, 6.0]]);
    }

    #[test]
    fn probability_of_improvement_by_hand() {
        // x = (1, 3), y = (2, 2, 3): pairs x > y: 3>2, 3>2 → 2; ties: 3=3 → 0.5; of 6
        assert!(close(
            task_improvement(&[1.0, 3.0], &[2.0, 2.0, 3.0]),
            2.5 / 6.0
        ));
        // identical runs: one half
        assert!(close(task_improvement(&[4.0, 1.0], &[4.0, 1.0]), 0.5));
        let x = Scores {
            tasks: vec![vec![1.0, 3.0], vec![10.0]],
        };
        let y = Scores {
            tasks: vec![vec![2.0, 2.0, 3.0], vec![0.0]],
        };
        assert!(close(
            probability_of_improvement(&x, &y),
            (2.5 / 6.0 + 1.0) / 2.0
        ));
        assert!(close(
            probability_of_improvement(&x, &y) + probability_of_improvement(&y, &x),
            1.0
        ));
    }

    #[test]
    fn leave_one_task_out_ranges_by_hand() {
        // per task P(x > y): 1, 0, 1/2 → P = 1/2; leaving out task 0, 1, 2: 1/4, 3/4, 1/2
        let x = Scores {
            tasks: vec![vec![2.0], vec![0.0], vec![1.0]],
        };
        let y = Scores {
            tasks: vec![vec![1.0], vec![1.0], vec![1.0]],
        };
        let b = StratifiedBootstrap {
            reps: 10,
            level: 0.95,
            seed: 0,
        };
        let p = b.improvement(&x, &y);
        assert!(close(p.point, 0.5));
        assert_eq!(p.leave_one_task_out, Some([0.25, 0.75]));
        // the mean of x's task means 1, without each task: 1/2, 3/2, 1
        let m = b.estimate(&x, Aggregate::Mean);
        assert_eq!(m.leave_one_task_out, Some([0.5, 1.5]));
        // one task: nothing to leave out
        let one = Scores {
            tasks: vec![vec![1.0, 2.0]],
        };
        assert_eq!(b.estimate(&one, Aggregate::Mean).leave_one_task_out, None);
        assert!(cell(&p).ends_with("(LOTO 0.250–0.750)"), "{}", cell(&p));
    }

    #[test]
    fn score_distribution_counts_strictly_above() {
        let s = example();
        let f = score_distribution(&s, &[-1.0, 0.5, 1.0, 9.0]);
        assert_eq!(f, vec![1.0, 5.0 / 8.0, 4.0 / 8.0, 0.0]);
        assert_eq!(linspace(0.0, 1.0, 5), vec![0.0, 0.25, 0.5, 0.75, 1.0]);
    }

    #[test]
    fn bootstrap_intervals_hold_the_point_and_are_reproducible() {
        let s = example();
        let b = StratifiedBootstrap {
            reps: 2000,
            level: 0.95,
            seed: 7,
        };
        for a in Aggregate::ALL {
            let e = b.estimate(&s, a);
            assert!(e.lower <= e.point && e.point <= e.upper, "{a:?} {e:?}");
            assert!(e.lower < e.upper, "{a:?} {e:?}");
            assert_eq!(e, b.estimate(&s, a), "same seed, same interval");
        }
        // a task whose runs all agree has no spread: only resampling the other moves the mean
        let fixed = Scores {
            tasks: vec![vec![2.0; 4]],
        };
        let e = b.estimate(&fixed, Aggregate::Mean);
        assert_eq!((e.point, e.lower, e.upper), (2.0, 2.0, 2.0));
        // x beats y on every pair: probability 1 in every resample
        let x = Scores {
            tasks: vec![vec![5.0, 6.0]],
        };
        let y = Scores {
            tasks: vec![vec![1.0, 2.0, 3.0]],
        };
        let p = b.improvement(&x, &y);
        assert_eq!((p.point, p.lower, p.upper), (1.0, 1.0, 1.0));
        // four of the eight scores are above 1
        let profile = b.profile(&s, &[1.0]);
        assert_eq!(profile[0].point, 0.5);
        assert!(profile[0].lower < 0.5 && profile[0].upper > 0.5);
    }

    #[test]
    fn the_mean_interval_covers_the_truth_about_as_often_as_it_says() {
        // 200 experiments of 3 tasks × 10 runs from N(task mean, 1): the 95 % interval of the
        // mean should hold the true mean (the average of the task means) in about 95 % of
        // them; percentile intervals run a little narrow with 10 runs per task.
        let mut rng = StdRng::seed_from_u64(1);
        let truth = [0.0, 1.0, 5.0];
        let b = StratifiedBootstrap {
            reps: 500,
            level: 0.95,
            seed: 3,
        };
        let mut covered = 0;
        for _ in 0..200 {
            let s = Scores {
                tasks: truth
                    .iter()
                    .map(|&m| {
                        (0..10)
                            .map(|_| m + rng.sample::<f64, _>(rand_distr::StandardNormal))
                            .collect()
                    })
                    .collect(),
            };
            let e = b.estimate(&s, Aggregate::Mean);
            covered += usize::from(e.lower <= 2.0 && 2.0 <= e.upper);
        }
        assert!((175..=198).contains(&covered), "covered {covered} of 200");
    }
    /// The leave-one-task-out values in O(n log n) equal the statistic computed again on the
    /// scores without each task (ties, uneven task sizes and a task of one run included).
    #[test]
    fn leave_one_task_out_values_equal_the_statistic_without_each_task() {
        let mut rng = StdRng::seed_from_u64(7);
        for case in 0..40 {
            let tasks = 2 + case % 6;
            let scores = Scores {
                tasks: (0..tasks)
                    .map(|_| {
                        let runs = rng.random_range(1..9);
                        (0..runs)
                            .map(|_| f64::from(rng.random_range(-4i32..5)) * 0.5)
                            .collect()
                    })
                    .collect(),
            };
            for a in Aggregate::ALL {
                let fast = a.without_each_task(&scores);
                for (t, &value) in fast.iter().enumerate() {
                    let mut rest = scores.clone();
                    rest.tasks.remove(t);
                    let direct = a.of(&rest);
                    assert!(
                        (value - direct).abs() <= 1e-12 * direct.abs().max(1.0),
                        "{} without task {t} of {:?}: {value} against {direct}",
                        a.name(),
                        scores.tasks
                    );
                }
            }
            let y = Scores {
                tasks: scores.tasks.iter().rev().cloned().collect(),
            };
            for (x, y) in scores.tasks.iter().zip(&y.tasks) {
                let mut wins = 0.0;
                for &a in x {
                    for &b in y {
                        wins += if a > b {
                            1.0
                        } else if a == b {
                            0.5
                        } else {
                            0.0
                        };
                    }
                }
                assert_eq!(task_improvement(x, y), wins / (x.len() * y.len()) as f64);
            }
        }
    }

    /// A comparison holds at most MAX_ALGORITHMS algorithms, refused while the file is read.
    #[test]
    fn a_score_file_of_too_many_algorithms_is_refused_while_it_is_read() {
        let mut text = String::from("algorithm,task,score\n");
        for a in 0..=MAX_ALGORITHMS {
            text += &format!("algo{a},A,1\n");
        }
        let err = format!("{:#}", read_scores(&text).unwrap_err());
        assert!(
            err.contains(&format!(
                "line {}: `algo{MAX_ALGORITHMS}`",
                MAX_ALGORITHMS + 2
            )) && err.contains("1..=100"),
            "{err}"
        );
        // a name is bounded too, and quoted as an excerpt
        let long = "n".repeat(10_000);
        let err = format!(
            "{:#}",
            read_scores(&format!("algorithm,task,score\n{long},A,1\n")).unwrap_err()
        );
        assert!(err.contains("is 10000 bytes") && err.len() < 300, "{err}");
    }
}
