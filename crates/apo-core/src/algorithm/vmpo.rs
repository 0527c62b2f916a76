//! V-MPO — on-policy Maximum a Posteriori Policy Optimization (Song et al., 2020): the
//! top half of the batch by advantage, weighted by `softmax(adv / η)`, fitted by maximum
//! likelihood under a KL constraint with a learned temperature η and Lagrange multiplier α
//! (terms in [`crate::objective::vmpo`]), by Adam with KL early stopping.

use serde::{Deserialize, Serialize};

use super::{check, policy_update_docs};
use super::{AlgorithmConfig, Common, ConfigError, PolicyStep, Settings};
use crate::objective::vmpo::MIN_MULTIPLIER;
use crate::objective::{Objective, VmpoParams};
use crate::proximal::{ProximalConfig, ProximalStep};

/// V-MPO's settings, `[algo.vmpo]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VmpoConfig {
    /// Discount factor γ.
    pub gamma: f64,
    /// GAE λ.
    pub lambda: f64,
    /// ε_η > 0, the temperature's constraint.
    pub eps_eta: f64,
    /// ε_α > 0, the bound on the mean KL.
    pub eps_alpha: f64,
    /// The temperature η at the start of the run.
    pub eta_init: f64,
    /// The Lagrange multiplier α at the start of the run.
    pub alpha_init: f64,
    /// The policy's (and the multipliers') Adam update.
    pub policy_update: ProximalConfig,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl Settings for VmpoConfig {
    fn common(&self) -> Common {
        Common {
            gamma: self.gamma,
            lambda: self.lambda,
            value_update: self.value_update,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        check(
            positive(self.eps_eta) && self.eps_eta <= 10.0,
            "eps_eta",
            self.eps_eta,
            "must be in (0, 10]",
        )?;
        check(
            positive(self.eps_alpha) && self.eps_alpha <= 10.0,
            "eps_alpha",
            self.eps_alpha,
            "must be in (0, 10]",
        )?;
        check(
            self.eta_init >= MIN_MULTIPLIER && self.eta_init <= 1e8,
            "eta_init",
            self.eta_init,
            "must be in [1e-8, 1e8]",
        )?;
        check(
            self.alpha_init >= MIN_MULTIPLIER && self.alpha_init <= 1e8,
            "alpha_init",
            self.alpha_init,
            "must be in [1e-8, 1e8]",
        )?;
        self.policy_update.validate("policy_update")
    }

    /// V-MPO's objective with η and α at their initial values (the learner keeps the
    /// learned ones).
    fn objective(&self) -> Objective {
        Objective::Vmpo(VmpoParams {
            eps_eta: self.eps_eta,
            eps_alpha: self.eps_alpha,
            eta: self.eta_init,
            alpha: self.alpha_init,
        })
    }

    fn policy_step(&self) -> PolicyStep<'_> {
        PolicyStep::Proximal(ProximalStep::new(&self.policy_update))
    }

    fn key_docs(&self) -> Vec<(String, &'static str)> {
        let mut docs = Common::key_docs();
        docs.extend(
            [
                (
                    "eps_eta",
                    "ε_η, the temperature's constraint (paper: 0.008); (0, 10]",
                ),
                (
                    "eps_alpha",
                    "ε_α, the bound on the mean KL (paper: 0.05); (0, 10]",
                ),
                (
                    "eta_init",
                    "the temperature η at the start (paper: 1.0); [1e-8, 1e8]",
                ),
                (
                    "alpha_init",
                    "the multiplier α at the start (paper: 5.0); [1e-8, 1e8]",
                ),
            ]
            .map(|(k, d)| (k.to_string(), d)),
        );
        docs.extend(policy_update_docs());
        docs
    }
}

impl AlgorithmConfig for VmpoConfig {
    const ABOUT: &'static str =
        "V-MPO (top-half advantage weighting, learned temperature and KL multiplier)";

    fn paper_defaults() -> Self {
        let common = Common::PAPER;
        Self {
            gamma: common.gamma,
            lambda: common.lambda,
            eps_eta: 0.008,
            eps_alpha: 0.05,
            eta_init: 1.0,
            alpha_init: 5.0,
            policy_update: ProximalConfig::PAPER_POLICY,
            value_update: common.value_update,
        }
    }
}
