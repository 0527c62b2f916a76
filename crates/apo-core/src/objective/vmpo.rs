//! V-MPO's loss (Song et al., 2020, "V-MPO: on-policy maximum a posteriori policy
//! optimization for discrete and continuous control", as the APO paper's baselines ran it).
//!
//! ```text
//! top            = the ⌊n/2⌋ rows of the (mini)batch with the largest advantages
//! ψ              = softmax(adv_top / sg(η))
//! policy_loss    = −Σ ψ · logp_θ(top)
//! temperature    = η ε_η + η · log mean(exp(adv_top / η))
//! KL             = mean_s KL(π_old(·|s) ‖ π_θ(·|s))       over the whole (mini)batch
//! trust_region   = α (ε_α − sg(KL)) + sg(α) · KL
//! loss           = policy_loss + temperature + trust_region   (objective = −loss)
//! ```
//! `sg` stops the gradient. The temperature η and the Lagrange multiplier α are learned with
//! the policy by Adam at the policy's learning rate and clamped to `≥` [`MIN_MULTIPLIER`]
//! after each step ([`Multipliers`]). Inputs are `[n]` tensors; the terms are `[1]`.
//!
//! On several ranks ([`crate::collective`]) the top half, ψ's softmax and the means are over the
//! union of the ranks' batches (ties in rank order, then row order): the advantages are
//! gathered, and ψ and `log mean exp` computed from all of them. The gradients of η and α
//! are then taken in closed form (`∂/∂η = ε_η + log mean exp(adv_top/η) − Σ ψ·adv_top / η`,
//! `∂/∂α = ε_α − KL`), since every rank holds their terms whole and autodiff's would be
//! counted once per rank.

use burn::tensor::activation::softmax;
use burn::tensor::backend::Backend;
use burn::tensor::{Int, Tensor, TensorData};
use serde::{Deserialize, Serialize};

use crate::adam::{ADAM_BETA_1, ADAM_BETA_2, ADAM_EPSILON};
use crate::distribution::DistParams;
use crate::flat::to_host;
use crate::tensor_batch::TensorBatch;

/// The smallest value of η and α (they are clamped to it after each step).
pub const MIN_MULTIPLIER: f64 = 1e-8;

/// V-MPO's constants, and the multipliers' values used by
/// [`Objective::evaluate`](super::Objective::evaluate) (where they are constants).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VmpoParams {
    /// ε_η, the temperature's constraint (paper: 0.008).
    pub eps_eta: f64,
    /// ε_α, the KL constraint (paper: 0.05).
    pub eps_alpha: f64,
    /// The temperature η > 0.
    pub eta: f64,
    /// The Lagrange multiplier α > 0.
    pub alpha: f64,
}

/// The rows of the top half of a batch by advantage: the indices of the `max(1, ⌊n/2⌋)`
/// largest values of `adv`, largest first (ties in row order); empty for an empty batch.
pub fn top_half(adv: &[f64]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..adv.len()).collect();
    // a stable sort keeps equal advantages in row order; NaN sorts last
    idx.sort_by(|&a, &b| adv[b].total_cmp(&adv[a]));
    let keep = (adv.len() / 2).max(1).min(adv.len());
    idx.truncate(keep);
    idx
}

/// `log mean(exp(x))` of a `[n]` tensor → `[1]`, shifted by the (constant) maximum.
fn log_mean_exp<B: Backend>(x: Tensor<B, 1>) -> Tensor<B, 1> {
    let n = x.dims()[0];
    let max = x.clone().max().detach();
    (x - max.clone().expand([n])).exp().sum().log() + max - (n as f64).ln()
}

/// `α (ε_α − sg(KL)) + sg(α) · KL` → `[1]`.
fn trust_region_loss<B: Backend>(
    alpha: Tensor<B, 1>,
    kl: Tensor<B, 1>,
    eps_alpha: f64,
) -> Tensor<B, 1> {
    alpha.clone() * kl.clone().detach().neg().add_scalar(eps_alpha) + alpha.detach() * kl
}

