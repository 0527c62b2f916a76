//! TRPO — Trust Region Policy Optimization: the trust-region step on the surrogate
//! `mean(ratio · adv)`.

use serde::{Deserialize, Serialize};

use super::{AlgorithmConfig, Common, ConfigError, PolicyStep, Settings};
use crate::objective::Objective;
use crate::proximal::ProximalConfig;
use crate::trust_region::TrustRegionConfig;

/// TRPO's settings, `[algo.trpo]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrpoConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// The trust-region step.
    pub trust_region: TrustRegionConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl Settings for TrpoConfig {
    fn common(&self) -> Common {
        Common {
            gamma: self.gamma,
            lambda: self.lambda,
            value_update: self.value_update,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        self.trust_region.validate()
    }

    fn objective(&self) -> Objective {
        Objective::Trpo
    }

    fn policy_step(&self) -> PolicyStep<'_> {
        PolicyStep::TrustRegion(&self.trust_region)
    }

    fn key_docs(&self) -> Vec<(String, &'static str)> {
        let mut docs = Common::key_docs();
        docs.extend(TrustRegionConfig::key_docs());
        docs
    }
}

impl AlgorithmConfig for TrpoConfig {
    const ABOUT: &'static str = "Trust Region Policy Optimization";

    fn paper_defaults() -> Self {
        let common = Common::PAPER;
        Self {
            gamma: common.gamma,
            lambda: common.lambda,
            trust_region: TrustRegionConfig::default(),
            value_update: common.value_update,
        }
    }
}
