//! The hyperparameters of every algorithm, with the paper's defaults and validation.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::objective::{ApoParams, HMax, Objective};
use crate::proximal::ProximalConfig;
use crate::trust_region::TrustRegionConfig;

/// The policy-optimization algorithms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Algorithm {
    /// Absolute Policy Optimization (trust region).
    Apo,
    /// Proximal Absolute Policy Optimization (clipping, Adam, KL early stop).
    Papo,
    /// Trust Region Policy Optimization.
    Trpo,
    /// Proximal Policy Optimization (clip).
    Ppo,
    /// Advantage Actor-Critic.
    A2c,
}

impl Algorithm {
    /// Every algorithm, in the order `apo list` shows them.
    pub const ALL: [Algorithm; 5] = [
        Algorithm::Apo,
        Algorithm::Papo,
        Algorithm::Trpo,
        Algorithm::Ppo,
        Algorithm::A2c,
    ];

    /// The lowercase name used on the command line and in configs.
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Apo => "apo",
            Algorithm::Papo => "papo",
            Algorithm::Trpo => "trpo",
            Algorithm::Ppo => "ppo",
            Algorithm::A2c => "a2c",
        }
    }

    /// Whether the policy update is the trust-region step (else the proximal Adam step).
    pub fn is_trust_region(self) -> bool {
        matches!(self, Algorithm::Apo | Algorithm::Trpo)
    }
}

impl fmt::Display for Algorithm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Algorithm {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Algorithm::ALL
            .into_iter()
            .find(|a| a.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| format!("unknown algorithm `{s}`; known: apo, papo, trpo, ppo, a2c"))
    }
}

/// How `|H|_max` is obtained (paper's ablation Q3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HMaxMode {
    /// The hyperparameter `omega2`.
    Hyperparameter,
    /// Estimated from the batch and the policy.
    Estimated,
}

/// An invalid hyperparameter: names the field, its value and the rule it breaks.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid `{field}` = {value}: {rule}")]
pub struct ConfigError {
    /// The field's path, e.g. `trust_region.max_kl`.
    pub field: String,
    /// The offending value, as written.
    pub value: String,
    /// What the value must satisfy.
    pub rule: String,
}

/// All hyperparameters of an update, for any [`Algorithm`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlgoConfig {
    /// The algorithm.
    pub algo: Algorithm,
    /// Discount factor γ ∈ [0, 1).
    pub gamma: f64,
    /// GAE λ ∈ [0, 1].
    pub lambda: f64,
    /// Probability factor k ≥ 0 (APO, PAPO).
    pub k: f64,
    /// ω1 ≥ 0, standing for `‖μ‖∞ / (1 − γ²)` (APO, PAPO).
    pub omega1: f64,
    /// ω2 ≥ 0, standing for `|H|_max` (APO, PAPO, when `h_max = "hyperparameter"`).
    pub omega2: f64,
    /// Where `|H|_max` comes from.
    pub h_max: HMaxMode,
    /// Clip ε ∈ (0, 1) (PPO, PAPO).
    pub clip: f64,
    /// The trust-region step (APO, TRPO).
    pub trust_region: TrustRegionConfig,
    /// The policy's Adam update (PAPO, PPO, A2C).
    pub policy_update: ProximalConfig,
    /// The value network's Adam update (all).
    pub value_update: ProximalConfig,
}

impl AlgoConfig {
    /// The paper's defaults for `algo` (Table "Important hyper-parameters"): γ 0.99,
    /// λ 0.97, δ / target KL 0.02, clip 0.2, k 7, 80 policy iterations at lr 3e-4,
    /// 80 value iterations at lr 1e-3, backtracking 0.8 × 100. ω1 = ω2 = 0.005 (the middle
    /// of the paper's grid {0.001, 0.003, 0.005, 0.007, 0.01}²).
    pub fn paper_defaults(algo: Algorithm) -> Self {
        Self {
            algo,
            gamma: 0.99,
            lambda: 0.97,
            k: 7.0,
            omega1: 0.005,
            omega2: 0.005,
            h_max: HMaxMode::Hyperparameter,
            clip: 0.2,
            trust_region: TrustRegionConfig::default(),
            policy_update: ProximalConfig {
                lr: 3e-4,
                iters: 80,
                target_kl: (algo != Algorithm::A2c).then_some(0.02),
                minibatch_size: None,
            },
            value_update: ProximalConfig {
                lr: 1e-3,
                iters: 80,
                target_kl: None,
                minibatch_size: None,
            },
        }
    }

