//! The APO objective (paper eq. "apo optimization weighted sum version", practical form).
//!
//! With `ratio = exp(logp_θ − logp_old)`, and hyperparameters `k` (probability factor),
//! `ω1` (stands for `‖μ‖∞ / (1 − γ²)`), `ω2` (stands for `|H|_max`):
//!
//! ```text
//! mean_surr = mean(ratio · adv)
//! mv        = ω1 · mean(| (ratio − 1) · delta² + 2 · ratio · delta · ω2 |)
//! min_J_sq  = mean_surr² + 2 · mean(V) · mean_surr,
//!             0 when mean_surr + mean(V) − bias < 0,
//!             bias = 4γ · |mean(logp_old − logp_θ)| · max(adv) / (1 − γ)²
//! vm        = (ω1 (1 − γ²) / k) · mean(|adv|² + 2 |adv| V) − min_J_sq
//! objective = mean_surr − k (mv + vm)
//! ```
//!
//! Two settings leave the paper's form (the defaults) for the variants of
//! `docs/algorithms.md` ("Variants that keep the step"): [`PenaltyUnits`] (the scale-free
//! penalty) and [`Switch`] (how `min_J_sq`'s switch is decided).
//!
//! Every function here returns a `[1]` tensor unless said otherwise; inputs named
//! `ratio`, `adv`, `delta`, `value`, `logp`, `logp_old` are `[batch]`. Means and maxima are over
//! every rank's batch ([`Comm::mean`], [`Comm::max_const`]; one rank: the plain ones).

use burn::tensor::backend::Backend;
use burn::tensor::{Tensor, TensorData};
use serde::{Deserialize, Serialize};

use crate::collective::Comm;

/// Where `|H(s, a, s')|_max` comes from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HMax {
    /// A hyperparameter ω2 (the paper's choice, which it reports works better).
    Fixed(f64),
    /// Estimated from the batch and the current policy, per sample (paper eq. "H def"),
    /// see [`estimated_h_max`].
    Estimated,
}

/// The units of the penalty's reward-valued inputs: the one-step advantages `delta`, the
/// critic values `V` and ω2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PenaltyUnits {
    /// As collected, in the task's reward units (the paper). The surrogate's advantages are
    /// normalized, the penalty's are not, so ω has to follow the reward scale.
    #[default]
    Reward,
    /// Divided by σ_A, the standard deviation the GAE advantages were normalized by
    /// ([`TensorBatch::adv_scale`](crate::TensorBatch::adv_scale)): every term is then in the surrogate's units and the
    /// objective does not change when the rewards are multiplied by a constant. The bound it
    /// stands for is `B_k` of the return measured in units of σ_A, i.e. `J − (k/σ_A)·Var` in
    /// reward units.
    Advantage,
}

/// How `min_J_sq`'s switch (`min_J_sq := 0` when the interval of `J` reaches zero) is decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Switch {
    /// At every evaluated θ: off when `mean_surr + mean(V) − bias < 0` (the paper). The bias
    /// grows with the sample KL, so the switch can turn off inside the line search.
    #[default]
    Paper,
    /// Once per update, at θ_j, and held for the whole line search (or all Adam iterations):
    /// off when `mean(adv) + mean(V) < 0`, the paper's condition at θ_j (ratio 1, bias 0).
    Held,
    /// Always off: `min_J_sq = 0`, so VarianceMean is held at its value at θ_j, the minimum of
    /// the exact VarianceMean bound over π (docs/algorithms.md).
    Off,
}

/// Hyperparameters of the APO penalty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ApoParams {
    /// Probability factor `k ≥ 0`; `k = 0` is TRPO's surrogate.
    pub k: f64,
    /// ω1, standing for `‖μ‖∞ / (1 − γ²)`.
    pub omega1: f64,
    /// `|H|_max`: ω2 or estimated.
    pub h_max: HMax,
    /// Discount factor γ of the task.
    pub gamma: f64,
    /// The units of `delta`, `V` and ω2 (paper: [`PenaltyUnits::Reward`]).
    #[serde(default)]
    pub units: PenaltyUnits,
    /// How `min_J_sq`'s switch is decided (paper: [`Switch::Paper`]).
    #[serde(default)]
    pub switch: Switch,
}

impl ApoParams {
    /// The paper's penalty: reward units, the switch decided at every θ.
    pub fn paper(k: f64, omega1: f64, h_max: HMax, gamma: f64) -> Self {
        Self {
            k,
            omega1,
            h_max,
            gamma,
            units: PenaltyUnits::Reward,
            switch: Switch::Paper,
        }
    }
}

/// `exp(logp − logp_old)` → `[batch]`.
pub fn ratio<B: Backend>(logp: Tensor<B, 1>, logp_old: Tensor<B, 1>) -> Tensor<B, 1> {
    (logp - logp_old).exp()
}

/// The importance-sampled surrogate `mean(ratio · adv)`.
pub fn mean_surr<B: Backend>(comm: &Comm, ratio: Tensor<B, 1>, adv: Tensor<B, 1>) -> Tensor<B, 1> {
    comm.mean(ratio * adv)
}

/// `t(r) = (r − 1) · delta² + 2 · r · delta · h` → `[batch]`: the sample form of
/// `E_π[A²] − E_πj[A²] + 2 E_π[A] |H|_max` (the `|H|²` term is constant and dropped).
pub fn variance_increment<B: Backend>(
    ratio: Tensor<B, 1>,
    delta: Tensor<B, 1>,
    h: Tensor<B, 1>,
) -> Tensor<B, 1> {
    let delta_sq = delta.clone().square();
    (ratio.clone().sub_scalar(1.0) * delta_sq) + (ratio * delta * h).mul_scalar(2.0)
}

