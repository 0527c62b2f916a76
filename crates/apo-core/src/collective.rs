//! Data-parallel updates: sums across the processes of a job, and the means and gradients of
//! one update over the union of every process's batch.
//!
//! With `N` processes ("ranks") each holding a part of the epoch's batch, an update must be the
//! update of the whole batch, identical on every rank. Every objective here is a function
//! `f(m_1, …, m_q)` of means over the batch (`mean_surr`, `mean_variance`, the mean KL, …),
//! some of them inside nonlinear terms (APO's `min_J_sq` squares `mean_surr`). On rank `r`,
//! with its part's sum `s_r(θ)` of a per-sample quantity and the global count `n`,
//! [`Comm::mean`] returns
//!
//! ```text
//! m̃_r = m + (s_r/n − sg(s_r/n)),     m = Σ_r s_r / n   (summed across ranks)
//! ```
//!
//! whose value is the global mean `m` on every rank and whose gradient is `∇s_r / n`, rank `r`'s
//! share of `∇m`. So `f(m̃_r)` has the global value, and by the chain rule
//! `Σ_r ∇f(m̃_r) = Σ_i ∂f/∂m_i · Σ_r ∇s_r/n = ∇f(m)`: summing the ranks' gradients
//! ([`Comm::sum`]) gives the gradient of the whole batch's objective. Fisher-vector products
//! are means too (`(1/n) Σ_s J_sᵀ M_s J_s v`): each rank weighs its own by `n_r / n` and they
//! are summed. Sums are reduced onto rank 0 and broadcast, so every rank holds bitwise the same
//! result and conjugate gradient and the line search run in lockstep.
//!
//! [`Solo`] is the one-process case: [`Comm::mean`] is the plain mean and sums are the identity.

use std::fmt;
use std::sync::Arc;

use burn::module::{AutodiffModule, ModuleVisitor, Param, ParamId};
use burn::optim::GradientsParams;
use burn::tensor::backend::{AutodiffBackend, Backend};
use burn::tensor::{Tensor, TensorData};

/// Reductions across the ranks of a job. Every rank must make the same calls in the same
/// order (they are collective operations).
pub trait Collective: Send + Sync {
    /// This process's rank, `0..size`.
    fn rank(&self) -> usize;
    /// The number of ranks.
    fn size(&self) -> usize;
    /// Element-wise sum over ranks, in place; every rank ends with bitwise the same values.
    fn sum(&self, values: &mut [f64]);
    /// Element-wise maximum over ranks, in place.
    fn max(&self, values: &mut [f64]);
    /// Every rank's `values` (of any length), in rank order, on every rank.
    fn gather(&self, values: &[f64]) -> Vec<Vec<f64>>;
}

/// The one-process job.
#[derive(Debug, Clone, Copy, Default)]
pub struct Solo;

impl Collective for Solo {
    fn rank(&self) -> usize {
        0
    }
    fn size(&self) -> usize {
        1
    }
    fn sum(&self, _: &mut [f64]) {}
    fn max(&self, _: &mut [f64]) {}
    fn gather(&self, values: &[f64]) -> Vec<Vec<f64>> {
        vec![values.to_vec()]
    }
}

/// A shared handle on a [`Collective`], with the reductions an update needs on tensors.
/// The default is [`Solo`].
#[derive(Clone)]
pub struct Comm(Arc<dyn Collective>);

impl Default for Comm {
    fn default() -> Self {
        Self(Arc::new(Solo))
    }
}

impl fmt::Debug for Comm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Comm(rank {} of {})", self.rank(), self.size())
    }
}

impl Comm {
    /// A handle on `collective`.
    pub fn new(collective: Arc<dyn Collective>) -> Self {
        Self(collective)
    }

    /// This process's rank.
    pub fn rank(&self) -> usize {
        self.0.rank()
    }

    /// The number of ranks.
    pub fn size(&self) -> usize {
        self.0.size()
    }

    /// Whether there is more than one rank.
    pub fn is_distributed(&self) -> bool {
        self.size() > 1
    }

    /// Element-wise sum over ranks, in place (bitwise equal on every rank).
    pub fn sum(&self, values: &mut [f64]) {
        if self.is_distributed() {
            self.0.sum(values);
        }
    }

