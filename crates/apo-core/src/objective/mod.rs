//! The policy objectives, as Burn graphs to be maximized.
//!
//! * [`apo`] — APO's surrogate lower bound of `B_k = J − k·V` (trust region).
//! * [`papo`] — the same with PPO-style clipping (proximal).
//! * [`vmpo`] — V-MPO's weighted log-likelihood with its temperature and trust-region losses.
//! * TRPO's (and ESPO's) surrogate `mean(ratio · adv)`, PPO's clipped surrogate, A2C's
//!   `mean(logp · adv)` and AlphaPPO's `(1 − β) mean(ratio · adv) − β mean_s D_α(π_old ‖ π_θ)`
//!   are [`Objective::Trpo`], [`Objective::Ppo`], [`Objective::A2c`] and
//!   [`Objective::AlphaPpo`].

pub mod apo;
pub mod papo;
pub mod vmpo;

use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

use crate::distribution::DistParams;
use crate::tensor_batch::TensorBatch;
pub use apo::{ApoParams, HMax, PenaltyUnits, Switch};
pub use vmpo::{Multipliers, VmpoParams};

/// Which objective an update maximizes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Objective {
    /// TRPO's surrogate `mean(ratio · adv)`.
    Trpo,
    /// APO: `mean_surr − k (mv + vm)`.
    Apo(ApoParams),
    /// PPO's clipped surrogate with clip ε.
    Ppo {
        /// Clip ε.
        clip: f64,
    },
    /// PAPO: APO's terms with the ratio clipped to `[1 − clip, 1 + clip]`.
    Papo {
        /// APO's hyperparameters.
        params: ApoParams,
        /// Clip ε.
        clip: f64,
    },
    /// A2C's policy-gradient objective `mean(logp · adv)`.
    A2c,
    /// AlphaPPO: `(1 − β) · mean(ratio · adv) − β · mean_s D_α(π_old(·|s) ‖ π_θ(·|s))`
    /// ([`DistParams::alpha_divergence_from`]).
    AlphaPpo {
        /// α ∈ (0, 1) of the divergence.
        alpha: f64,
        /// The divergence's weight β ∈ [0, 1].
        beta: f64,
    },
    /// V-MPO's `−loss` ([`vmpo`]), with η and α as constants.
    Vmpo(VmpoParams),
}

/// The value of an objective and its named terms, each `[1]`.
#[derive(Debug, Clone)]
pub struct ObjectiveTerms<B: Backend> {
    /// The objective to maximize.
    pub objective: Tensor<B, 1>,
    /// The surrogate `mean_surr` (clipped for PPO/PAPO; `mean(logp · adv)` for A2C; the
    /// weighted log-likelihood `Σ ψ · logp(top)` for V-MPO).
    pub mean_surr: Tensor<B, 1>,
    /// The MeanVariance term (APO/PAPO with `k > 0`).
    pub mean_variance: Option<Tensor<B, 1>>,
    /// The VarianceMean term (APO/PAPO with `k > 0`).
    pub variance_mean: Option<Tensor<B, 1>>,
    /// The bias of the lower bound of `J` in `min_J_sq`'s switch (APO/PAPO with `k > 0`).
    pub bias: Option<Tensor<B, 1>>,
    /// 1 when `min_J_sq`'s switch is on (the paper's: `mean_surr + mean(V) − bias ≥ 0`; see
    /// [`Switch`] for the others), else 0 (APO/PAPO with `k > 0`).
    pub min_j_sq_on: Option<Tensor<B, 1>>,
}

