//! Module parameters as one flat vector.
//!
//! The trust-region step works in parameter space: conjugate gradient, step scaling and
//! the line search all act on θ as one vector of `num_params` reals. [`flatten`] reads the
//! float parameters of any Burn module in visiting order; [`unflatten`] rebuilds the module
//! with each parameter replaced by its slice of a flat tensor. When that flat tensor is an
//! autodiff leaf, the module becomes a differentiable function of θ, so gradients and
//! Hessian-vector products come out as flat vectors too.

use burn::module::{Module, ModuleMapper, ModuleVisitor, Param};
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

struct Collect<B: Backend> {
    parts: Vec<Tensor<B, 1>>,
}

impl<B: Backend> ModuleVisitor<B> for Collect<B> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<B, D>>) {
        self.parts.push(param.val().reshape([-1]));
    }
}

/// The float parameters of `module`, concatenated in visiting order → `[num_params]`.
pub fn flatten<B: Backend, M: Module<B>>(module: &M) -> Tensor<B, 1> {
    let mut collect = Collect { parts: Vec::new() };
    module.visit(&mut collect);
    Tensor::cat(collect.parts, 0)
}

struct Distribute<B: Backend> {
    theta: Tensor<B, 1>,
    offset: usize,
}

impl<B: Backend> ModuleMapper<B> for Distribute<B> {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<B, D>>) -> Param<Tensor<B, D>> {
        // `lazy_shape` does not run a lazy initializer: replacing the parameters of a
        // freshly built module draws no random numbers from the backend's global RNG.
        let shape = param.lazy_shape();
        let n = shape.num_elements();
        let start = self.offset;
        self.offset += n;
        let dims: [usize; D] = std::array::from_fn(|i| shape[i]);
        Param::initialized(
            param.id,
            self.theta.clone().slice(start..start + n).reshape(dims),
        )
    }
}

/// `module` with its float parameters replaced by consecutive slices of `theta`
/// (`[num_params]`, in the order of [`flatten`]). Parameter ids are kept, so optimizer
/// state keyed by them stays valid. Lazily initialized parameters are replaced without
/// being initialized, so building a module only to unflatten into it is cheap and leaves
/// the backend's RNG untouched.
///
/// # Panics
/// If `theta` does not have exactly as many elements as the module has parameters.
pub fn unflatten<B: Backend, M: Module<B>>(module: M, theta: Tensor<B, 1>) -> M {
    let total = theta.dims()[0];
    let mut distribute = Distribute { theta, offset: 0 };
    let module = module.map(&mut distribute);
    assert_eq!(
        distribute.offset, total,
        "flat parameter vector has the wrong length"
    );
    module
}

/// A flat tensor's values on the host, as `f64`.
pub fn to_host<B: Backend, const D: usize>(tensor: Tensor<B, D>) -> Vec<f64> {
    tensor.into_data().iter::<f64>().collect()
}

/// A `[len]` tensor on `device` from host values.
pub fn from_host<B: Backend>(values: &[f64], device: &B::Device) -> Tensor<B, 1> {
    Tensor::from_data(
        burn::tensor::TensorData::new(values.to_vec(), [values.len()]),
        device,
    )
}