/// V-MPO's terms for the policy's distributions `dist` on `batch`, with the temperature `eta`
/// and the multiplier `alpha` (`[1]` each; leaves that require gradients when they are
/// learned, constants otherwise).
#[derive(Debug, Clone)]
pub struct VmpoTerms<B: Backend> {
    /// `−Σ ψ · logp_θ(top)`.
    pub policy_loss: Tensor<B, 1>,
    /// `η ε_η + η · log mean(exp(adv_top / η))`.
    pub temperature_loss: Tensor<B, 1>,
    /// `α (ε_α − sg(KL)) + sg(α) · KL`.
    pub trust_region_loss: Tensor<B, 1>,
    /// The mean `KL(π_old ‖ π_θ)` over the batch.
    pub kl: Tensor<B, 1>,
    /// `(∂loss/∂η, ∂loss/∂α)` in closed form, when the batch spans several ranks (else
    /// `None`: take them from autodiff).
    pub multiplier_grads: Option<(f64, f64)>,
}

impl<B: Backend> VmpoTerms<B> {
    /// The terms; `logp` is `dist.log_prob(batch.actions)` (`[n]`), `eta` and `alpha` are `[1]`.
    pub fn new(
        dist: &DistParams<B>,
        logp: Tensor<B, 1>,
        batch: &TensorBatch<B>,
        params: &VmpoParams,
        eta: Tensor<B, 1>,
        alpha: Tensor<B, 1>,
    ) -> Self {
        if batch.comm.is_distributed() {
            return Self::across_ranks(dist, logp, batch, params, eta, alpha);
        }
        let device = batch.adv.device();
        let top = top_half(&to_host(batch.adv.clone()));
        let n_top = top.len();
        let idx = Tensor::<B, 1, Int>::from_data(
            TensorData::new(top.iter().map(|&i| i as i64).collect(), [n_top]),
            &device,
        );
        let adv_top = batch.adv.clone().select(0, idx.clone());
        let logp_top = logp.select(0, idx);

        let psi = softmax(adv_top.clone() / eta.clone().detach().expand([n_top]), 0);
        let policy_loss = (psi * logp_top).sum().neg();
        let temperature_loss = eta.clone().mul_scalar(params.eps_eta)
            + eta.clone() * log_mean_exp(adv_top / eta.expand([n_top]));
        let kl = dist.kl_from(&batch.dist_old).mean();
        let trust_region_loss = trust_region_loss(alpha, kl.clone(), params.eps_alpha);
        Self {
            policy_loss,
            temperature_loss,
            trust_region_loss,
            kl,
            multiplier_grads: None,
        }
    }

    /// [`VmpoTerms::new`] over the union of the batches of `batch.comm`'s ranks.
    fn across_ranks(
        dist: &DistParams<B>,
        logp: Tensor<B, 1>,
        batch: &TensorBatch<B>,
        params: &VmpoParams,
        eta: Tensor<B, 1>,
        alpha: Tensor<B, 1>,
    ) -> Self {
        let device = batch.adv.device();
        let comm = &batch.comm;
        let parts = comm.gather(&to_host(batch.adv.clone()));
        let offset: usize = parts[..comm.rank()].iter().map(Vec::len).sum();
        let local = parts.get(comm.rank()).map_or(0, Vec::len);
        let all: Vec<f64> = parts.concat();
        let top = top_half(&all);
        // ψ and log mean exp(adv_top/η) over the global top half, with η a constant
        let eta_value = to_host(eta.clone().detach())[0];
        let scaled: Vec<f64> = top.iter().map(|&i| all[i] / eta_value).collect();
        let max = scaled.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let sum_exp: f64 = scaled.iter().map(|x| (x - max).exp()).sum();
        let log_mean_exp = max + sum_exp.ln() - (top.len().max(1) as f64).ln();
        let log_sum_exp = max + sum_exp.ln();
        let psi_adv: f64 = top
            .iter()
            .zip(&scaled)
            .map(|(&i, x)| (x - log_sum_exp).exp() * all[i])
            .sum();
        let (rows, psi): (Vec<i64>, Vec<f64>) = top
            .iter()
            .zip(&scaled)
            .filter(|(&i, _)| (offset..offset + local).contains(&i))
            .map(|(&i, x)| ((i - offset) as i64, (x - log_sum_exp).exp()))
            .unzip();
        let idx = Tensor::<B, 1, Int>::from_data(TensorData::new(rows, [psi.len()]), &device);
        let psi = Tensor::<B, 1>::from_data(TensorData::new(psi.clone(), [psi.len()]), &device);
        // Σ over the global top = (number of top rows) · mean over them
        let policy_loss = comm
            .mean(psi * logp.select(0, idx))
            .mul_scalar(top.len() as f64)
            .neg();
        let temperature_loss = eta.mul_scalar(params.eps_eta + log_mean_exp);
        let kl = comm.mean(dist.kl_from(&batch.dist_old));
        let kl_value = to_host(kl.clone().detach())[0];
        let trust_region_loss = trust_region_loss(alpha, kl.clone(), params.eps_alpha);
        Self {
            policy_loss,
            temperature_loss,
            trust_region_loss,
            kl,
            multiplier_grads: Some((
                params.eps_eta + log_mean_exp - psi_adv / eta_value,
                params.eps_alpha - kl_value,
            )),
        }
    }

