//! The PAPO objective: APO's terms with PPO-style clipping of the ratio.
//!
//! ```text
//! mean_surr = mean(min(ratio · adv, clip(ratio) · adv))
//! mv        = ω1 · mean(min(t(ratio), t(clip(ratio)))),   t(r) = (r − 1) · delta² + 2 · r · delta · ω2
//! vm, min_J_sq as in APO, with the clipped mean_surr
//! objective = mean_surr − k (mv + vm)
//! ```
//! `clip(r)` clamps to `[1 − ε, 1 + ε]`. Returns are `[1]` tensors; inputs `[batch]`; means are
//! over every rank's batch ([`Comm::mean`]).

use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

use super::apo::variance_increment;
use crate::collective::Comm;

/// `clip(ratio)` to `[1 − clip, 1 + clip]` → `[batch]`.
pub fn clip_ratio<B: Backend>(ratio: Tensor<B, 1>, clip: f64) -> Tensor<B, 1> {
    ratio.clamp(1.0 - clip, 1.0 + clip)
}

/// PPO's clipped surrogate `mean(min(ratio · adv, clip(ratio) · adv))`.
pub fn clipped_mean_surr<B: Backend>(
    comm: &Comm,
    ratio: Tensor<B, 1>,
    adv: Tensor<B, 1>,
    clip: f64,
) -> Tensor<B, 1> {
    let unclipped = ratio.clone() * adv.clone();
    let clipped = clip_ratio(ratio, clip) * adv;
    comm.mean(unclipped.min_pair(clipped))
}

/// The clipped MeanVariance term `ω1 · mean(min(t(ratio), t(clip(ratio))))`.
pub fn clipped_mean_variance<B: Backend>(
    comm: &Comm,
    ratio: Tensor<B, 1>,
    delta: Tensor<B, 1>,
    h: Tensor<B, 1>,
    omega1: f64,
    clip: f64,
) -> Tensor<B, 1> {
    let unclipped = variance_increment(ratio.clone(), delta.clone(), h.clone());
    let clipped = variance_increment(clip_ratio(ratio, clip), delta, h);
    comm.mean(unclipped.min_pair(clipped)).mul_scalar(omega1)
}
