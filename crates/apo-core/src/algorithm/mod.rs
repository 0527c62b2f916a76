//! The algorithms: one module each, registered by one line of `algorithms!`.
//!
//! An algorithm's module holds its settings — its own section of a run's config,
//! `[algo.<name>]` — with the paper's defaults, their ranges and their documentation, and says
//! which objective ([`Objective`]) its policy update maximizes and by which step
//! ([`PolicyStep`]: the trust-region step or Adam with KL early stopping). The rest of the
//! update (batch, value fit, KL, report) is the [`Learner`](crate::Learner)'s and is shared.
//!
//! # Adding an algorithm
//!
//! Write its module (a settings struct implementing [`Settings`] and [`AlgorithmConfig`]) and
//! add one line to the `algorithms!` invocation below: the [`Algorithm`] enum, the
//! [`AlgoConfig`] enum (serde's externally tagged form: the section `[algo.<name>]`), the list
//! of names and every dispatch are generated from it.

mod a2c;
mod alpha_ppo;
mod apo;
mod cvar;
mod espo;
mod mvpi;
mod papo;
mod ppo;
mod retcap;
mod tailppo;
mod trpo;
mod vmpo;

use std::fmt;
use std::str::FromStr;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::objective::{ApoParams, HMax, Objective, PenaltyUnits, Switch};
use crate::proximal::{ProximalConfig, ProximalStep};
use crate::shaping::ShapingRule;
use crate::trust_region::TrustRegionConfig;
pub use crate::validate::ConfigError;
pub(crate) use crate::validate::{check, finite_nonneg, shown};

pub use a2c::A2cConfig;
pub use alpha_ppo::AlphaPpoConfig;
pub use apo::ApoConfig;
pub use cvar::CvarConfig;
pub use espo::EspoConfig;
pub use mvpi::MvpiConfig;
pub use papo::PapoConfig;
pub use ppo::PpoConfig;
pub use retcap::RetcapConfig;
pub use tailppo::TailPpoConfig;
pub use trpo::TrpoConfig;
pub use vmpo::VmpoConfig;

/// The probability factor `k` of the reported bound `J − k·Var` for algorithms that have none
/// of their own (the paper's `k`).
pub const PAPER_PROBABILITY_FACTOR: f64 = 7.0;

/// The policy update of an algorithm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PolicyStep<'a> {
    /// Conjugate gradient on Fisher-vector products, step scaling, backtracking line search.
    TrustRegion(&'a TrustRegionConfig),
    /// Adam passes with early stopping (KL, or ESPO's ratio deviation).
    Proximal(ProximalStep<'a>),
}

/// The settings every algorithm has: the return estimation and the critic's update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Common {
    /// Discount factor γ ∈ [0, 1).
    pub gamma: f64,
    /// GAE λ ∈ [0, 1].
    pub lambda: f64,
    /// The value network's Adam update.
    pub value_update: ProximalConfig,
}

impl Common {
    /// The paper's: γ 0.99, λ 0.97, 80 value iterations of Adam at lr 1e-3, full batch.
    pub const PAPER: Common = Common {
        gamma: 0.99,
        lambda: 0.97,
        value_update: ProximalConfig {
            lr: 1e-3,
            iters: 80,
            target_kl: None,
            minibatch_size: None,
        },
    };

    fn validate(&self) -> Result<(), ConfigError> {
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
        self.value_update.validate("value_update")
    }

    /// Documentation of the common keys, relative to an algorithm's section.
    pub fn key_docs() -> Vec<(String, &'static str)> {
        let mut docs: Vec<(String, &'static str)> = [
            ("gamma", "discount factor γ; [0, 1)"),
            ("lambda", "GAE λ; [0, 1]"),
            ("value_update", "the value network's Adam update"),
        ]
        .map(|(k, d)| (k.to_string(), d))
        .into();
        docs.extend(ProximalConfig::key_docs("value_update"));
        docs
    }
}

/// The APO penalty's settings, shared by APO and PAPO.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Penalty {
    /// Probability factor `k ≥ 0`.
    pub k: f64,
    /// ω1 ≥ 0, standing for `‖μ‖∞ / (1 − γ²)`.
    pub omega1: f64,
    /// ω2 ≥ 0, standing for `|H|_max` (when `h_max = "hyperparameter"`).
    pub omega2: f64,
    /// Where `|H|_max` comes from.
    pub h_max: HMaxMode,
    /// The units of `delta`, `V` and ω2 (paper: reward units).
    pub penalty_units: PenaltyUnits,
    /// How `min_J_sq`'s switch is decided (paper: at every θ).
    pub switch: Switch,
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

impl Penalty {
    /// The paper's: k = 7, ω1 = ω2 = 0.005 (the middle of its grid {0.001, 0.003, 0.005,
    /// 0.007, 0.01}²), |H|_max from ω2.
    pub const PAPER: Penalty = Penalty {
        k: 7.0,
        omega1: 0.005,
        omega2: 0.005,
        h_max: HMaxMode::Hyperparameter,
        penalty_units: PenaltyUnits::Reward,
        switch: Switch::Paper,
    };

