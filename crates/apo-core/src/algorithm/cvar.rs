//! CVaR — the CVaR policy gradient on the worst episodes, with PPO (Tamar, Glassner &
//! Mannor, "Optimizing the CVaR via Sampling", AAAI 2015; EPOpt-ε of Rajeswaran et al., ICLR
//! 2017, is its TRPO form, and the "CVaR PPO" baseline of Mead et al. 2025 this form): each
//! epoch's PPO update sees only the episodes whose return is at or below the batch's
//! α-quantile, their advantages normalized over them; the critic fits every row
//! ([`crate::shaping`]). At `alpha = 1` it is PPO, bit for bit.

use serde::{Deserialize, Serialize};

use super::{check, shaped_ppo_settings, AlgorithmConfig, ConfigError, PpoConfig};
use crate::proximal::ProximalConfig;
use crate::shaping::ShapingRule;

/// CVaR's settings, `[algo.cvar]`: PPO's, and the tail's probability.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CvarConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// The tail's probability α ∈ (0, 1]: the update sees the episodes at or below the
    /// batch's α-quantile of the return.
    pub alpha: f64,
    /// Clip ε ∈ (0, 1) of the probability ratio.
    pub clip: f64,
    /// The policy's Adam update.
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl CvarConfig {
    const RISK_DOCS: &'static [(&'static str, &'static str)] = &[(
        "alpha",
        "α, the tail's probability: the update sees the episodes at or below the batch's α-quantile of the return (1: PPO); (0, 1]",
    )];

    fn risk_check(&self) -> Result<(), ConfigError> {
        check_alpha("alpha", self.alpha)
    }

    fn rule(&self) -> ShapingRule {
        ShapingRule::WorstEpisodes { alpha: self.alpha }
    }
}

shaped_ppo_settings!(CvarConfig);

/// Checks a tail probability α ∈ (0, 1] named `field`.
pub(crate) fn check_alpha(field: &str, alpha: f64) -> Result<(), ConfigError> {
    check(
        alpha > 0.0 && alpha <= 1.0,
        field,
        alpha,
        "must be in (0, 1]",
    )
}

impl AlgorithmConfig for CvarConfig {
    const ABOUT: &'static str =
        "CVaR policy gradient with PPO on the episodes at or below the α-quantile";

    /// PPO's paper defaults, and α = 0.2 (Mead et al. 2025's CVaR level).
    fn paper_defaults() -> Self {
        let ppo = PpoConfig::paper_defaults();
        Self {
            gamma: ppo.gamma,
            lambda: ppo.lambda,
            alpha: 0.2,
            clip: ppo.clip,
            policy_update: ppo.policy_update,
            value_update: ppo.value_update,
        }
    }
}
