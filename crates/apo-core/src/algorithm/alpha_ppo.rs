//! AlphaPPO — PPO with an α-divergence proximity term (Xu et al., 2023, "Improving proximal
//! policy optimization with alpha divergence"): Adam ascends
//! `(1 − β) · mean(ratio · adv) − β · mean_s D_α(π_old(·|s) ‖ π_θ(·|s))`
//! ([`crate::distribution::DistParams::alpha_divergence_from`]) with KL early stopping.

use serde::{Deserialize, Serialize};

use super::{check, policy_update_docs};
use super::{AlgorithmConfig, Common, ConfigError, PolicyStep, Settings};
use crate::objective::Objective;
use crate::proximal::{ProximalConfig, ProximalStep};

/// AlphaPPO's settings, `[algo.alphappo]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlphaPpoConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// α ∈ (0, 1) of the divergence (→ 1: the KL from the old policy).
    pub alpha: f64,
    /// The divergence's weight β ∈ [0, 1].
    pub beta: f64,
    /// The policy's Adam update.
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl Settings for AlphaPpoConfig {
    fn common(&self) -> Common {
        Common {
            gamma: self.gamma,
            lambda: self.lambda,
            value_update: self.value_update,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        check(
            self.alpha > 0.0 && self.alpha < 1.0,
            "alpha",
            self.alpha,
            "must be in (0, 1)",
        )?;
        check(
            (0.0..=1.0).contains(&self.beta),
            "beta",
            self.beta,
            "must be in [0, 1]",
        )?;
        self.policy_update.validate("policy_update")
    }

    fn objective(&self) -> Objective {
        Objective::AlphaPpo {
            alpha: self.alpha,
            beta: self.beta,
        }
    }

    fn policy_step(&self) -> PolicyStep<'_> {
        PolicyStep::Proximal(ProximalStep::new(&self.policy_update))
    }

    fn key_docs(&self) -> Vec<(String, &'static str)> {
        let mut docs = Common::key_docs();
        docs.push((
            "alpha".to_string(),
            "α of the divergence D_α(π_old ‖ π) (paper: 0.5); (0, 1)",
        ));
        docs.push((
            "beta".to_string(),
            "weight β of the divergence against 1 − β of the surrogate (paper: 0.5); [0, 1]",
        ));
        docs.extend(policy_update_docs());
        docs
    }
}

impl AlgorithmConfig for AlphaPpoConfig {
    const ABOUT: &'static str = "PPO with an α-divergence penalty (Adam, KL early stop)";

    fn paper_defaults() -> Self {
        let common = Common::PAPER;
        Self {
            gamma: common.gamma,
            lambda: common.lambda,
            alpha: 0.5,
            beta: 0.5,
            policy_update: ProximalConfig::PAPER_POLICY,
            value_update: common.value_update,
        }
    }
}
