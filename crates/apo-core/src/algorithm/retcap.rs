//! RetCap — return capping with PPO (Mead, Costen, Lacerda & Hawes, "Return Capping:
//! Sample-Efficient CVaR Policy Gradient Optimisation", ICML 2025, arXiv 2504.20887): PPO on
//! rewards reshaped so that each episode's return is capped at `C`,
//! `r^a_t = min(R_t, C) − min(R_{t−1}, C)`, with the cap following the policy's α-quantile
//! of the return, `C ← max(C + η·(VaR_α − C), C_M)` ([`crate::shaping`]). With no cap
//! (`C = ∞`) it is PPO.

use serde::{Deserialize, Serialize};

use super::cvar::check_alpha;
use super::{check, shaped_ppo_settings, AlgorithmConfig, ConfigError, PpoConfig};
use crate::proximal::ProximalConfig;
use crate::shaping::ShapingRule;

/// Return capping's settings, `[algo.retcap]`: PPO's, and the cap's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RetcapConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// The tail's probability α ∈ (0, 1] whose return quantile the cap follows.
    pub alpha: f64,
    /// The cap's step size η ∈ [0, 1] toward each epoch's α-quantile.
    pub eta: f64,
    /// The lowest cap `C_M` (a return; `-inf`: none).
    pub min_cap: f64,
    /// Clip ε ∈ (0, 1) of the probability ratio.
    pub clip: f64,
    /// The policy's Adam update.
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl RetcapConfig {
    /// The largest |C_M| accepted but −∞: returns beyond it leave f32's precision for the
    /// rewards it shapes.
    const MAX_CAP: f64 = 1e9;

    const RISK_DOCS: &'static [(&'static str, &'static str)] = &[
        (
            "alpha",
            "α, the tail's probability whose return quantile the cap follows; (0, 1]",
        ),
        (
            "eta",
            "η, the cap's step toward each epoch's α-quantile: C ← C + η(VaR − C); [0, 1]",
        ),
        (
            "min_cap",
            "C_M, the lowest cap, a return (-inf: none); -inf or [-1e9, 1e9]",
        ),
    ];

    fn risk_check(&self) -> Result<(), ConfigError> {
        check_alpha("alpha", self.alpha)?;
        check(
            (0.0..=1.0).contains(&self.eta),
            "eta",
            self.eta,
            "must be in [0, 1]",
        )?;
        check(
            (-Self::MAX_CAP..=Self::MAX_CAP).contains(&self.min_cap)
                || self.min_cap == f64::NEG_INFINITY,
            "min_cap",
            self.min_cap,
            "must be -inf (no minimum) or in [-1e9, 1e9]",
        )
    }

    fn rule(&self) -> ShapingRule {
        ShapingRule::ReturnCap {
            alpha: self.alpha,
            eta: self.eta,
            min_cap: self.min_cap,
        }
    }
}

shaped_ppo_settings!(RetcapConfig);

impl AlgorithmConfig for RetcapConfig {
    const ABOUT: &'static str = "Return capping with PPO (CVaR as the expected capped return)";

    /// PPO's paper defaults, α = 0.2 and η = 0.1 (the values of Mead et al.'s published
    /// example), no minimum cap.
    fn paper_defaults() -> Self {
        let ppo = PpoConfig::paper_defaults();
        Self {
            gamma: ppo.gamma,
            lambda: ppo.lambda,
            alpha: 0.2,
            eta: 0.1,
            min_cap: f64::NEG_INFINITY,
            clip: ppo.clip,
            policy_update: ppo.policy_update,
            value_update: ppo.value_update,
        }
    }
}
