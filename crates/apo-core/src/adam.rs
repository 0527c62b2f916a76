//! Adam's constants, shared by every optimizer in apo: Burn's Adam on the networks, the host
//! value fit and V-MPO's multipliers.

/// Adam's β₁, β₂ and ε of every optimizer in apo (PyTorch's defaults, as in the paper's
/// implementation).
pub(crate) const ADAM_BETA_1: f32 = 0.9;
/// See [`ADAM_BETA_1`].
pub(crate) const ADAM_BETA_2: f32 = 0.999;
/// See [`ADAM_BETA_1`].
pub(crate) const ADAM_EPSILON: f32 = 1e-8;