impl Objective {
    /// Evaluates the objective for the policy's distributions `dist` on `batch`.
    pub fn evaluate<B: Backend>(
        &self,
        dist: &DistParams<B>,
        batch: &TensorBatch<B>,
    ) -> ObjectiveTerms<B> {
        let logp = dist.log_prob(batch.actions.clone());
        match *self {
            Objective::A2c => {
                let mean_surr = batch.comm.mean(logp * batch.adv.clone());
                Self::surrogate_only(mean_surr)
            }
            Objective::Trpo => {
                let ratio = apo::ratio(logp, batch.logp_old.clone());
                Self::surrogate_only(apo::mean_surr(&batch.comm, ratio, batch.adv.clone()))
            }
            Objective::Ppo { clip } => {
                let ratio = apo::ratio(logp, batch.logp_old.clone());
                Self::surrogate_only(papo::clipped_mean_surr(
                    &batch.comm,
                    ratio,
                    batch.adv.clone(),
                    clip,
                ))
            }
            Objective::AlphaPpo { alpha, beta } => {
                let ratio = apo::ratio(logp, batch.logp_old.clone());
                let mean_surr = apo::mean_surr(&batch.comm, ratio, batch.adv.clone());
                let divergence = batch
                    .comm
                    .mean(dist.alpha_divergence_from(&batch.dist_old, alpha));
                ObjectiveTerms {
                    objective: mean_surr.clone().mul_scalar(1.0 - beta)
                        - divergence.mul_scalar(beta),
                    ..Self::surrogate_only(mean_surr)
                }
            }
            Objective::Vmpo(params) => {
                let device = batch.adv.device();
                let terms = vmpo::VmpoTerms::new(
                    dist,
                    logp,
                    batch,
                    &params,
                    Tensor::full([1], params.eta, &device),
                    Tensor::full([1], params.alpha, &device),
                );
                ObjectiveTerms {
                    objective: terms.loss().neg(),
                    ..Self::surrogate_only(terms.policy_loss.neg())
                }
            }
            Objective::Apo(params) => Self::absolute(&params, None, logp, dist, batch),
            Objective::Papo { params, clip } => {
                Self::absolute(&params, Some(clip), logp, dist, batch)
            }
        }
    }

    fn surrogate_only<B: Backend>(mean_surr: Tensor<B, 1>) -> ObjectiveTerms<B> {
        ObjectiveTerms {
            objective: mean_surr.clone(),
            mean_surr,
            mean_variance: None,
            variance_mean: None,
            bias: None,
            min_j_sq_on: None,
        }
    }

    /// APO (`clip = None`) or PAPO (`clip = Some(ε)`).
    fn absolute<B: Backend>(
        params: &ApoParams,
        clip: Option<f64>,
        logp: Tensor<B, 1>,
        dist: &DistParams<B>,
        batch: &TensorBatch<B>,
    ) -> ObjectiveTerms<B> {
        let comm = &batch.comm;
        // the penalty's reward-valued inputs, in the units `params.units` asks for (reward
        // units: the batch's own tensors, so the paper's numbers are untouched)
        let (delta, value) = match params.units {
            PenaltyUnits::Reward => (batch.delta.clone(), batch.value.clone()),
            PenaltyUnits::Advantage => {
                let scale = 1.0 / batch.adv_scale;
                (
                    batch.delta.clone().mul_scalar(scale),
                    batch.value.clone().mul_scalar(scale),
                )
            }
        };
        let ratio = apo::ratio(logp.clone(), batch.logp_old.clone());
        let mean_surr = match clip {
            None => apo::mean_surr(comm, ratio.clone(), batch.adv.clone()),
            Some(clip) => papo::clipped_mean_surr(comm, ratio.clone(), batch.adv.clone(), clip),
        };
        if params.k == 0.0 {
            return Self::surrogate_only(mean_surr);
        }
        let h = apo::h_max(comm, params, ratio.clone(), batch.adv.clone(), || {
            comm.mean(dist.kl_from(&batch.dist_old))
        });
        let mv = match clip {
            None => apo::mean_variance(comm, ratio, delta, h, params.omega1),
            Some(clip) => papo::clipped_mean_variance(comm, ratio, delta, h, params.omega1, clip),
        };
        let bias = apo::lower_bound_bias(
            comm,
            logp,
            batch.logp_old.clone(),
            batch.adv.clone(),
            params.gamma,
        );
        let mean_value = comm.mean(value.clone());
        let off = apo::switch_off(
            comm,
            params.switch,
            mean_surr.clone(),
            mean_value.clone(),
            bias.clone(),
            batch.adv.clone(),
        );
        let on = off.clone().bool_not().float();
        let min_j_sq = apo::min_j_sq(mean_surr.clone(), mean_value, off);
        let vm = apo::variance_mean(
            comm,
            batch.adv.clone(),
            value,
            min_j_sq,
            params.omega1,
            params.gamma,
            params.k,
        );
        let objective = mean_surr.clone() - (mv.clone() + vm.clone()).mul_scalar(params.k);
        ObjectiveTerms {
            objective,
            mean_surr,
            mean_variance: Some(mv),
            variance_mean: Some(vm),
            bias: Some(bias.detach()),
            min_j_sq_on: Some(on),
        }
    }
}
