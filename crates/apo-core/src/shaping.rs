//! Risk shaping: what the field's risk-averse methods change in an epoch's batch before an
//! ordinary policy update — the rewards the advantages are computed from, or the episodes the
//! update sees.
//!
//! Four methods, each a PPO update on a shaped batch (`crate::algorithm`'s `mvpi`, `cvar`,
//! `retcap` and `tailppo`):
//!
//! * **Mean-variance policy iteration** (Zhang, Liu & Whiteson, "Mean-Variance Policy
//!   Iteration for Risk-Averse Reinforcement Learning", AAAI 2021; the per-step reward
//!   variance of Bisi et al., "Risk-Averse Trust Region Optimization for Reward-Volatility
//!   Reduction", IJCAI 2020). The objective `E[r] − λ·Var(r)` of the per-step reward `r`,
//!   written with Fenchel's dual of the square, is maximized by alternating two steps: `y`
//!   becomes the mean per-step reward of the current policy, then the policy maximizes the
//!   ordinary return of the augmented reward `r̂ = r − λ·r² + 2λ·r·y`
//!   ([`ShapingRule::MeanVariance`]). At `λ = 0`, `r̂ = r`: the batch is PPO's, bit for bit.
//! * **CVaR policy gradient on the worst episodes** (Tamar, Glassner & Mannor, "Optimizing
//!   the CVaR via Sampling", AAAI 2015; EPOpt-ε of Rajeswaran et al., ICLR 2017, is its TRPO
//!   form; the "CVaR PPO" baseline of Mead et al. 2025 its PPO form): the update sees only
//!   the episodes whose return is at or below the batch's α-quantile `VaR_α`
//!   ([`ShapingRule::WorstEpisodes`]); their advantages are normalized over them alone. The
//!   critic still fits every row. At `α = 1` every row is kept: PPO's batch.
//! * **Return capping** (Mead, Costen, Lacerda & Hawes, "Return Capping: Sample-Efficient
//!   CVaR Policy Gradient Optimisation", ICML 2025, arXiv 2504.20887): the CVaR problem recast
//!   as maximizing `E[min(R, C)]`, the expected return of every episode capped at `C`; with
//!   `C = VaR_α` of the optimal CVaR policy the two have the same optimum. Each step's reward
//!   becomes `r^a_t = min(R_t, C) − min(R_{t−1}, C)` with `R_t` the episode's undiscounted
//!   return up to and including step `t` (`R_{−1} = 0`), so an episode's shaped rewards sum
//!   to `min(R, C)` and no episode is discarded. `C` follows the policy's `VaR_α`:
//!   `C_k = max(C_{k−1} + η·(VaR_α(π_{k−1}) − C_{k−1}), C_M)` ([`ShapingRule::ReturnCap`]),
//!   kept in [`ShapingState`] (and in checkpoints). At `C = ∞`, `r^a = r`: PPO's batch.
//! * **Tail-weighted PPO**, apo's own candidate (`docs/results/worst-case-methods.md`): every
//!   row is kept, and the normalized advantages of the episodes at or below `VaR_α` are
//!   multiplied by a weight `w ≥ 1` ([`ShapingRule::TailWeight`]); PPO's clipped surrogate is
//!   positively homogeneous in the advantage, so this counts the tail's rows `w` times. At
//!   `w = 1` the batch is PPO's, bit for bit.
//!
//! Where the papers leave a choice, apo's (documented in `docs/algorithms.md`):
//!
//! * `VaR_α` is the lower empirical α-quantile of the returns of the episodes that ended in
//!   the epoch (on every rank): the `⌈α·N⌉`-th smallest of the `N` returns. A path the end of
//!   the epoch cut ([`PathEnd::episode`] false) has no known return: it does not enter the
//!   quantile, and the CVaR update leaves it out unless `α = 1`. An epoch in which no episode
//!   ended shapes nothing (every row is kept, the cap does not move).
//! * `y` is the mean reward over every row of the epoch's batch (on every rank), computed
//!   before the update, as the papers' step "y = the mean reward of the current policy".
//! * The cap starts at the first epoch's `VaR_α` (the papers start from a given value), and
//!   the first epoch is shaped with it.
//!
//! The rewards are reshaped before the advantages: `delta`, the GAE advantages (normalized
//! again over the rows the update sees) and the rewards-to-go are computed from the shaped
//! rewards with the critic's values as the rollout stored them, exactly as
//! [`crate::buffer::RolloutBuffer`] computes them.

