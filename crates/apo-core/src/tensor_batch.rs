//! A [`Batch`] moved onto a Burn device.

use burn::tensor::backend::{AutodiffBackend, Backend};
use burn::tensor::{Tensor, TensorData};

use crate::buffer::Batch;
use crate::distribution::DistParams;
use crate::policy::ActionKind;

/// The epoch's data as tensors, constant during an update.
#[derive(Debug, Clone)]
pub struct TensorBatch<B: Backend> {
    /// Observations, `[n, observation_dim]`.
    pub obs: Tensor<B, 2>,
    /// Actions, `[n, action_width]`.
    pub actions: Tensor<B, 2>,
    /// `log π_j(a|s)`, `[n]`.
    pub logp_old: Tensor<B, 1>,
    /// π_j's distributions.
    pub dist_old: DistParams<B>,
    /// Critic values at collection, `[n]`.
    pub value: Tensor<B, 1>,
    /// One-step advantages, `[n]`.
    pub delta: Tensor<B, 1>,
    /// Normalized GAE advantages, `[n]`.
    pub adv: Tensor<B, 1>,
    /// Rewards-to-go, `[n]`.
    pub ret: Tensor<B, 1>,
}

fn t1<B: Backend>(v: &[f32], device: &B::Device) -> Tensor<B, 1> {
    Tensor::from_data(TensorData::new(v.to_vec(), [v.len()]), device)
}

fn t2<B: Backend>(v: &[f32], rows: usize, device: &B::Device) -> Tensor<B, 2> {
    let cols = if rows == 0 { 0 } else { v.len() / rows };
    Tensor::from_data(TensorData::new(v.to_vec(), [rows, cols]), device)
}

impl<B: Backend> TensorBatch<B> {
    /// Moves `batch` to `device`; `action` says how to read the stored distribution parameters.
    pub fn new(batch: &Batch, action: ActionKind, device: &B::Device) -> Self {
        let n = batch.len;
        let dist = t2::<B>(&batch.dist, n, device);
        let dist_old = match action {
            ActionKind::Continuous { dim } => DistParams::Gaussian {
                mean: dist.clone().slice([0..n, 0..dim]),
                log_std: dist.slice([0..n, dim..2 * dim]),
            },
            ActionKind::Discrete { .. } => DistParams::Categorical { logits: dist },
        };
        Self {
            obs: t2(&batch.obs, n, device),
            actions: t2(&batch.actions, n, device),
            logp_old: t1(&batch.logp, device),
            dist_old,
            value: t1(&batch.value, device),
            delta: t1(&batch.delta, device),
            adv: t1(&batch.adv, device),
            ret: t1(&batch.ret, device),
        }
    }

    /// Number of transitions.
    pub fn len(&self) -> usize {
        self.adv.dims()[0]
    }

    /// Whether the batch is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The rows `indices` of every field (a minibatch).
    pub fn select(&self, indices: &[usize]) -> Self {
        let device = self.adv.device();
        let idx = Tensor::<B, 1, burn::tensor::Int>::from_data(
            TensorData::new(indices.iter().map(|&i| i as i64).collect::<Vec<_>>(), [indices.len()]),
            &device,
        );
        let s2 = |t: &Tensor<B, 2>| t.clone().select(0, idx.clone());
        let s1 = |t: &Tensor<B, 1>| t.clone().select(0, idx.clone());
        let dist_old = match &self.dist_old {
            DistParams::Gaussian { mean, log_std } => DistParams::Gaussian { mean: s2(mean), log_std: s2(log_std) },
            DistParams::Categorical { logits } => DistParams::Categorical { logits: s2(logits) },
        };
        Self {
            obs: s2(&self.obs),
            actions: s2(&self.actions),
            logp_old: s1(&self.logp_old),
            dist_old,
            value: s1(&self.value),
            delta: s1(&self.delta),
            adv: s1(&self.adv),
            ret: s1(&self.ret),
        }
    }

    /// The same data as constants of the autodiff backend `AB` over `B` (no copy).
    pub fn lift<AB: AutodiffBackend<InnerBackend = B>>(&self) -> TensorBatch<AB> {
        fn up<AB: AutodiffBackend, const D: usize>(t: &Tensor<AB::InnerBackend, D>) -> Tensor<AB, D> {
            Tensor::from_inner(t.clone())
        }
        let dist_old = match &self.dist_old {
            DistParams::Gaussian { mean, log_std } => {
                DistParams::Gaussian { mean: up::<AB, 2>(mean), log_std: up::<AB, 2>(log_std) }
            }
            DistParams::Categorical { logits } => DistParams::Categorical { logits: up::<AB, 2>(logits) },
        };
        TensorBatch {
            obs: up::<AB, 2>(&self.obs),
            actions: up::<AB, 2>(&self.actions),
            logp_old: up::<AB, 1>(&self.logp_old),
            dist_old,
            value: up::<AB, 1>(&self.value),
            delta: up::<AB, 1>(&self.delta),
            adv: up::<AB, 1>(&self.adv),
            ret: up::<AB, 1>(&self.ret),
        }
    }

    /// The same data on another backend (through the host).
    pub fn to_backend<B2: Backend>(&self, device: &B2::Device) -> TensorBatch<B2> {
        fn mv<B: Backend, B2: Backend, const D: usize>(t: &Tensor<B, D>, device: &B2::Device) -> Tensor<B2, D> {
            Tensor::from_data(t.to_data(), device)
        }
        let dist_old = match &self.dist_old {
            DistParams::Gaussian { mean, log_std } => {
                DistParams::Gaussian { mean: mv(mean, device), log_std: mv(log_std, device) }
            }
            DistParams::Categorical { logits } => DistParams::Categorical { logits: mv(logits, device) },
        };
        TensorBatch {
            obs: mv(&self.obs, device),
            actions: mv(&self.actions, device),
            logp_old: mv(&self.logp_old, device),
            dist_old,
            value: mv(&self.value, device),
            delta: mv(&self.delta, device),
            adv: mv(&self.adv, device),
            ret: mv(&self.ret, device),
        }
    }
}
