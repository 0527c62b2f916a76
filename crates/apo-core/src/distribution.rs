//! Action distributions as Burn graphs: log-probabilities, entropy and the analytic KL divergence.
//!
//! Two families: the diagonal Gaussian (continuous actions) and the categorical
//! (discrete actions). Actions are always passed as a `[batch, width]` float tensor:
//! the action vector for a Gaussian, a one-hot row for a categorical.

use burn::tensor::activation::{log_softmax, softmax};
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

/// `0.5 * ln(2π)`.
const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;

/// The parameters of a batch of action distributions.
#[derive(Debug, Clone)]
pub enum DistParams<B: Backend> {
    /// Diagonal Gaussian `N(mean, exp(log_std)²)`.
    Gaussian {
        /// Means, `[batch, action_dim]`.
        mean: Tensor<B, 2>,
        /// Log standard deviations, `[batch, action_dim]` (a state-independent log-std is
        /// expanded to the batch).
        log_std: Tensor<B, 2>,
    },
    /// Categorical over `n` actions.
    Categorical {
        /// Unnormalized log-probabilities, `[batch, n]`.
        logits: Tensor<B, 2>,
    },
}

impl<B: Backend> DistParams<B> {
    /// The number of distributions in the batch.
    pub fn batch_size(&self) -> usize {
        match self {
            DistParams::Gaussian { mean, .. } => mean.dims()[0],
            DistParams::Categorical { logits } => logits.dims()[0],
        }
    }

    /// Log-probability (density) of `actions` (`[batch, action_dim]`, or one-hot
    /// `[batch, n]` for a categorical) → `[batch]`.
    pub fn log_prob(&self, actions: Tensor<B, 2>) -> Tensor<B, 1> {
        match self {
            DistParams::Gaussian { mean, log_std } => {
                let dim = mean.dims()[1] as f64;
                let z = (actions - mean.clone()) * log_std.clone().neg().exp();
                (z.square().mul_scalar(-0.5) - log_std.clone())
                    .sum_dim(1)
                    .sub_scalar(HALF_LN_2PI * dim)
                    .squeeze_dim(1)
            }
            DistParams::Categorical { logits } => (log_softmax(logits.clone(), 1) * actions)
                .sum_dim(1)
                .squeeze_dim(1),
        }
    }

    /// Entropy of each distribution → `[batch]`.
    pub fn entropy(&self) -> Tensor<B, 1> {
        match self {
            DistParams::Gaussian { log_std, .. } => {
                let dim = log_std.dims()[1] as f64;
                log_std
                    .clone()
                    .sum_dim(1)
                    .add_scalar((0.5 + HALF_LN_2PI) * dim)
                    .squeeze_dim(1)
            }
            DistParams::Categorical { logits } => {
                let logp = log_softmax(logits.clone(), 1);
                (logp.clone().exp() * logp).sum_dim(1).neg().squeeze_dim(1)
            }
        }
    }

    /// `KL(old ‖ self)` per state → `[batch]`, analytic.
    ///
    /// Gaussian: `Σ_i [ln σ_i − ln σ_old,i + (σ_old,i² + (μ_old,i − μ_i)²) / (2σ_i²) − ½]`.
    /// Categorical: `Σ_a p_old(a) (ln p_old(a) − ln p(a))`.
    ///
    /// # Panics
    /// If `old` is of the other family (a programming error, not user input).
    pub fn kl_from(&self, old: &DistParams<B>) -> Tensor<B, 1> {
        match (old, self) {
            (
                DistParams::Gaussian {
                    mean: m0,
                    log_std: s0,
                },
                DistParams::Gaussian {
                    mean: m1,
                    log_std: s1,
                },
            ) => {
                let var_ratio = (s0.clone() - s1.clone()).mul_scalar(2.0).exp();
                let mean_term =
                    (m0.clone() - m1.clone()).square() * s1.clone().mul_scalar(-2.0).exp();
                ((s1.clone() - s0.clone()) + (var_ratio + mean_term).mul_scalar(0.5))
                    .sub_scalar(0.5)
                    .sum_dim(1)
                    .squeeze_dim(1)
            }
            (DistParams::Categorical { logits: l0 }, DistParams::Categorical { logits: l1 }) => {
                let logp0 = log_softmax(l0.clone(), 1);
                let logp1 = log_softmax(l1.clone(), 1);
                (softmax(l0.clone(), 1) * (logp0 - logp1))
                    .sum_dim(1)
                    .squeeze_dim(1)
            }
            _ => panic!("KL between distributions of different families"),
        }
    }