    fn validate(&self) -> Result<(), ConfigError> {
        // bounded so that the penalty stays finite in f32 (a k of 1e308 made the policy loss
        // infinite and the error named the learning rates, not k)
        let within = |x: f64| finite_nonneg(x) && x <= Self::MAX;
        let rule = "must be in [0, 1000]";
        check(within(self.k), "k", shown(self.k), rule)?;
        check(within(self.omega1), "omega1", shown(self.omega1), rule)?;
        check(within(self.omega2), "omega2", shown(self.omega2), rule)
    }

    /// The largest k, ω1 and ω2 accepted.
    const MAX: f64 = 1000.0;

    /// The objective's parameters for discount `gamma`.
    fn params(&self, gamma: f64) -> ApoParams {
        ApoParams {
            k: self.k,
            omega1: self.omega1,
            h_max: match self.h_max {
                HMaxMode::Hyperparameter => HMax::Fixed(self.omega2),
                HMaxMode::Estimated => HMax::Estimated,
            },
            gamma,
            units: self.penalty_units,
            switch: self.switch,
        }
    }

    const KEY_DOCS: [(&'static str, &'static str); 6] = [
        ("k", "probability factor k of the bound J − k·Var (paper: 7); [0, 1000]"),
        (
            "omega1",
            "ω1, stands for ‖μ‖∞/(1−γ²) (paper grid 0.001..0.01); [0, 1000]",
        ),
        (
            "omega2",
            "ω2, stands for |H|_max when h_max = \"hyperparameter\"; [0, 1000]",
        ),
        (
            "h_max",
            "where |H|_max comes from: \"hyperparameter\" (ω2) or \"estimated\" (paper's ablation Q3)",
        ),
        (
            "penalty_units",
            "units of delta, V and ω2 in the penalty: \"reward\" (the paper) or \"advantage\" (divided by the advantages' normalizing std: scale-free)",
        ),
        (
            "switch",
            "min_J_sq's switch: \"paper\" (decided at every θ), \"held\" (decided at θ_j for the whole update) or \"off\" (min_J_sq = 0)",
        ),
    ];
}

/// The documentation of a proximal policy update's keys, `policy_update.*`.
pub(crate) fn policy_update_docs() -> Vec<(String, &'static str)> {
    let mut docs = vec![("policy_update".to_string(), "the policy's Adam update")];
    docs.extend(ProximalConfig::key_docs("policy_update"));
    docs
}

/// Validates a clip ε ∈ (0, 1).
pub(crate) fn check_clip(clip: f64) -> Result<(), ConfigError> {
    check(clip > 0.0 && clip < 1.0, "clip", clip, "must be in (0, 1)")
}

/// Documentation of `clip`.
pub(crate) const CLIP_DOC: (&str, &str) = (
    "clip",
    "clip ε of the probability ratio (paper: 0.2); (0, 1)",
);

/// What every algorithm's settings tell the learner (object-safe; see [`AlgorithmConfig`]).
pub trait Settings: fmt::Debug {
    /// γ, λ and the value update.
    fn common(&self) -> Common;
    /// Checks every field's range; the error names the first bad field, relative to the
    /// algorithm's section (`k`, `trust_region.max_kl`).
    fn validate(&self) -> Result<(), ConfigError>;
    /// The objective the policy update maximizes.
    fn objective(&self) -> Objective;
    /// How the policy is updated.
    fn policy_step(&self) -> PolicyStep<'_>;
    /// The probability factor `k` of the algorithm's bound, if it has one.
    fn probability_factor(&self) -> Option<f64> {
        None
    }
    /// How the epoch's batch is shaped before the update ([`crate::shaping`]), if it is.
    fn shaping(&self) -> Option<ShapingRule> {
        None
    }
    /// Every key of the section with what it does and its range (relative dotted paths).
    fn key_docs(&self) -> Vec<(String, &'static str)>;
}

/// An algorithm's settings type, as registered in `algorithms!`.
pub trait AlgorithmConfig:
    Settings + Clone + PartialEq + Serialize + DeserializeOwned + Send + Sync + 'static
{
    /// A one-line description.
    const ABOUT: &'static str;
    /// The paper's defaults (Table "Important hyper-parameters").
    fn paper_defaults() -> Self;
}

/// The [`Settings`] of an algorithm that is PPO on a shaped batch (`mvpi`, `cvar`, `retcap`;
/// [`crate::shaping`]): its struct has PPO's fields (`gamma`, `lambda`, `clip`,
/// `policy_update`, `value_update`) flat beside its own — `serde` cannot deny unknown fields
/// through `flatten` — and, as inherent items, `fn risk_check(&self) -> Result<(),
/// ConfigError>`, `fn rule(&self) -> ShapingRule` and `const RISK_DOCS: &[(&str, &str)]`.
macro_rules! shaped_ppo_settings {
    ($config:ty) => {
        impl $config {
            /// The PPO update the batch is shaped for.
            fn ppo(&self) -> $crate::algorithm::PpoConfig {
                $crate::algorithm::PpoConfig {
                    gamma: self.gamma,
                    lambda: self.lambda,
                    clip: self.clip,
                    policy_update: self.policy_update,
                    value_update: self.value_update,
                }
            }
        }

        impl $crate::algorithm::Settings for $config {
            fn common(&self) -> $crate::algorithm::Common {
                self.ppo().common()
            }

            fn validate(&self) -> Result<(), $crate::algorithm::ConfigError> {
                self.risk_check()?;
                self.ppo().validate()
            }

            fn objective(&self) -> $crate::objective::Objective {
                self.ppo().objective()
            }

            fn policy_step(&self) -> $crate::algorithm::PolicyStep<'_> {
                $crate::algorithm::PolicyStep::Proximal($crate::proximal::ProximalStep::new(
                    &self.policy_update,
                ))
            }

            fn shaping(&self) -> Option<$crate::shaping::ShapingRule> {
                Some(self.rule())
            }

            fn key_docs(&self) -> Vec<(String, &'static str)> {
                let mut docs = self.ppo().key_docs();
                docs.extend(Self::RISK_DOCS.iter().map(|&(k, d)| (k.to_string(), d)));
                docs
            }
        }
    };
}
use shaped_ppo_settings;

