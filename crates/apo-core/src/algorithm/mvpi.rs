//! MVPI — Mean-Variance Policy Iteration with PPO (Zhang, Liu & Whiteson, "Mean-Variance
//! Policy Iteration for Risk-Averse Reinforcement Learning", AAAI 2021): maximizes
//! `E[r] − λ·Var(r)` of the per-step reward by alternating `y ← E_π[r]` (the batch's mean
//! reward) with a PPO update on the augmented reward `r̂ = r − λ·r² + 2λ·r·y`
//! ([`crate::shaping`]). At `mv_lambda = 0` it is PPO, bit for bit.

use serde::{Deserialize, Serialize};

use super::{check, shaped_ppo_settings, AlgorithmConfig, ConfigError, PpoConfig};
use crate::proximal::ProximalConfig;
use crate::shaping::ShapingRule;

/// MVPI's settings, `[algo.mvpi]`: PPO's, and the variance's weight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MvpiConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// The weight λ ≥ 0 of the per-step reward's variance (the paper's λ).
    pub mv_lambda: f64,
    /// Clip ε ∈ (0, 1) of the probability ratio.
    pub clip: f64,
    /// The policy's Adam update.
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl MvpiConfig {
    const RISK_DOCS: &'static [(&'static str, &'static str)] = &[(
        "mv_lambda",
        "λ, the weight of the per-step reward's variance: PPO on r − λr² + 2λry, y the batch's mean reward (0: PPO); [0, 1000]",
    )];

    fn risk_check(&self) -> Result<(), ConfigError> {
        check(
            self.mv_lambda.is_finite() && (0.0..=Self::MAX).contains(&self.mv_lambda),
            "mv_lambda",
            self.mv_lambda,
            "must be in [0, 1000]",
        )
    }

    fn rule(&self) -> ShapingRule {
        ShapingRule::MeanVariance {
            lambda: self.mv_lambda,
        }
    }

    /// The largest weight accepted: beyond it `λ·r²` leaves f32's range for rewards of
    /// ordinary size.
    const MAX: f64 = 1000.0;
}

shaped_ppo_settings!(MvpiConfig);

impl AlgorithmConfig for MvpiConfig {
    const ABOUT: &'static str =
        "Mean-Variance Policy Iteration with PPO (per-step reward variance)";

    /// PPO's paper defaults, and λ = 0.1, the middle of the grid {0.01, 0.1, 1} apo's
    /// worst-case study searches (the MVPI paper tunes λ per task; the weight's scale is the
    /// task's per-step reward's).
    fn paper_defaults() -> Self {
        let ppo = PpoConfig::paper_defaults();
        Self {
            gamma: ppo.gamma,
            lambda: ppo.lambda,
            mv_lambda: 0.1,
            clip: ppo.clip,
            policy_update: ppo.policy_update,
            value_update: ppo.value_update,
        }
    }
}