    /// Checks every field's range; the error names the first bad field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        fn check(
            ok: bool,
            field: &str,
            value: impl fmt::Display,
            rule: &str,
        ) -> Result<(), ConfigError> {
            if ok {
                Ok(())
            } else {
                Err(ConfigError {
                    field: field.into(),
                    value: value.to_string(),
                    rule: rule.into(),
                })
            }
        }
        let finite_pos = |x: f64| x.is_finite() && x > 0.0;
        let finite_nonneg = |x: f64| x.is_finite() && x >= 0.0;
        check(
            (0.0..1.0).contains(&self.gamma),
            "gamma",
            self.gamma,
            "must be in [0, 1)",
        )?;
        check(
            (0.0..=1.0).contains(&self.lambda),
            "lambda",
            self.lambda,
            "must be in [0, 1]",
        )?;
        check(finite_nonneg(self.k), "k", self.k, "must be ≥ 0")?;
        check(
            finite_nonneg(self.omega1),
            "omega1",
            self.omega1,
            "must be ≥ 0",
        )?;
        check(
            finite_nonneg(self.omega2),
            "omega2",
            self.omega2,
            "must be ≥ 0",
        )?;
        check(
            self.clip > 0.0 && self.clip < 1.0,
            "clip",
            self.clip,
            "must be in (0, 1)",
        )?;
        let tr = &self.trust_region;
        check(
            finite_pos(tr.max_kl),
            "trust_region.max_kl",
            tr.max_kl,
            "must be > 0",
        )?;
        check(
            tr.cg_iters > 0,
            "trust_region.cg_iters",
            tr.cg_iters,
            "must be ≥ 1",
        )?;
        check(
            finite_nonneg(tr.cg_damping),
            "trust_region.cg_damping",
            tr.cg_damping,
            "must be ≥ 0",
        )?;
        check(
            finite_nonneg(tr.cg_residual_tol),
            "trust_region.cg_residual_tol",
            tr.cg_residual_tol,
            "must be ≥ 0",
        )?;
        check(
            tr.backtrack_coeff > 0.0 && tr.backtrack_coeff < 1.0,
            "trust_region.backtrack_coeff",
            tr.backtrack_coeff,
            "must be in (0, 1)",
        )?;
        check(
            tr.backtrack_iters > 0,
            "trust_region.backtrack_iters",
            tr.backtrack_iters,
            "must be ≥ 1",
        )?;
        for (name, p) in [
            ("policy_update", &self.policy_update),
            ("value_update", &self.value_update),
        ] {
            check(finite_pos(p.lr), &format!("{name}.lr"), p.lr, "must be > 0")?;
            check(
                p.iters > 0,
                &format!("{name}.iters"),
                p.iters,
                "must be ≥ 1",
            )?;
            if let Some(t) = p.target_kl {
                check(
                    finite_pos(t),
                    &format!("{name}.target_kl"),
                    t,
                    "must be > 0",
                )?;
            }
            if let Some(m) = p.minibatch_size {
                check(m > 0, &format!("{name}.minibatch_size"), m, "must be ≥ 1")?;
            }
        }
        Ok(())
    }

    /// The APO/PAPO penalty's parameters.
    pub fn apo_params(&self) -> ApoParams {
        let h_max = match self.h_max {
            HMaxMode::Hyperparameter => HMax::Fixed(self.omega2),
            HMaxMode::Estimated => HMax::Estimated,
        };
        ApoParams {
            k: self.k,
            omega1: self.omega1,
            h_max,
            gamma: self.gamma,
        }
    }

    /// The objective the policy update maximizes.
    pub fn objective(&self) -> Objective {
        match self.algo {
            Algorithm::Apo => Objective::Apo(self.apo_params()),
            Algorithm::Papo => Objective::Papo {
                params: self.apo_params(),
                clip: self.clip,
            },
            Algorithm::Trpo => Objective::Trpo,
            Algorithm::Ppo => Objective::Ppo { clip: self.clip },
            Algorithm::A2c => Objective::A2c,
        }
    }
}