use serde::{Deserialize, Serialize};

use crate::buffer::{normalize_over, path_advantages, Batch, PathEnd};
use crate::collective::Comm;

/// How a batch is shaped (from an algorithm's settings).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ShapingRule {
    /// Mean-variance policy iteration: `r̂ = r − λ·r² + 2λ·r·y`, `λ ≥ 0`.
    MeanVariance {
        /// The weight λ of the per-step reward's variance.
        lambda: f64,
    },
    /// CVaR policy gradient: only the episodes at or below `VaR_α`, `α ∈ (0, 1]`.
    WorstEpisodes {
        /// The tail's probability α.
        alpha: f64,
    },
    /// Return capping: `r^a_t = min(R_t, C) − min(R_{t−1}, C)`, the cap following `VaR_α`.
    ReturnCap {
        /// The tail's probability α ∈ (0, 1] whose quantile the cap follows.
        alpha: f64,
        /// The cap's step size η ∈ [0, 1] toward each epoch's `VaR_α`.
        eta: f64,
        /// The lowest cap `C_M` (`−∞`: none).
        min_cap: f64,
    },
    /// Tail-weighted PPO: every row, the advantages of the episodes at or below `VaR_α` times
    /// `w`.
    TailWeight {
        /// The tail's probability α ∈ (0, 1].
        alpha: f64,
        /// The weight `w ≥ 1` of the tail's advantages.
        weight: f64,
    },
}

/// What shaping carries from one epoch to the next: return capping's cap `C` (`None` until
/// the first epoch in which an episode ended). Saved in checkpoints, so that a resumed run
/// shapes as the uninterrupted one.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ShapingState {
    /// The cap the next epoch's batch is shaped with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cap: Option<f64>,
}

impl ShapingState {
    /// Whether nothing is carried (no cap yet).
    pub fn is_empty(&self) -> bool {
        self.cap.is_none()
    }
}

/// What one epoch's shaping did, for the epoch's log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapingReport {
    /// The level the rule used: `y` (mean-variance), `VaR_α` (CVaR, tail weighting) or the cap
    /// `C` the batch was shaped with (return capping); NaN when no episode ended (CVaR,
    /// capping, tail weighting).
    pub level: f64,
    /// The share of the batch's rows the policy update sees (1 but for CVaR).
    pub kept: f64,
}

/// A shaped batch: what the policy update sees, and what the critic fits when that differs.
#[derive(Debug, Clone, PartialEq)]
pub struct Shaped {
    /// The policy update's batch.
    pub policy: Batch,
    /// The value fit's batch, when it is not `policy` (CVaR: every row, as collected).
    pub value: Option<Batch>,
    /// What the shaping did.
    pub report: ShapingReport,
}

/// Why a batch cannot be shaped.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ShapingError {
    /// The batch does not record what shaping needs: a reward per row and paths that cover
    /// its rows, with every per-row field of its length (a batch from
    /// [`crate::buffer::RolloutBuffer`] has them).
    #[error(
        "the batch of {rows} rows records {rewards} rewards and paths ending at rows {ends}: the risk shaping (MVPI, CVaR, return capping) needs a reward per row, paths in row order that end at row {rows}, and every per-row field with {rows} rows (Batch::reward, Batch::paths; RolloutBuffer fills them)"
    )]
    Unrecorded {
        /// The batch's rows.
        rows: usize,
        /// The rewards it records.
        rewards: usize,
        /// Where its paths end (at most the first 8, then `…`).
        ends: String,
    },
    /// Another rank's batch cannot be shaped (so no rank shapes, and none waits for it).
    #[error("another rank's batch cannot be shaped (its error names what it lacks)")]
    OtherRank,
    /// CVaR's selection of the worst episodes in a data-parallel run: each rank would keep its
    /// own share of them, some none at all.
    #[error(
        "CVaR's selection of the worst episodes runs in one process only: a data-parallel run of {ranks} ranks is refused"
    )]
    Distributed {
        /// The run's ranks.
        ranks: usize,
    },
}

