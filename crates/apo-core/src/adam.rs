//! Adam in apo: the constants every optimizer shares (Burn's Adam on the networks, the host
//! updates and V-MPO's multipliers), and Adam on the host for the host kernels' updates
//! ([`HostAdam`]), which reads its state from Burn's optimizer record and writes it back, so that
//! checkpoints do not depend on where an update ran.

use burn::module::{AutodiffModule, ModuleMapper, ModuleVisitor, Param};
use burn::optim::adaptor::OptimizerAdaptor;
use burn::optim::record::AdaptorRecord;
use burn::optim::{Adam, AdamState, AdaptiveMomentumState, Optimizer};
use burn::tensor::backend::{AutodiffBackend, Backend};
use burn::tensor::{Tensor, TensorData};

/// Adam's β₁, β₂ and ε of every optimizer in apo (PyTorch's defaults, as in the paper's
/// implementation).
pub(crate) const ADAM_BETA_1: f32 = 0.9;
/// See [`ADAM_BETA_1`].
pub(crate) const ADAM_BETA_2: f32 = 0.999;
/// See [`ADAM_BETA_1`].
pub(crate) const ADAM_EPSILON: f32 = 1e-8;

/// The record of Burn's Adam on a module `M` of the autodiff backend `AB`.
type Record<AB, M> = <OptimizerAdaptor<Adam, M, AB> as Optimizer<M, AB>>::Record;

/// Adam's state for a module's parameters as one flat vector in visiting order.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct HostAdam {
    /// First moment, `[num_params]`.
    pub(crate) moment_1: Vec<f32>,
    /// Second moment, `[num_params]`.
    pub(crate) moment_2: Vec<f32>,
    /// Steps taken.
    pub(crate) time: usize,
}

impl HostAdam {
    /// The state before any step, for `n` parameters.
    pub(crate) fn new(n: usize) -> Self {
        Self {
            moment_1: vec![0.0; n],
            moment_2: vec![0.0; n],
            time: 0,
        }
    }

    /// The state of Burn's Adam `optim` for `module`'s parameters (zeros for a parameter
    /// without one; the step count is the largest any parameter has).
    pub(crate) fn read<AB: AutodiffBackend, M: AutodiffModule<AB>>(
        module: &M,
        optim: &OptimizerAdaptor<Adam, M, AB>,
    ) -> Self {
        let mut read = ReadMoments::<AB, M> {
            record: optim.to_record(),
            adam: HostAdam::new(0),
        };
        module.visit(&mut read);
        read.adam
    }

    /// Number of parameters.
    pub(crate) fn len(&self) -> usize {
        self.moment_1.len()
    }

    /// One Adam step at learning rate `lr` of `params` (`[num_params]`, as an iterator so that
    /// a flat vector may live in several buffers) down `grads` (`[num_params]`).
    ///
    /// Burn's Adam, operation for operation: `θ −= lr · m·c / (√v + ε·√(1 − β₂ᵗ))` with
    /// `c = √(1 − β₂ᵗ) / (1 − β₁ᵗ)`.
    pub(crate) fn step<'a>(
        &mut self,
        params: impl Iterator<Item = &'a mut f32>,
        grads: &[f32],
        lr: f32,
    ) {
        self.time += 1;
        let t = i32::try_from(self.time).unwrap_or(i32::MAX);
        let correction_2 = (1.0 - ADAM_BETA_2.powi(t)).sqrt();
        let factor = correction_2 / (1.0 - ADAM_BETA_1.powi(t));
        let epsilon = ADAM_EPSILON * correction_2;
        for (((p, g), m), v) in params
            .zip(grads)
            .zip(&mut self.moment_1)
            .zip(&mut self.moment_2)
        {
            *m = *m * ADAM_BETA_1 + g * (1.0 - ADAM_BETA_1);
            *v = *v * ADAM_BETA_2 + g * g * (1.0 - ADAM_BETA_2);
            *p -= (*m * factor / (v.sqrt() + epsilon)) * lr;
        }
    }

    /// `module` with its parameters replaced by `params` (`[num_params]`, visiting order; ids
    /// and autodiff settings kept), and `optim` holding this state.
    pub(crate) fn write<AB: AutodiffBackend, M: AutodiffModule<AB>>(
        &self,
        module: M,
        optim: OptimizerAdaptor<Adam, M, AB>,
        params: &[f32],
    ) -> (M, OptimizerAdaptor<Adam, M, AB>) {
        let mut write = WriteBack::<AB, M> {
            adam: self,
            params,
            offset: 0,
            record: Record::<AB, M>::default(),
        };
        let module = module.map(&mut write);
        let optim = optim.load_record(write.record);
        (module, optim)
    }
}

/// Reads each parameter's Adam moments and step count out of an optimizer record, in
/// visiting order.
struct ReadMoments<AB: AutodiffBackend, M: AutodiffModule<AB>> {
    record: Record<AB, M>,
    adam: HostAdam,
}

impl<AB: AutodiffBackend, M: AutodiffModule<AB>> ModuleVisitor<AB> for ReadMoments<AB, M> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<AB, D>>) {
        let n = param.lazy_shape().num_elements();
        let adam = &mut self.adam;
        match self.record.remove(&param.id) {
            Some(record) => {
                let state: AdamState<AB::InnerBackend, D> = record.into_state::<D>();
                let momentum = state.momentum;
                adam.time = adam.time.max(momentum.time);
                adam.moment_1
                    .extend(momentum.moment_1.into_data().iter::<f32>());
                adam.moment_2
                    .extend(momentum.moment_2.into_data().iter::<f32>());
            }
            None => {
                adam.moment_1.extend(std::iter::repeat_n(0.0, n));
                adam.moment_2.extend(std::iter::repeat_n(0.0, n));
            }
        }
    }
}

/// Writes host parameters back into a module and builds the matching optimizer record.
struct WriteBack<'a, AB: AutodiffBackend, M: AutodiffModule<AB>> {
    adam: &'a HostAdam,
    params: &'a [f32],
    offset: usize,
    record: Record<AB, M>,
}

fn tensor<const D: usize, B: Backend>(
    values: &[f32],
    dims: [usize; D],
    device: &B::Device,
) -> Tensor<B, D> {
    Tensor::from_data(TensorData::new(values.to_vec(), dims), device)
}

impl<AB: AutodiffBackend, M: AutodiffModule<AB>> ModuleMapper<AB> for WriteBack<'_, AB, M> {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<AB, D>>) -> Param<Tensor<AB, D>> {
        let shape = param.lazy_shape();
        let dims: [usize; D] = std::array::from_fn(|i| shape[i]);
        let range = self.offset..self.offset + shape.num_elements();
        self.offset = range.end;
        let device = param.lazy_device();
        let adam = self.adam;
        if adam.time > 0 {
            let momentum = AdaptiveMomentumState::new(
                adam.time,
                tensor::<D, AB::InnerBackend>(&adam.moment_1[range.clone()], dims, &device),
                tensor::<D, AB::InnerBackend>(&adam.moment_2[range.clone()], dims, &device),
            );
            self.record.insert(
                param.id,
                AdaptorRecord::from_state(AdamState::new(momentum)),
            );
        }
        let value = tensor::<D, AB>(&self.params[range], dims, &device);
        let id = param.id;
        param.transform_for_load(value, id)
    }
}
