//! PPO — Proximal Policy Optimization: the clipped surrogate maximized by Adam with KL early
//! stopping.

use serde::{Deserialize, Serialize};

use super::{
    check_clip, policy_update_docs, AlgorithmConfig, Common, ConfigError, PolicyStep, Settings,
    CLIP_DOC,
};
use crate::objective::Objective;
use crate::proximal::{ProximalConfig, ProximalStep};

/// PPO's settings, `[algo.ppo]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PpoConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// Clip ε ∈ (0, 1) of the probability ratio.
    pub clip: f64,
    /// The policy's Adam update.
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl Settings for PpoConfig {
    fn common(&self) -> Common {
        Common {
            gamma: self.gamma,
            lambda: self.lambda,
            value_update: self.value_update,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        check_clip(self.clip)?;
        self.policy_update.validate("policy_update")
    }

    fn objective(&self) -> Objective {
        Objective::Ppo { clip: self.clip }
    }

    fn policy_step(&self) -> PolicyStep<'_> {
        PolicyStep::Proximal(ProximalStep::new(&self.policy_update))
    }

    fn key_docs(&self) -> Vec<(String, &'static str)> {
        let mut docs = Common::key_docs();
        docs.push((CLIP_DOC.0.to_string(), CLIP_DOC.1));
        docs.extend(policy_update_docs());
        docs
    }
}

impl AlgorithmConfig for PpoConfig {
    const ABOUT: &'static str = "Proximal Policy Optimization (clip)";

    fn paper_defaults() -> Self {
        let common = Common::PAPER;
        Self {
            gamma: common.gamma,
            lambda: common.lambda,
            clip: 0.2,
            policy_update: ProximalConfig::PAPER_POLICY,
            value_update: common.value_update,
        }
    }
}