/// `Ok` when `batch` records a reward per row and paths, in row order, ending at its last row,
/// and its per-row fields have its rows; on every rank of `comm` alike (a rank whose batch
/// fails makes every rank refuse, so that none waits for it in a collective).
fn check(batch: &Batch, comm: &Comm) -> Result<(), ShapingError> {
    let n = batch.len;
    let ordered = batch.path_ranges().all(|(start, end, _)| start < end);
    let covered = batch.paths.last().map_or(0, |p| p.end) == n;
    let rows = [
        &batch.value,
        &batch.logp,
        &batch.delta,
        &batch.adv,
        &batch.ret,
    ]
    .iter()
    .all(|v| v.len() == n)
        && [&batch.obs, &batch.actions, &batch.dist].iter().all(|v| {
            if n == 0 {
                v.is_empty()
            } else {
                v.len() % n == 0
            }
        });
    let mine = batch.reward.len() == n && ordered && covered && rows;
    let mut bad = [f64::from(u8::from(!mine))];
    comm.max(&mut bad);
    if bad[0] == 0.0 {
        return Ok(());
    }
    if mine {
        return Err(ShapingError::OtherRank);
    }
    let mut ends: Vec<String> = batch
        .paths
        .iter()
        .take(8)
        .map(|p| p.end.to_string())
        .collect();
    if batch.paths.len() > 8 {
        ends.push("…".to_string());
    }
    Err(ShapingError::Unrecorded {
        rows: n,
        rewards: batch.reward.len(),
        ends: format!("[{}]", ends.join(", ")),
    })
}

/// The returns (undiscounted sums of `reward`) of the batch's paths that ended an episode,
/// in row order.
pub fn episode_returns(batch: &Batch) -> Vec<f64> {
    batch
        .path_ranges()
        .filter(|(_, _, path)| path.episode)
        .map(|(start, end, _)| batch.reward[start..end].iter().map(|&r| f64::from(r)).sum())
        .collect()
}

/// The lower empirical α-quantile of `values`: the `⌈α·N⌉`-th smallest (at least the
/// smallest), `α·N` taken as the integer it is within rounding (0.1 · 30 is 3, not the
/// 3.0000000000000004 of floating point); `None` for no value. Sorts `values` (n log n).
pub fn lower_quantile(values: &mut [f64], alpha: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    let rank = ((alpha * n as f64 - 1e-9).ceil() as usize).clamp(1, n);
    Some(values[rank - 1])
}

/// MVPI's augmented rewards `r − λ·r² + 2λ·r·y`, computed in f64, `[n]`.
pub fn mean_variance_rewards(reward: &[f32], lambda: f64, y: f64) -> Vec<f32> {
    reward
        .iter()
        .map(|&r| {
            let r = f64::from(r);
            (r - lambda * r * r + 2.0 * lambda * r * y) as f32
        })
        .collect()
}

/// Return capping's rewards: along each path, `min(R_t, C) − min(R_{t−1}, C)` with `R_t`
/// the path's undiscounted return up to and including step `t` (f64), `[n]`. With
/// `cap = +∞` every reward is returned as it is.
pub fn capped_rewards(reward: &[f32], paths: &[PathEnd], cap: f64) -> Vec<f32> {
    if cap == f64::INFINITY {
        return reward.to_vec();
    }
    let mut out = Vec::with_capacity(reward.len());
    let mut start = 0;
    for path in paths {
        let mut before = 0.0f64;
        for &r in &reward[start..path.end] {
            let after = before + f64::from(r);
            out.push((after.min(cap) - before.min(cap)) as f32);
            before = after;
        }
        start = path.end;
    }
    out
}

