//! Gradients and Hessian-vector products of scalar functions of a module's flat parameters.
//!
//! Both take a *template* module (any instance of the architecture; its values are
//! overwritten) and the point θ as host `f64` values, and return host vectors, which is
//! what the conjugate-gradient solver works on.

use burn::backend::Autodiff;
use burn::module::Module;
use burn::tensor::backend::{AutodiffBackend, Backend};
use burn::tensor::Tensor;

use crate::flat::{from_host, to_host, unflatten};
use crate::policy::PolicyError;

/// The twice-differentiable backend over `B`: `Autodiff<Autodiff<B>>`.
pub type Autodiff2<B> = Autodiff<Autodiff<B>>;

/// `(f(θ), ∇_θ f(θ))` at `theta` (`[num_params]`), with `f` given the module whose
/// parameters are slices of θ. `f` returns a `[1]` tensor.
pub fn gradient<AB, M>(
    template: &M,
    theta: &[f64],
    device: &AB::Device,
    f: impl FnOnce(&M) -> Tensor<AB, 1>,
) -> (f64, Vec<f64>)
where
    AB: AutodiffBackend,
    M: Module<AB>,
{
    let leaf = from_host::<AB>(theta, device).require_grad();
    let module = unflatten(template.clone(), leaf.clone());
    let value = f(&module);
    let grads = value.backward();
    let g = leaf
        .grad(&grads)
        .map(to_host)
        .unwrap_or_else(|| vec![0.0; theta.len()]);
    (to_host(value)[0], g)
}

/// `∇²_θ f(θ) · v` at `theta`, by double backward through [`Autodiff2`]: the gradient
/// `g(θ)` is computed by the outer autodiff with the inner one recording, then
/// `∇_θ (g(θ) · v)` by the inner one.
///
/// The training code does not use it (the trust-region step needs first derivatives only,
/// [`crate::fisher`]); it is the reference its Fisher-vector products are tested against.
///
/// # Errors
/// [`PolicyError`] naming `M` when `f` is not twice differentiable: Burn's `nn` layers
/// (`Linear`, convolutions, norms, embeddings) do not record their backward passes, so their
/// second derivatives cannot be taken (Burn reports it by a panic, caught here; its message
/// is printed by the panic hook).
pub fn hessian_vector_product<B, M>(
    template: &M,
    theta: &[f64],
    v: &[f64],
    device: &B::Device,
    f: impl FnOnce(&M) -> Tensor<Autodiff2<B>, 1>,
) -> Result<Vec<f64>, PolicyError>
where
    B: Backend,
    M: Module<Autodiff2<B>>,
{
    let product = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        double_backward::<B, M>(template, theta, v, device, f)
    }));
    product.map_err(|panic| {
        let message = panic
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| panic.downcast_ref::<&str>().copied())
            .unwrap_or("a panic inside Burn");
        PolicyError::of::<M>(format!(
            "is not twice differentiable ({message}); the trust-region step does not need it \
             (apo_core::fisher::FisherOperator takes first derivatives only), or implement \
             Policy::distribution_jvp"
        ))
    })
}

fn double_backward<B, M>(
    template: &M,
    theta: &[f64],
    v: &[f64],
    device: &B::Device,
    f: impl FnOnce(&M) -> Tensor<Autodiff2<B>, 1>,
) -> Vec<f64>
where
    B: Backend,
    M: Module<Autodiff2<B>>,
{
    let inner = from_host::<Autodiff<B>>(theta, device).require_grad();
    let outer = Tensor::<Autodiff2<B>, 1>::from_inner(inner.clone()).require_grad();
    let module = unflatten(template.clone(), outer.clone());
    let grads = f(&module).backward();
    let Some(g) = outer.grad(&grads) else {
        return vec![0.0; theta.len()];
    };
    let gv = (g * from_host::<Autodiff<B>>(v, device)).sum();
    let grads = gv.backward();
    inner
        .grad(&grads)
        .map(to_host)
        .unwrap_or_else(|| vec![0.0; theta.len()])
}
