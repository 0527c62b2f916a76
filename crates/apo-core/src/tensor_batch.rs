//! A [`Batch`] moved onto a Burn device.

use burn::tensor::backend::{AutodiffBackend, Backend};
use burn::tensor::{Tensor, TensorData};

use crate::buffer::Batch;
use crate::collective::Comm;
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
    /// The standard deviation σ_A the raw advantages were divided by ([`Batch::adv_scale`]).
    pub adv_scale: f64,
    /// The ranks whose batches, together, are the update's batch (this one is rank
    /// `comm.rank()`'s part); means over the batch are taken with [`Comm::mean`].
    pub comm: Comm,
}

fn t1<B: Backend>(v: &[f32], device: &B::Device) -> Tensor<B, 1> {
    Tensor::from_data(TensorData::new(v.to_vec(), [v.len()]), device)
}

fn t2<B: Backend>(v: &[f32], rows: usize, device: &B::Device) -> Tensor<B, 2> {
    let cols = v.len().checked_div(rows).unwrap_or(0);
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
            adv_scale: batch.adv_scale,
            comm: Comm::default(),
        }
    }

    /// The batch as rank `comm.rank()`'s part of the union of the ranks' batches.
    pub fn with_comm(mut self, comm: Comm) -> Self {
        self.comm = comm;
        self
    }

    /// Number of transitions.
    pub fn len(&self) -> usize {
        self.adv.dims()[0]
    }

    /// Whether the batch is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The rows `indices` of every field (a minibatch; with several ranks, this rank's part of
    /// it).
    pub fn select(&self, indices: &[usize]) -> Self {
        let device = self.adv.device();
        let idx = Tensor::<B, 1, burn::tensor::Int>::from_data(
            TensorData::new(
                indices.iter().map(|&i| i as i64).collect::<Vec<_>>(),
                [indices.len()],
            ),
            &device,
        );
        self.map(&Select(idx))
    }

    /// The same data as constants of the autodiff backend `AB` over `B` (no copy).
    pub fn lift<AB: AutodiffBackend<InnerBackend = B>>(&self) -> TensorBatch<AB> {
        self.map(&Lift)
    }

    /// Applies `f` to every field.
    fn map<B2: Backend>(&self, f: &impl FieldMap<B, B2>) -> TensorBatch<B2> {
        let dist_old = match &self.dist_old {
            DistParams::Gaussian { mean, log_std } => DistParams::Gaussian {
                mean: f.two(mean),
                log_std: f.two(log_std),
            },
            DistParams::Categorical { logits } => DistParams::Categorical {
                logits: f.two(logits),
            },
        };
        TensorBatch {
            obs: f.two(&self.obs),
            actions: f.two(&self.actions),
            logp_old: f.one(&self.logp_old),
            dist_old,
            value: f.one(&self.value),
            delta: f.one(&self.delta),
            adv: f.one(&self.adv),
            ret: f.one(&self.ret),
            adv_scale: self.adv_scale,
            comm: self.comm.clone(),
        }
    }
}

/// A transformation of every field of a batch (`[n]` and `[n, width]` tensors alike).
trait FieldMap<B: Backend, B2: Backend> {
    fn one(&self, t: &Tensor<B, 1>) -> Tensor<B2, 1>;
    fn two(&self, t: &Tensor<B, 2>) -> Tensor<B2, 2>;
}

/// Rows by index.
struct Select<B: Backend>(Tensor<B, 1, burn::tensor::Int>);

impl<B: Backend> FieldMap<B, B> for Select<B> {
    fn one(&self, t: &Tensor<B, 1>) -> Tensor<B, 1> {
        t.clone().select(0, self.0.clone())
    }
    fn two(&self, t: &Tensor<B, 2>) -> Tensor<B, 2> {
        t.clone().select(0, self.0.clone())
    }
}

/// Into an autodiff backend, as constants.
struct Lift;

impl<AB: AutodiffBackend> FieldMap<AB::InnerBackend, AB> for Lift {
    fn one(&self, t: &Tensor<AB::InnerBackend, 1>) -> Tensor<AB, 1> {
        Tensor::from_inner(t.clone())
    }
    fn two(&self, t: &Tensor<AB::InnerBackend, 2>) -> Tensor<AB, 2> {
        Tensor::from_inner(t.clone())
    }
}
