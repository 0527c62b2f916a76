//! ESPO — Early Stopping Policy Optimization (Sun et al., 2022, "You may not need ratio
//! clipping in PPO"): the plain surrogate `mean(ratio · adv)` ascended by full-batch Adam,
//! stopping before a step once the mean absolute ratio deviation `mean(|ratio − 1|)`
//! exceeds δ.

use serde::{Deserialize, Serialize};

use super::{check, policy_update_docs};
use super::{AlgorithmConfig, Common, ConfigError, PolicyStep, Settings};
use crate::objective::Objective;
use crate::proximal::{ProximalConfig, ProximalStep};

/// ESPO's settings, `[algo.espo]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EspoConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// δ > 0: the largest mean absolute ratio deviation `mean(|ratio − 1|)` at which a step is
    /// still taken.
    pub delta: f64,
    /// The policy's Adam update (ESPO's default has no KL stop).
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl Settings for EspoConfig {
    fn common(&self) -> Common {
        Common {
            gamma: self.gamma,
            lambda: self.lambda,
            value_update: self.value_update,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        check(
            self.delta > 0.0 && self.delta <= 10.0,
            "delta",
            self.delta,
            "must be in (0, 10]",
        )?;
        self.policy_update.validate("policy_update")
    }

    fn objective(&self) -> Objective {
        Objective::Trpo
    }

    fn policy_step(&self) -> PolicyStep<'_> {
        PolicyStep::Proximal(ProximalStep {
            update: &self.policy_update,
            max_ratio_deviation: Some(self.delta),
        })
    }

    fn key_docs(&self) -> Vec<(String, &'static str)> {
        let mut docs = Common::key_docs();
        docs.push((
            "delta".to_string(),
            "δ: stop before a step once mean(|ratio − 1|) exceeds it (paper: 0.25); (0, 10]",
        ));
        docs.extend(policy_update_docs());
        docs
    }
}

impl AlgorithmConfig for EspoConfig {
    const ABOUT: &'static str =
        "Early Stopping Policy Optimization (surrogate, Adam, ratio-deviation stop)";

    fn paper_defaults() -> Self {
        let common = Common::PAPER;
        Self {
            gamma: common.gamma,
            lambda: common.lambda,
            delta: 0.25,
            policy_update: ProximalConfig {
                target_kl: None,
                ..ProximalConfig::PAPER_POLICY
            },
            value_update: common.value_update,
        }
    }
}
