//! TailPPO — tail-weighted PPO, apo's own candidate for the worst return (designed and
//! written down with its reason before any of its runs: `docs/results/worst-case-methods.md`,
//! "Candidates of our own"): PPO on every row, with the normalized advantages of the episodes
//! whose return is at or below the batch's α-quantile `VaR_α` multiplied by a weight `w ≥ 1`
//! ([`crate::shaping`]). Since `min(ρ·wA, clip(ρ)·wA) = w·min(ρ·A, clip(ρ)·A)` for `w > 0`, the
//! update is PPO's clipped surrogate with the tail's rows counted `w` times: the CVaR policy
//! gradient's emphasis on the worst episodes (Tamar, Glassner & Mannor, AAAI 2015) without
//! discarding the `1 − α` of the batch above the quantile, the sample inefficiency that Mead,
//! Costen, Lacerda & Hawes (ICML 2025) name as the CVaR policy gradient's failure. At `w = 1`
//! it is PPO, bit for bit.

use serde::{Deserialize, Serialize};

use super::cvar::check_alpha;
use super::{check, shaped_ppo_settings, AlgorithmConfig, ConfigError, PpoConfig};
use crate::proximal::ProximalConfig;
use crate::shaping::ShapingRule;

/// Tail-weighted PPO's settings, `[algo.tailppo]`: PPO's, the tail's probability and its
/// weight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TailPpoConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// The tail's probability α ∈ (0, 1]: the episodes at or below the batch's α-quantile of
    /// the return are weighted.
    pub alpha: f64,
    /// The weight `w ∈ [1, 100]` of the tail's advantages (1: PPO).
    pub tail_weight: f64,
    /// Clip ε ∈ (0, 1) of the probability ratio.
    pub clip: f64,
    /// The policy's Adam update.
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl TailPpoConfig {
    /// The largest weight accepted: beyond it the tail's rows are all the update sees, CVaR's
    /// update with extra steps.
    const MAX_WEIGHT: f64 = 100.0;

    const RISK_DOCS: &'static [(&'static str, &'static str)] = &[
        (
            "alpha",
            "α, the tail's probability: the episodes at or below the batch's α-quantile of the return are weighted; (0, 1]",
        ),
        (
            "tail_weight",
            "w, the weight of the tail's advantages (1: PPO); [1, 100]",
        ),
    ];

    fn risk_check(&self) -> Result<(), ConfigError> {
        check_alpha("alpha", self.alpha)?;
        check(
            (1.0..=Self::MAX_WEIGHT).contains(&self.tail_weight),
            "tail_weight",
            self.tail_weight,
            "must be in [1, 100]",
        )
    }

    fn rule(&self) -> ShapingRule {
        ShapingRule::TailWeight {
            alpha: self.alpha,
            weight: self.tail_weight,
        }
    }
}

shaped_ppo_settings!(TailPpoConfig);

impl AlgorithmConfig for TailPpoConfig {
    const ABOUT: &'static str =
        "Tail-weighted PPO (apo's candidate: the worst episodes' advantages weighted)";

    /// PPO's paper defaults, α = 0.2 (the CVaR level of the other methods) and `w = 4`, the
    /// middle of the grid the protocol tunes it on (2, 4, 8).
    fn paper_defaults() -> Self {
        let ppo = PpoConfig::paper_defaults();
        Self {
            gamma: ppo.gamma,
            lambda: ppo.lambda,
            alpha: 0.2,
            tail_weight: 4.0,
            clip: ppo.clip,
            policy_update: ppo.policy_update,
            value_update: ppo.value_update,
        }
    }
}
