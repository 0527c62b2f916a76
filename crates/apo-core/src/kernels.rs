//! Where an update's network passes run.
//!
//! The trust-region step's Fisher-vector products, the proximal algorithms' policy steps and
//! the value fit are first-order passes through the built-in MLPs, repeated many times per
//! epoch (10 conjugate-gradient products, up to 80 Adam steps each). On a GPU backend Burn's graph is the fast way to run them. On a CPU
//! backend Burn runs each tensor op as its own pass over memory, and the host kernels of
//! apo-core (matmuls plus one fused sweep per layer, `f32`) are several times faster
//! (`docs/benchmarks.md`). Policies without a host form (your own [`crate::Policy`]) and
//! critics of another shape always take Burn's path.

use serde::{Deserialize, Serialize};

/// Where the Fisher-vector products, the proximal policy steps and the value fit run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kernels {
    /// Burn's autodiff on the learner's backend (any backend; the choice for a GPU).
    #[default]
    Backend,
    /// apo-core's `f32` host kernels (the choice for a CPU backend). The results differ from
    /// the backend's only by rounding.
    Host,
}
