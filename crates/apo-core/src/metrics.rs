//! Metrics: per-epoch statistics of completed episodes, the empirical lower probability
//! bound `J − k·Var` with its Selberg confidence, and the paper's across-run metrics.

use serde::{Deserialize, Serialize};

/// Statistics of the episodes completed in one epoch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpisodeStats {
    /// Number of completed episodes.
    pub count: usize,
    /// Mean return (the paper's expected performance).
    pub ret_mean: f64,
    /// Minimum return (the paper's worst performance).
    pub ret_min: f64,
    /// Maximum return.
    pub ret_max: f64,
    /// Standard deviation of the returns (population).
    pub ret_std: f64,
    /// Lower conditional value at risk at 10 %: the mean of the worst `⌈0.1·count⌉` returns
    /// (at least one), see [`lower_cvar`].
    pub ret_cvar10: f64,
    /// The 10 % quantile of the returns (linear interpolation between order statistics), see
    /// [`quantile`].
    pub ret_q10: f64,
    /// Mean episode length.
    pub len_mean: f64,
    /// Empirical lower probability bound `B_k = J − k · Var`.
    pub bound: f64,
    /// Its Selberg confidence `1 − 1 / (k² Var + 1)`: `P(R ≥ B_k)` is at least this.
    pub confidence: f64,
}

impl EpisodeStats {
    /// Statistics of `returns` (undiscounted episode returns) and their `lengths`, with
    /// probability factor `k`. `None` when no episode was completed.
    pub fn from_episodes(returns: &[f64], lengths: &[usize], k: f64) -> Option<Self> {
        if returns.is_empty() {
            return None;
        }
        let n = returns.len() as f64;
        let ret_mean = returns.iter().sum::<f64>() / n;
        let var = returns.iter().map(|r| (r - ret_mean).powi(2)).sum::<f64>() / n;
        let (bound, confidence) = lower_probability_bound(ret_mean, var, k);
        let mut sorted = returns.to_vec();
        sorted.sort_by(f64::total_cmp);
        Some(Self {
            count: returns.len(),
            ret_mean,
            ret_min: returns.iter().copied().fold(f64::INFINITY, f64::min),
            ret_max: returns.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            ret_std: var.sqrt(),
            ret_cvar10: lower_cvar(&sorted, RISK_LEVEL),
            ret_q10: quantile(&sorted, RISK_LEVEL),
            len_mean: lengths.iter().sum::<usize>() as f64 / lengths.len().max(1) as f64,
            bound,
            confidence,
        })
    }
}

/// The level α of the risk metrics an epoch records ([`EpisodeStats::ret_cvar10`],
/// [`EpisodeStats::ret_q10`]): 10 %.
pub const RISK_LEVEL: f64 = 0.1;

/// Lower CVaR at level `alpha` of ascending `sorted` values: the mean of the smallest
/// `max(1, ⌈alpha·n⌉)` of them (the worst `alpha` share of the episodes, at least one; with
/// fewer than `1/alpha` episodes it is the worst return). `NaN` for no values.
pub fn lower_cvar(sorted: &[f64], alpha: f64) -> f64 {
    let n = sorted.len();
    // the small tolerance keeps ⌈0.1·30⌉ at 3 although 0.1·30 is 3.0000000000000004 in f64
    let take = ((alpha * n as f64 - 1e-9).ceil() as usize).clamp(1, n.max(1));
    sorted.iter().take(take).sum::<f64>() / take.min(n) as f64
}

/// The `p`-quantile of ascending `sorted` values by linear interpolation between order
/// statistics (position `p·(n − 1)`: Hyndman & Fan's type 7, the default of NumPy and R).
/// `NaN` for no values.
pub fn quantile(sorted: &[f64], p: f64) -> f64 {
    let n = sorted.len();
    if n == 0 {
        return f64::NAN;
    }
    let position = p.clamp(0.0, 1.0) * (n - 1) as f64;
    let below = position.floor() as usize;
    let above = (below + 1).min(n - 1);
    let fraction = position - below as f64;
    sorted[below] + fraction * (sorted[above] - sorted[below])
}

/// `(J − k · var, 1 − 1 / (k² var + 1))`: Selberg's inequality gives
/// `P(R ≥ J − k·var) ≥ 1 − 1/(k² var + 1)` for a return `R` of mean `J` and variance `var`.
pub fn lower_probability_bound(mean: f64, var: f64, k: f64) -> (f64, f64) {
    (mean - k * var, 1.0 - 1.0 / (k * k * var + 1.0))
}

