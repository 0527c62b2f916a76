//! # apo-theory
//!
//! A small "theory lab": finite (tabular) Markov decision processes whose quantities can be
//! computed *exactly*, so that the statements of the APO paper — above all Theorem 1, which
//! bounds the change of the return variance between two policies — can be checked to machine
//! precision instead of through noisy rollouts.
//!
//! Everything is `f64`, and nothing here depends on Burn.
//!
//! * [`mdp`] — [`Mdp`]: transitions `P(s'|s,a)`, rewards `r(s,a,s')`, start distribution `μ`
//!   and discount `γ`; random instances and a few hand-made ones where the return variance
//!   matters ([`Mdp::safe_or_risky`], [`Mdp::chain_gamble`]);
//! * [`policy`] — [`TabularPolicy`]: `π(a|s)`, with KL divergence and total variation between
//!   policies;
//! * [`exact`] — [`Evaluation`]: exact `V`, `Q`, advantages, `J`, the discounted state
//!   distribution `d^π`, the second moment and variance of the discounted return (Sobel 1982),
//!   its split into `MV_π` and `VM_π`, and the action-value variance `ω_π`;
//! * [`montecarlo`] — sampled discounted returns, to check the exact quantities against.
//!
//! ## Index layouts
//!
//! With `S` states and `A` actions, all tables are flat, row-major `Vec<f64>`:
//!
//! | quantity                  | shape       | index of `(s, a, s')`   |
//! |---------------------------|-------------|-------------------------|
//! | `P(s'\|s,a)`, `r(s,a,s')`  | `[S][A][S]` | `(s * A + a) * S + s'`  |
//! | `π(a\|s)`, `Q`, `A`        | `[S][A]`    | `s * A + a`             |
//! | `V`, `μ`, `d^π`, `M`, `ω` | `[S]`       | `s`                     |
//! | `P_π(s'\|s)`               | `[S][S]`    | `s * S + s'`            |
//!
//! ## Example
//!
//! ```
//! use apo_theory::{Evaluation, Mdp, TabularPolicy};
//!
//! let mdp = Mdp::safe_or_risky(0.9);
//! let risky = TabularPolicy::deterministic(3, 2, &[Mdp::RISKY_ACTION, 0, 0]);
//! let ev = Evaluation::new(&mdp, &risky).unwrap();
//! assert!((ev.j - 1.0).abs() < 1e-12);
//! assert!((ev.return_variance - 4.0).abs() < 1e-12);
//! ```

pub mod bound;
pub mod checks;
pub mod exact;
pub mod mdp;
pub mod montecarlo;
pub mod policy;
pub mod practical;

pub use exact::Evaluation;
pub use mdp::{Mdp, PROB_TOL};
pub use montecarlo::{sample_returns, truncation_bound, SampleStats};
pub use policy::TabularPolicy;

/// Errors from validating MDPs and policies, and from the exact linear solves.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TheoryError {
    /// A state or action space is empty (`what` is `"states"` or `"actions"`).
    #[error("the number of {what} must be at least 1, got 0")]
    EmptySpace {
        /// `"states"` or `"actions"`.
        what: &'static str,
    },
    /// A flat table has the wrong length.
    #[error("{what} has length {got}, expected {expected}")]
    LengthMismatch {
        /// Which table, e.g. `"transition"`.
        what: &'static str,
        /// The length its shape requires.
        expected: usize,
        /// The length it has.
        got: usize,
    },
    /// An entry is NaN or infinite.
    #[error("{what} is not finite: {value}")]
    NonFinite {
        /// The entry, e.g. `"reward r(s=1, a=0, s'=2)"`.
        what: String,
        /// Its value.
        value: f64,
    },
    /// A probability is negative.
    #[error("{what} is negative: {value}")]
    NegativeProbability {
        /// The entry, e.g. `"transition P(s'=2 | s=1, a=0)"`.
        what: String,
        /// Its value.
        value: f64,
    },
    /// A probability vector does not sum to 1 within [`PROB_TOL`].
    #[error("{what} sums to {sum}, expected 1 (tolerance {PROB_TOL:e})")]
    NotNormalized {
        /// The distribution, e.g. `"transition row P(.|s=1, a=0)"`.
        what: String,
        /// Its sum.
        sum: f64,
    },
    /// The discount is not in `[0, 1)`.
    #[error("discount gamma = {0} is outside [0, 1)")]
    InvalidGamma(f64),
    /// A policy's shape does not match the MDP's.
    #[error(
        "policy has {policy_states} states x {policy_actions} actions, \
         but the MDP has {mdp_states} states x {mdp_actions} actions"
    )]
    ShapeMismatch {
        /// States of the MDP.
        mdp_states: usize,
        /// Actions of the MDP.
        mdp_actions: usize,
        /// States of the policy.
        policy_states: usize,
        /// Actions of the policy.
        policy_actions: usize,
    },
    /// A linear system could not be solved (singular matrix or non-finite solution).
    #[error("the linear system for {what} is singular or its solution is not finite")]
    SingularSystem {
        /// Which system, e.g. `"V = (I - γ P_π)^-1 r_π"`.
        what: &'static str,
    },
}