/// `batch` with its rewards replaced by `reward`: `delta`, advantages (normalized over every
/// rank's rows) and rewards-to-go computed again from them, the critic's values and
/// bootstraps as collected.
fn with_rewards(batch: &Batch, reward: Vec<f32>, gamma: f64, lambda: f64, comm: &Comm) -> Batch {
    let mut out = Batch {
        delta: Vec::with_capacity(batch.len),
        adv: Vec::with_capacity(batch.len),
        ret: Vec::with_capacity(batch.len),
        ..batch.clone()
    };
    for (start, end, path) in batch.path_ranges() {
        path_advantages(
            &reward[start..end],
            &batch.value[start..end],
            path.last_value,
            gamma,
            lambda,
            &mut out.delta,
            &mut out.adv,
            &mut out.ret,
        );
    }
    out.reward = reward;
    out.adv_scale = normalize_over(&mut out.adv, comm);
    out
}

/// The rows of `batch`'s paths that `keep` selects, as a batch of their own, advantages
/// computed again and normalized over the selected rows (of every rank).
fn select_paths(
    batch: &Batch,
    keep: impl Fn(usize, usize, &PathEnd) -> bool,
    gamma: f64,
    lambda: f64,
    comm: &Comm,
) -> Batch {
    let n = batch.len.max(1);
    let widths = (
        batch.obs.len() / n,
        batch.actions.len() / n,
        batch.dist.len() / n,
    );
    let mut out = Batch::default();
    for (start, end, path) in batch.path_ranges() {
        if !keep(start, end, &path) {
            continue;
        }
        let rows = |v: &Vec<f32>, w: usize| v[start * w..end * w].to_vec();
        out.obs.extend(rows(&batch.obs, widths.0));
        out.actions.extend(rows(&batch.actions, widths.1));
        out.dist.extend(rows(&batch.dist, widths.2));
        out.logp.extend(rows(&batch.logp, 1));
        out.value.extend(rows(&batch.value, 1));
        out.reward.extend(rows(&batch.reward, 1));
        path_advantages(
            &batch.reward[start..end],
            &batch.value[start..end],
            path.last_value,
            gamma,
            lambda,
            &mut out.delta,
            &mut out.adv,
            &mut out.ret,
        );
        out.len += end - start;
        out.paths.push(PathEnd {
            end: out.len,
            ..path
        });
    }
    out.adv_scale = normalize_over(&mut out.adv, comm);
    out
}

/// The α-quantile of the returns of the episodes that ended in `batch` on every rank of
/// `comm` ([`lower_quantile`]); `None` when none ended.
fn value_at_risk(batch: &Batch, alpha: f64, comm: &Comm) -> Option<f64> {
    let mut returns: Vec<f64> = comm.gather(&episode_returns(batch)).concat();
    // a non-finite return ranks nothing (a NaN would make every `<=` false)
    returns.retain(|r| r.is_finite());
    lower_quantile(&mut returns, alpha)
}