    /// The α-divergence `D_α(old ‖ self)` per state → `[batch]`, for `α ∈ (0, 1)`, in Amari's
    /// form `D_α(p ‖ q) = (∫ p^α q^(1−α) − 1) / (α(α − 1))` with `p = old`, which tends to
    /// `KL(old ‖ self)` as α → 1.
    ///
    /// Gaussian: the closed form per action dimension, summed over dimensions (as AlphaPPO's
    /// experiments compute it; for more than one dimension this is not the divergence of the
    /// joint distribution, except in the limit α → 1): with `s² = α σ1² + (1 − α) σ0²`,
    /// `∫ p^α q^(1−α) = σ0^(1−α) σ1^α / s · exp(−α(1 − α)(μ0 − μ1)² / (2 s²))`.
    /// Categorical: `Σ_a p_old(a)^α p(a)^(1−α)`, computed in log space.
    ///
    /// # Panics
    /// If `old` is of the other family (a programming error, not user input).
    pub fn alpha_divergence_from(&self, old: &DistParams<B>, alpha: f64) -> Tensor<B, 1> {
        let scale = 1.0 / (alpha * (alpha - 1.0));
        match (old, self) {
            (
                DistParams::Gaussian {
                    mean: m0,
                    log_std: s0,
                },
                DistParams::Gaussian {
                    mean: m1,
                    log_std: s1,
                },
            ) => {
                // ln ∫ p^α q^(1−α) per dimension, [batch, action_dim]
                let s_sq = s1.clone().mul_scalar(2.0).exp().mul_scalar(alpha)
                    + s0.clone().mul_scalar(2.0).exp().mul_scalar(1.0 - alpha);
                let log_overlap = s0.clone().mul_scalar(1.0 - alpha) + s1.clone().mul_scalar(alpha)
                    - s_sq.clone().log().mul_scalar(0.5)
                    - ((m0.clone() - m1.clone()).square() / s_sq)
                        .mul_scalar(0.5 * alpha * (1.0 - alpha));
                (log_overlap.exp().sub_scalar(1.0).mul_scalar(scale))
                    .sum_dim(1)
                    .squeeze_dim(1)
            }
            (DistParams::Categorical { logits: l0 }, DistParams::Categorical { logits: l1 }) => {
                let x = log_softmax(l0.clone(), 1).mul_scalar(alpha)
                    + log_softmax(l1.clone(), 1).mul_scalar(1.0 - alpha);
                // log-sum-exp over actions, shifted by the (constant) row maximum
                let max = x.clone().max_dim(1).detach();
                let dims = x.dims();
                let log_overlap = (x - max.clone().expand(dims)).exp().sum_dim(1).log() + max;
                log_overlap
                    .exp()
                    .sub_scalar(1.0)
                    .mul_scalar(scale)
                    .squeeze_dim(1)
            }
            _ => panic!("α-divergence between distributions of different families"),
        }
    }

    /// The same parameters cut from the autodiff graph.
    pub fn detach(self) -> Self {
        match self {
            DistParams::Gaussian { mean, log_std } => DistParams::Gaussian {
                mean: mean.detach(),
                log_std: log_std.detach(),
            },
            DistParams::Categorical { logits } => DistParams::Categorical {
                logits: logits.detach(),
            },
        }
    }
}