    /// `policy_loss + temperature_loss + trust_region_loss`.
    pub fn loss(&self) -> Tensor<B, 1> {
        self.policy_loss.clone() + self.temperature_loss.clone() + self.trust_region_loss.clone()
    }
}

/// Adam's state of one scalar (Burn's Adam, with the same constants as the networks').
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
struct ScalarAdam {
    moment_1: f64,
    moment_2: f64,
}

impl ScalarAdam {
    /// The change of the parameter for gradient `grad` at step `time` (from 1).
    fn delta(&mut self, grad: f64, lr: f64, time: i32) -> f64 {
        let (b1, b2, eps) = (
            f64::from(ADAM_BETA_1),
            f64::from(ADAM_BETA_2),
            f64::from(ADAM_EPSILON),
        );
        self.moment_1 = b1 * self.moment_1 + (1.0 - b1) * grad;
        self.moment_2 = b2 * self.moment_2 + (1.0 - b2) * grad * grad;
        let correction_2 = (1.0 - b2.powi(time)).sqrt();
        let factor = correction_2 / (1.0 - b1.powi(time));
        -lr * self.moment_1 * factor / (self.moment_2.sqrt() + eps * correction_2)
    }
}

/// V-MPO's learned temperature η and Lagrange multiplier α, with their Adam state: part of a
/// learner's state (and of a checkpoint).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Multipliers {
    /// The temperature η.
    pub eta: f64,
    /// The Lagrange multiplier α.
    pub alpha: f64,
    adam_eta: ScalarAdam,
    adam_alpha: ScalarAdam,
    /// Adam steps taken.
    steps: u64,
}

impl Multipliers {
    /// η and α at their initial values, before any step.
    pub fn new(eta: f64, alpha: f64) -> Self {
        Self {
            eta,
            alpha,
            adam_eta: ScalarAdam::default(),
            adam_alpha: ScalarAdam::default(),
            steps: 0,
        }
    }

    /// `params` with η and α set to the current values.
    pub fn apply(&self, params: VmpoParams) -> VmpoParams {
        VmpoParams {
            eta: self.eta,
            alpha: self.alpha,
            ..params
        }
    }

    /// η and α as `[1]` leaves that require gradients, on `device`.
    pub fn leaves<B: burn::tensor::backend::AutodiffBackend>(
        &self,
        device: &B::Device,
    ) -> (Tensor<B, 1>, Tensor<B, 1>) {
        (
            Tensor::full([1], self.eta, device).require_grad(),
            Tensor::full([1], self.alpha, device).require_grad(),
        )
    }

    /// One Adam step of η and α down the gradients `grad_eta` and `grad_alpha` of the loss,
    /// at learning rate `lr`, then the clamp to `≥` [`MIN_MULTIPLIER`].
    pub fn step(&mut self, grad_eta: f64, grad_alpha: f64, lr: f64) {
        self.steps += 1;
        let time = i32::try_from(self.steps).unwrap_or(i32::MAX);
        self.eta = (self.eta + self.adam_eta.delta(grad_eta, lr, time)).max(MIN_MULTIPLIER);
        self.alpha = (self.alpha + self.adam_alpha.delta(grad_alpha, lr, time)).max(MIN_MULTIPLIER);
    }
}