/// Shapes `batch` (an epoch's batch of one rank, collected with the current policy) by `rule`;
/// `gamma` and `lambda` are the algorithm's. `state` carries return capping's cap from epoch
/// to epoch (updated here).
///
/// # Errors
/// [`ShapingError`] when a rank's batch does not record a reward per row and paths that cover
/// its rows, or when CVaR's selection is asked of a data-parallel run; `state` is unchanged
/// then.
pub fn shape(
    batch: &Batch,
    rule: ShapingRule,
    state: &mut ShapingState,
    gamma: f64,
    lambda: f64,
    comm: &Comm,
) -> Result<Shaped, ShapingError> {
    check(batch, comm)?;
    if matches!(rule, ShapingRule::WorstEpisodes { .. }) && comm.is_distributed() {
        // each rank would keep its own share of the worst episodes, some none at all, and the
        // proximal step's collectives would then differ between ranks (a deadlock)
        return Err(ShapingError::Distributed { ranks: comm.size() });
    }
    Ok(match rule {
        ShapingRule::TailWeight { alpha, weight } => {
            let var = value_at_risk(batch, alpha, comm);
            let mut policy = batch.clone();
            // w = 1 leaves the batch as it is (PPO's, bit for bit)
            if let Some(var) = var.filter(|_| weight != 1.0) {
                for (start, end, path) in batch.path_ranges() {
                    let ret: f64 = batch.reward[start..end].iter().map(|&r| f64::from(r)).sum();
                    if path.episode && ret <= var {
                        for a in &mut policy.adv[start..end] {
                            *a = (f64::from(*a) * weight) as f32;
                        }
                    }
                }
            }
            Shaped {
                policy,
                value: None,
                report: ShapingReport {
                    level: var.unwrap_or(f64::NAN),
                    kept: 1.0,
                },
            }
        }
        ShapingRule::MeanVariance { lambda: weight } => {
            let mut totals = [
                batch.reward.iter().map(|&r| f64::from(r)).sum::<f64>(),
                batch.reward.len() as f64,
            ];
            comm.sum(&mut totals);
            let y = if totals[1] > 0.0 {
                totals[0] / totals[1]
            } else {
                0.0
            };
            let reward = mean_variance_rewards(&batch.reward, weight, y);
            Shaped {
                policy: with_rewards(batch, reward, gamma, lambda, comm),
                value: None,
                report: ShapingReport {
                    level: y,
                    kept: 1.0,
                },
            }
        }
        ShapingRule::WorstEpisodes { alpha } => {
            let var = value_at_risk(batch, alpha, comm);
            let selected = match var {
                Some(var) if alpha < 1.0 => Some(select_paths(
                    batch,
                    |start, end, path| {
                        path.episode
                            && batch.reward[start..end]
                                .iter()
                                .map(|&r| f64::from(r))
                                .sum::<f64>()
                                <= var
                    },
                    gamma,
                    lambda,
                    comm,
                )),
                _ => None,
            };
            let mut rows = [
                selected.as_ref().map_or(batch.len, |b| b.len) as f64,
                batch.len as f64,
            ];
            comm.sum(&mut rows);
            let (policy, value) = match selected {
                Some(policy) => (policy, Some(batch.clone())),
                None => (batch.clone(), None),
            };
            Shaped {
                policy,
                value,
                report: ShapingReport {
                    level: var.unwrap_or(f64::NAN),
                    kept: if rows[1] > 0.0 {
                        rows[0] / rows[1]
                    } else {
                        1.0
                    },
                },
            }
        }
        ShapingRule::ReturnCap {
            alpha,
            eta,
            min_cap,
        } => {
            let var = value_at_risk(batch, alpha, comm);
            // the first epoch with an episode starts the cap at its VaR
            let cap = match (state.cap, var) {
                (Some(cap), _) => Some(cap),
                (None, Some(var)) => Some(var.max(min_cap)),
                (None, None) => None,
            };
            let policy = match cap {
                Some(cap) => with_rewards(
                    batch,
                    capped_rewards(&batch.reward, &batch.paths, cap),
                    gamma,
                    lambda,
                    comm,
                ),
                None => batch.clone(),
            };
            // C_{k+1} = max(C_k + η (VaR_α(π_k) − C_k), C_M); a cap that is not finite (set by
            // hand) stays where it is
            if let (Some(cap), Some(var)) = (cap, var) {
                if cap.is_finite() {
                    state.cap = Some((cap + eta * (var - cap)).max(min_cap));
                }
            }
            Shaped {
                policy,
                value: None,
                report: ShapingReport {
                    level: cap.unwrap_or(f64::NAN),
                    kept: 1.0,
                },
            }
        }
    })
}
