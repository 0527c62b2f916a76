//! Where an update's network passes run.
//!
//! The trust-region step (its Fisher-vector products, its gradient, its line-search tries), the
//! proximal algorithms' policy steps, an update's diagnostics and the value fit are passes
//! through the built-in MLPs over the whole batch, repeated many times per epoch (10
//! conjugate-gradient products, up to 80 Adam steps each). On a GPU backend Burn's graph is
//! the fast way to run them. On a CPU
//! backend Burn runs each tensor op as its own pass over memory, and the host kernels of
//! apo-core (matmuls plus one fused sweep per layer, `f32`) are several times faster
//! (`docs/benchmarks.md`). Policies without a host form (your own [`crate::Policy`]) and
//! critics of another shape always take Burn's path.

use serde::{Deserialize, Serialize};

/// Where an update's network passes (the policy's and the value fit's) run.
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
