//! A2C — Advantage Actor-Critic: Adam on the policy-gradient objective `mean(logp · adv)`.

use serde::{Deserialize, Serialize};

use super::{policy_update_docs, AlgorithmConfig, Common, ConfigError, PolicyStep, Settings};
use crate::objective::Objective;
use crate::proximal::{ProximalConfig, ProximalStep};

/// A2C's settings, `[algo.a2c]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct A2cConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// The policy's Adam update.
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl Settings for A2cConfig {
    fn common(&self) -> Common {
        Common {
            gamma: self.gamma,
            lambda: self.lambda,
            value_update: self.value_update,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        self.policy_update.validate("policy_update")
    }

    fn objective(&self) -> Objective {
        Objective::A2c
    }

    fn policy_step(&self) -> PolicyStep<'_> {
        PolicyStep::Proximal(ProximalStep::new(&self.policy_update))
    }

    fn key_docs(&self) -> Vec<(String, &'static str)> {
        let mut docs = Common::key_docs();
        docs.extend(policy_update_docs());
        docs
    }
}

impl AlgorithmConfig for A2cConfig {
    const ABOUT: &'static str = "Advantage Actor-Critic";

    fn paper_defaults() -> Self {
        let common = Common::PAPER;
        Self {
            gamma: common.gamma,
            lambda: common.lambda,
            // no KL early stop: A2C takes every step
            policy_update: ProximalConfig {
                target_kl: None,
                ..ProximalConfig::PAPER_POLICY
            },
            value_update: common.value_update,
        }
    }
}
