//! APO — Absolute Policy Optimization: the trust-region step on the surrogate lower bound of
//! `B_k = J − k·V` (paper, Algorithm 1 with the practical objective; terms in
//! [`crate::objective::apo`]).

use serde::{Deserialize, Serialize};

use super::{AlgorithmConfig, Common, ConfigError, Penalty, PolicyStep, Settings};
use crate::objective::{Objective, PenaltyUnits, Switch};
use crate::proximal::ProximalConfig;
use crate::trust_region::TrustRegionConfig;

/// APO's settings, `[algo.apo]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ApoConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// Probability factor k ≥ 0.
    pub k: f64,
    /// ω1 ≥ 0, standing for `‖μ‖∞ / (1 − γ²)`.
    pub omega1: f64,
    /// ω2 ≥ 0, standing for `|H|_max` (when `h_max = "hyperparameter"`).
    pub omega2: f64,
    /// Where `|H|_max` comes from.
    pub h_max: super::HMaxMode,
    /// The units of `delta`, `V` and ω2 in the penalty (paper: reward units).
    #[serde(default)]
    pub penalty_units: PenaltyUnits,
    /// How `min_J_sq`'s switch is decided (paper: at every θ).
    #[serde(default)]
    pub switch: Switch,
    /// The trust-region step.
    pub trust_region: TrustRegionConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl ApoConfig {
    /// The penalty's settings as one [`Penalty`] (its checks, docs and paper defaults are
    /// [`Penalty`]'s). They are fields of this struct rather than a `#[serde(flatten)]`ed
    /// `Penalty` because serde cannot deny unknown fields through `flatten`, and a mistyped
    /// key of `[algo.apo]` must be an error; they stay flat keys (`k`, `omega1`, …) in
    /// config files and `--set`.
    fn penalty(&self) -> Penalty {
        Penalty {
            k: self.k,
            omega1: self.omega1,
            omega2: self.omega2,
            h_max: self.h_max,
            penalty_units: self.penalty_units,
            switch: self.switch,
        }
    }
}

impl Settings for ApoConfig {
    fn common(&self) -> Common {
        Common {
            gamma: self.gamma,
            lambda: self.lambda,
            value_update: self.value_update,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        self.penalty().validate()?;
        self.trust_region.validate()
    }

    fn objective(&self) -> Objective {
        Objective::Apo(self.penalty().params(self.gamma))
    }

    fn policy_step(&self) -> PolicyStep<'_> {
        PolicyStep::TrustRegion(&self.trust_region)
    }

    fn probability_factor(&self) -> Option<f64> {
        Some(self.k)
    }

    fn key_docs(&self) -> Vec<(String, &'static str)> {
        let mut docs = Common::key_docs();
        docs.extend(Penalty::KEY_DOCS.map(|(k, d)| (k.to_string(), d)));
        docs.extend(TrustRegionConfig::key_docs());
        docs
    }
}

impl AlgorithmConfig for ApoConfig {
    const ABOUT: &'static str = "Absolute Policy Optimization (trust region)";

    fn paper_defaults() -> Self {
        let (common, penalty) = (Common::PAPER, Penalty::PAPER);
        Self {
            gamma: common.gamma,
            lambda: common.lambda,
            k: penalty.k,
            omega1: penalty.omega1,
            omega2: penalty.omega2,
            h_max: penalty.h_max,
            penalty_units: penalty.penalty_units,
            switch: penalty.switch,
            trust_region: TrustRegionConfig::default(),
            value_update: common.value_update,
        }
    }
}