/// Generates [`Algorithm`], [`AlgoConfig`] and their dispatch from one line per algorithm:
/// `Variant(SettingsType) = "name"`.
macro_rules! algorithms {
    ($($variant:ident($config:ty) = $name:literal),* $(,)?) => {
        /// The policy-optimization algorithms.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum Algorithm {
            $(
                #[doc = concat!("The algorithm of [`", stringify!($config), "`].")]
                $variant,
            )*
        }

        /// The settings of the chosen algorithm: in a config file, its section
        /// `[algo.<name>]` (serde's externally tagged form).
        #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
        pub enum AlgoConfig {
            $(
                #[doc = concat!("`[algo.", $name, "]`: [`", stringify!($config), "`].")]
                #[serde(rename = $name)]
                $variant($config),
            )*
        }

        impl Algorithm {
            /// Every algorithm, in registration order.
            pub const ALL: &'static [Algorithm] = &[$(Algorithm::$variant),*];

            /// The lowercase name used on the command line and in configs.
            pub fn name(self) -> &'static str {
                match self {
                    $(Algorithm::$variant => $name,)*
                }
            }

            /// A one-line description.
            pub fn about(self) -> &'static str {
                match self {
                    $(Algorithm::$variant => <$config as AlgorithmConfig>::ABOUT,)*
                }
            }
        }

        impl AlgoConfig {
            /// The paper's defaults for `algo`.
            pub fn paper_defaults(algo: Algorithm) -> Self {
                match algo {
                    $(Algorithm::$variant => {
                        AlgoConfig::$variant(<$config as AlgorithmConfig>::paper_defaults())
                    })*
                }
            }

            /// The algorithm.
            pub fn algorithm(&self) -> Algorithm {
                match self {
                    $(AlgoConfig::$variant(_) => Algorithm::$variant,)*
                }
            }

            /// The algorithm's settings.
            pub fn settings(&self) -> &dyn Settings {
                match self {
                    $(AlgoConfig::$variant(c) => c,)*
                }
            }
        }
    };
}

algorithms! {
    Apo(ApoConfig) = "apo",
    Papo(PapoConfig) = "papo",
    Trpo(TrpoConfig) = "trpo",
    Ppo(PpoConfig) = "ppo",
    A2c(A2cConfig) = "a2c",
    Espo(EspoConfig) = "espo",
    AlphaPpo(AlphaPpoConfig) = "alphappo",
    Vmpo(VmpoConfig) = "vmpo",
    Mvpi(MvpiConfig) = "mvpi",
    Cvar(CvarConfig) = "cvar",
    Retcap(RetcapConfig) = "retcap",
    TailPpo(TailPpoConfig) = "tailppo",
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
            .iter()
            .copied()
            .find(|a| a.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                let names: Vec<&str> = Algorithm::ALL.iter().map(|a| a.name()).collect();
                format!("unknown algorithm `{s}`; known: {}", names.join(", "))
            })
    }
}

impl AlgoConfig {
    /// γ, λ and the value update.
    pub fn common(&self) -> Common {
        self.settings().common()
    }

    /// Checks every field's range; the error names the first bad field, relative to the
    /// algorithm's section.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.common().validate()?;
        self.settings().validate()
    }

    /// The objective the policy update maximizes.
    pub fn objective(&self) -> Objective {
        self.settings().objective()
    }

    /// The probability factor `k` of the reported bound `J − k·Var`: the algorithm's own, or
    /// [`PAPER_PROBABILITY_FACTOR`].
    pub fn probability_factor(&self) -> f64 {
        self.settings()
            .probability_factor()
            .unwrap_or(PAPER_PROBABILITY_FACTOR)
    }
}