/// Mean of `per_epoch` over its last `last` entries (all of them when `last` is `None`
/// or larger): the paper's "average over all epochs" and "over the last N epochs".
pub fn average_over_epochs(per_epoch: &[f64], last: Option<usize>) -> Option<f64> {
    let n = per_epoch.len();
    let take = last.map_or(n, |l| l.min(n));
    (take > 0).then(|| per_epoch[n - take..].iter().sum::<f64>() / take as f64)
}

/// The paper's TRPO-normalized score: with `Δ1 = agent − random` and `Δ2 = trpo − random`,
/// `Δ2 / Δ1` when both are negative, else `Δ1 / Δ2`.
pub fn normalized_score(agent: f64, trpo: f64, random: f64) -> f64 {
    let (d1, d2) = (agent - random, trpo - random);
    if d1 < 0.0 && d2 < 0.0 {
        d2 / d1
    } else {
        d1 / d2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn episode_stats_by_hand() {
        // returns 1, 2, 6: mean 3, var (4 + 1 + 9) / 3 = 14/3
        let s =
            EpisodeStats::from_episodes(&[1.0, 2.0, 6.0], &[10, 20, 30], 0.5).expect("episodes");
        assert_eq!(s.count, 3);
        assert!((s.ret_mean - 3.0).abs() < 1e-12);
        assert!((s.ret_std - (14.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!((s.ret_min, s.ret_max, s.len_mean), (1.0, 6.0, 20.0));
        assert!((s.bound - (3.0 - 0.5 * 14.0 / 3.0)).abs() < 1e-12);
        assert!((s.confidence - (1.0 - 1.0 / (0.25 * 14.0 / 3.0 + 1.0))).abs() < 1e-12);
        assert!(EpisodeStats::from_episodes(&[], &[], 1.0).is_none());
        // fewer than 10 episodes: CVaR10 is the worst return; q10 at position 0.2 of 1, 2, 6
        assert_eq!(s.ret_cvar10, 1.0);
        assert!((s.ret_q10 - 1.2).abs() < 1e-12);
    }

    #[test]
    fn risk_metrics_by_hand() {
        // 30 returns 1..=30 in a shuffled order: the worst ⌈3⌉ are 1, 2, 3 → CVaR 2;
        // q10 at position 0.1·29 = 2.9 → 3 + 0.9·(4 − 3) = 3.9
        let returns: Vec<f64> = (0..30).map(|i| ((i * 7) % 30 + 1) as f64).collect();
        let s = EpisodeStats::from_episodes(&returns, &[1; 30], 1.0).expect("episodes");
        assert!((s.ret_cvar10 - 2.0).abs() < 1e-12, "{}", s.ret_cvar10);
        assert!((s.ret_q10 - 3.9).abs() < 1e-12, "{}", s.ret_q10);
        // 11 returns: ⌈1.1⌉ = 2 worst
        let sorted: Vec<f64> = (0..11).map(f64::from).collect();
        assert_eq!(lower_cvar(&sorted, 0.1), 0.5);
        assert_eq!(quantile(&sorted, 0.1), 1.0);
        assert_eq!(quantile(&sorted, 1.0), 10.0);
        assert_eq!(quantile(&[5.0], 0.1), 5.0);
        assert!(quantile(&[], 0.1).is_nan() && lower_cvar(&[], 0.1).is_nan());
    }

    #[test]
    fn epoch_averages_and_normalized_score() {
        assert_eq!(
            average_over_epochs(&[1.0, 2.0, 3.0, 4.0], Some(2)),
            Some(3.5)
        );
        assert_eq!(average_over_epochs(&[1.0, 2.0, 3.0, 4.0], None), Some(2.5));
        assert_eq!(average_over_epochs(&[1.0], Some(20)), Some(1.0));
        assert_eq!(average_over_epochs(&[], None), None);
        // both improvements positive: Δ1/Δ2 = (30 − 10) / (20 − 10)
        assert_eq!(normalized_score(30.0, 20.0, 10.0), 2.0);
        // both negative: Δ2/Δ1 = (−20) / (−5)
        assert_eq!(normalized_score(5.0, -10.0, 10.0), 4.0);
    }
}
