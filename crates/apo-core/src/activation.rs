//! The hidden-layer activation of the built-in networks.
//!
//! `tanh` is computed as `(exp(2x) − 1) / (exp(2x) + 1)` on `x` clamped to [−20, 20], from Burn's `exp`,
//! not with Burn's `tanh`: on the NdArray backend `tanh` maps every element through libm's
//! double-precision `tanh` (≈ 20 ns per element here, against ≈ 1–2 ns for `exp`), and its
//! backward pass computes it again. The clamp changes nothing representable: `1 − tanh(20)` is
//! 8.5e−18, below half an f64 ulp of 1, and its zero gradient outside replaces a derivative of at
//! most 1.7e−17; it also keeps `exp` finite, so no `∞ / ∞` or `∞ · 0` reaches either pass. A true
//! division is used, not `recip`: with burn-ndarray's `simd` feature `recip` is the CPU's
//! approximate reciprocal (relative error up to 6e−5 in f32). Every op used is twice
//! differentiable, so Hessian-vector products through it stay exact.
//! `docs/benchmarks.md` has the measurements.

use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

/// Beyond this `|x|`, `tanh(x)` is ±1 in f64.
const SATURATION: f64 = 20.0;

/// `tanh(x)`, elementwise; twice differentiable on every backend.
pub fn tanh<B: Backend, const D: usize>(x: Tensor<B, D>) -> Tensor<B, D> {
    let e = x.clamp(-SATURATION, SATURATION).mul_scalar(2.0).exp();
    e.clone().sub_scalar(1.0).div(e.add_scalar(1.0))
}

#[cfg(test)]
mod tests {
    use burn::backend::NdArray;
    use burn::tensor::{Tensor, TensorData};

    #[test]
    fn matches_tanh_in_f64_over_the_whole_range() {
        let xs: Vec<f64> = (-4000..=4000)
            .map(|i| i as f64 * 0.01)
            .chain([-1e30, -700.0, 1e-12, 700.0, 1e30])
            .collect();
        let device = Default::default();
        let x =
            Tensor::<NdArray<f64>, 1>::from_data(TensorData::new(xs.clone(), [xs.len()]), &device);
        let y: Vec<f64> = super::tanh(x).into_data().iter::<f64>().collect();
        for (x, y) in xs.iter().zip(&y) {
            assert!(
                (y - x.tanh()).abs() <= 4e-16,
                "tanh({x}) = {y}, libm {}",
                x.tanh()
            );
        }
    }
}