    /// Element-wise maximum over ranks, in place.
    pub fn max(&self, values: &mut [f64]) {
        if self.is_distributed() {
            self.0.max(values);
        }
    }

    /// Every rank's `values`, in rank order.
    pub fn gather(&self, values: &[f64]) -> Vec<Vec<f64>> {
        self.0.gather(values)
    }

    /// The sum of a count over ranks.
    pub fn total(&self, count: usize) -> usize {
        let mut v = [count as f64];
        self.sum(&mut v);
        v[0] as usize
    }

    /// The mean of `x` (`[n_r]`, this rank's part) over every rank's part → `[1]`, whose
    /// gradient is this rank's share of the global mean's (see the [module](self) docs). With
    /// one rank, `x.mean()`.
    pub fn mean<B: Backend>(&self, x: Tensor<B, 1>) -> Tensor<B, 1> {
        if !self.is_distributed() {
            return x.mean();
        }
        let rows = x.dims()[0] as f64;
        let local = x.sum();
        let mut totals = [first(local.clone()), rows];
        self.0.sum(&mut totals);
        let n = totals[1].max(1.0);
        let share = local.div_scalar(n);
        let global =
            Tensor::<B, 1>::from_data(TensorData::new(vec![totals[0] / n], [1]), &share.device());
        // `share − sg(share)` is exactly 0: the value is the global mean's bits on every rank
        global + (share.clone() - share.detach())
    }

    /// The maximum of the constant `x` (`[n_r]`) over every rank's part → `[1]`, without
    /// gradient. With one rank, `x.max()`.
    pub fn max_const<B: Backend>(&self, x: Tensor<B, 1>) -> Tensor<B, 1> {
        if !self.is_distributed() {
            return x.max();
        }
        let device = x.device();
        let mut m = [if x.dims()[0] == 0 {
            f64::NEG_INFINITY
        } else {
            first(x.detach().max())
        }];
        self.0.max(&mut m);
        Tensor::from_data(TensorData::new(vec![m[0]], [1]), &device)
    }
}

impl Comm {
    /// `grads` of `module`'s parameters summed over ranks (a parameter without a gradient
    /// counts as zeros): the gradient of the whole batch's objective when each rank's came
    /// from [`Comm::mean`]s. With one rank, `grads` unchanged.
    pub fn sum_gradients<AB: AutodiffBackend, M: AutodiffModule<AB>>(
        &self,
        module: &M,
        mut grads: GradientsParams,
    ) -> GradientsParams {
        if !self.is_distributed() {
            return grads;
        }
        let mut read = ReadGrads {
            grads: &grads,
            flat: Vec::new(),
        };
        module.visit(&mut read);
        let mut flat = read.flat;
        self.sum(&mut flat);
        let mut write = WriteGrads {
            grads: &mut grads,
            flat: &flat,
            offset: 0,
        };
        module.visit(&mut write);
        grads
    }
}

/// Reads a module's gradients in visiting order, zeros for parameters without one.
struct ReadGrads<'a> {
    grads: &'a GradientsParams,
    flat: Vec<f64>,
}

impl<AB: AutodiffBackend> ModuleVisitor<AB> for ReadGrads<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<AB, D>>) {
        match self.grads.get::<AB::InnerBackend, D>(param.id) {
            Some(g) => self.flat.extend(g.into_data().iter::<f64>()),
            None => {
                let n = param.shape().num_elements();
                self.flat.extend(std::iter::repeat_n(0.0, n));
            }
        }
    }
}

/// Registers consecutive slices of `flat` as a module's gradients, in visiting order.
struct WriteGrads<'a> {
    grads: &'a mut GradientsParams,
    flat: &'a [f64],
    offset: usize,
}

impl<AB: AutodiffBackend> ModuleVisitor<AB> for WriteGrads<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<AB, D>>) {
        let shape = param.shape();
        let n = shape.num_elements();
        let values = self.flat[self.offset..self.offset + n].to_vec();
        self.offset += n;
        let device = param.val().inner().device();
        let id: ParamId = param.id;
        self.grads.register::<AB::InnerBackend, D>(
            id,
            Tensor::from_data(TensorData::new(values, shape), &device),
        );
    }
}

/// The value of a `[1]` tensor.
fn first<B: Backend>(x: Tensor<B, 1>) -> f64 {
    x.into_data().iter::<f64>().next().unwrap_or(0.0)
}