/// MeanVariance term `mv = ω1 · mean(|t(ratio)|)`, with `h` the per-sample `|H|_max` (`[batch]`).
pub fn mean_variance<B: Backend>(
    comm: &Comm,
    ratio: Tensor<B, 1>,
    delta: Tensor<B, 1>,
    h: Tensor<B, 1>,
    omega1: f64,
) -> Tensor<B, 1> {
    comm.mean(variance_increment(ratio, delta, h).abs())
        .mul_scalar(omega1)
}

/// The bias of the lower bound of `J`: `4γ · |mean(logp_old − logp)| · max(adv) / (1 − γ)²`.
pub fn lower_bound_bias<B: Backend>(
    comm: &Comm,
    logp: Tensor<B, 1>,
    logp_old: Tensor<B, 1>,
    adv: Tensor<B, 1>,
    gamma: f64,
) -> Tensor<B, 1> {
    let scale = 4.0 * gamma / (1.0 - gamma).powi(2);
    comm.mean(logp_old - logp).abs() * comm.max_const(adv).mul_scalar(scale)
}

/// The minimal squared performance `min_J_sq = mean_surr² + 2 · mean(V) · mean_surr`,
/// switched to 0 where `off` (`[1]`, e.g. [`min_j_sq_off`]: the interval of `J` reaches zero).
/// The switch is a condition, not differentiated.
pub fn min_j_sq<B: Backend>(
    mean_surr: Tensor<B, 1>,
    mean_value: Tensor<B, 1>,
    off: Tensor<B, 1, burn::tensor::Bool>,
) -> Tensor<B, 1> {
    let value = mean_surr.clone().square() + (mean_value * mean_surr).mul_scalar(2.0);
    value.mask_fill(off, 0.0)
}

/// Whether `min_J_sq`'s switch is off under `switch` → `[1]` bool, without gradient:
/// [`Switch::Paper`] by [`min_j_sq_off`] at this θ; [`Switch::Held`] by the same condition at
/// θ_j, `mean(adv) + mean(V) < 0` (`adv`: `[batch]`); [`Switch::Off`] always.
pub fn switch_off<B: Backend>(
    comm: &Comm,
    switch: Switch,
    mean_surr: Tensor<B, 1>,
    mean_value: Tensor<B, 1>,
    bias: Tensor<B, 1>,
    adv: Tensor<B, 1>,
) -> Tensor<B, 1, burn::tensor::Bool> {
    match switch {
        Switch::Paper => min_j_sq_off(mean_surr, mean_value, bias),
        Switch::Held => (comm.mean(adv) + mean_value).detach().lower_elem(0.0),
        Switch::Off => Tensor::from_data(TensorData::from([true]), &mean_value.device()),
    }
}

/// Whether [`min_j_sq`]'s switch is off (`mean_surr + mean(V) − bias < 0`) → `[1]` bool,
/// without gradient.
pub fn min_j_sq_off<B: Backend>(
    mean_surr: Tensor<B, 1>,
    mean_value: Tensor<B, 1>,
    bias: Tensor<B, 1>,
) -> Tensor<B, 1, burn::tensor::Bool> {
    (mean_surr + mean_value - bias).detach().lower_elem(0.0)
}

/// VarianceMean term `vm = (ω1 (1 − γ²) / k) · mean(|adv|² + 2 |adv| V) − min_J_sq`, for `k > 0`.
pub fn variance_mean<B: Backend>(
    comm: &Comm,
    adv: Tensor<B, 1>,
    value: Tensor<B, 1>,
    min_j_sq: Tensor<B, 1>,
    omega1: f64,
    gamma: f64,
    k: f64,
) -> Tensor<B, 1> {
    let abs_adv = adv.abs();
    let spread = comm.mean(abs_adv.clone().square() + (abs_adv * value).mul_scalar(2.0));
    spread.mul_scalar(omega1 * (1.0 - gamma * gamma) / k) - min_j_sq
}

/// The estimated `|H(s, a, s')|_max` per sample → `[batch]`:
///
/// `2γ(1+γ) ε / (1−γ)² · D̄_KL + |ratio · adv|`, with `ε = max |adv|`.
///
/// Approximations (documented in `docs/algorithms.md`): the maximum KL over states is
/// replaced by the mean KL `kl_mean` (`[1]`, as the paper does for the trust region);
/// `Ā(s) = E_{a∼π}[A_πj(s, a)]` is estimated by the importance-sampled `ratio · adv`; and
/// along a sampled trajectory `γ η(s') − η(s) = −Ā(s)`, so the second term of the paper's
/// bound reduces to `|Ā(s)|`.
pub fn estimated_h_max<B: Backend>(
    comm: &Comm,
    ratio: Tensor<B, 1>,
    adv: Tensor<B, 1>,
    kl_mean: Tensor<B, 1>,
    gamma: f64,
) -> Tensor<B, 1> {
    let scale = 2.0 * gamma * (1.0 + gamma) / (1.0 - gamma).powi(2);
    let eps = comm.max_const(adv.clone().abs());
    let first = (eps * kl_mean).mul_scalar(scale);
    (ratio * adv).abs() + first
}

/// The per-sample `|H|_max` for `params` → `[batch]`; `kl_mean` is only evaluated in the
/// estimated mode.
pub fn h_max<B: Backend>(
    comm: &Comm,
    params: &ApoParams,
    ratio: Tensor<B, 1>,
    adv: Tensor<B, 1>,
    kl_mean: impl FnOnce() -> Tensor<B, 1>,
) -> Tensor<B, 1> {
    match params.h_max {
        HMax::Fixed(omega2) => Tensor::full(ratio.dims(), omega2, &ratio.device()),
        HMax::Estimated => estimated_h_max(comm, ratio, adv, kl_mean(), params.gamma),
    }
}
