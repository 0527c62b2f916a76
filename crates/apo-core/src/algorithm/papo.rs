//! PAPO — Proximal Absolute Policy Optimization: APO's terms with the probability ratio
//! clipped as in PPO, maximized by Adam with KL early stopping (terms in
//! [`crate::objective::papo`]).

use serde::{Deserialize, Serialize};

use super::{
    check_clip, policy_update_docs, AlgorithmConfig, Common, ConfigError, Penalty, PolicyStep,
    Settings,
};
use super::{HMaxMode, CLIP_DOC};
use crate::objective::{Objective, PenaltyUnits, Switch};
use crate::proximal::{ProximalConfig, ProximalStep};

/// PAPO's settings, `[algo.papo]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PapoConfig {
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
    pub h_max: HMaxMode,
    /// The units of `delta`, `V` and ω2 in the penalty (paper: reward units).
    #[serde(default)]
    pub penalty_units: PenaltyUnits,
    /// How `min_J_sq`'s switch is decided (paper: at every θ).
    #[serde(default)]
    pub switch: Switch,
    /// Clip ε ∈ (0, 1) of the probability ratio.
    pub clip: f64,
    /// The policy's Adam update.
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl PapoConfig {
    /// The penalty's settings as one [`Penalty`] (its checks, docs and paper defaults are
    /// [`Penalty`]'s). They are fields of this struct rather than a `#[serde(flatten)]`ed
    /// `Penalty` because serde cannot deny unknown fields through `flatten`, and a mistyped
    /// key of `[algo.papo]` must be an error; they stay flat keys (`k`, `omega1`, …) in
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

impl Settings for PapoConfig {
    fn common(&self) -> Common {
        Common {
            gamma: self.gamma,
            lambda: self.lambda,
            value_update: self.value_update,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        self.penalty().validate()?;
        check_clip(self.clip)?;
        self.policy_update.validate("policy_update")
    }

    fn objective(&self) -> Objective {
        Objective::Papo {
            params: self.penalty().params(self.gamma),
            clip: self.clip,
        }
    }

    fn policy_step(&self) -> PolicyStep<'_> {
        PolicyStep::Proximal(ProximalStep::new(&self.policy_update))
    }

    fn probability_factor(&self) -> Option<f64> {
        Some(self.k)
    }

    fn key_docs(&self) -> Vec<(String, &'static str)> {
        let mut docs = Common::key_docs();
        docs.extend(Penalty::KEY_DOCS.map(|(k, d)| (k.to_string(), d)));
        docs.push((CLIP_DOC.0.to_string(), CLIP_DOC.1));
        docs.extend(policy_update_docs());
        docs
    }
}

impl AlgorithmConfig for PapoConfig {
    const ABOUT: &'static str =
        "Proximal Absolute Policy Optimization (clipping, Adam, KL early stop)";

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
            clip: 0.2,
            policy_update: ProximalConfig::PAPER_POLICY,
            value_update: common.value_update,
        }
    }
}
