//! Hessian-vector products (double backward through `Autodiff<Autodiff<B>>`) of the mean
//! KL(π_old ‖ π_θ) — the trust region's Fisher matrix — and of APO's objective, on real
//! MLP policies (obs 4, hidden (8, 8); Gaussian with 3 actions, categorical with 5),
//! against float64 central finite differences.
//!
//! Two float64 references, computed on the host:
//! 1. central differences in direction v of the library's gradient on NdArray<f64>
//!    (`(g(θ + εv) − g(θ − εv)) / 2ε`, ε = 1e-5); the gradient itself is checked against
//!    finite differences of an independent objective in `objectives.rs`;
//! 2. mixed central differences of the plain-Rust reference value (no autodiff at all).
//!
//! The two agree to ~1e-8, which shows that the reference really is float64 (a float32
//! finite difference is good to ~1e-2 only).

use crate::common;

use burn::backend::Wgpu;
use common::backend::*;
use common::*;

#[test]
fn fd_references_agree_and_are_float64() {
    let mut worst: f64 = 0.0;
    for case in hvp_cases() {
        let r1 = case.reference_fd_of_gradient();
        let r2 = case.reference_fd_of_value();
        let err = rel_err(&r1, &r2);
        eprintln!("  {err:9.2e}  {}", case.name);
        assert!(
            err < 1e-6,
            "{}: the two float64 references disagree by {err:.3e}",
            case.name
        );
        worst = worst.max(err);
    }
    eprintln!("worst disagreement of the two float64 HVP references: {worst:.2e}");
}

#[test]
fn hvp_matches_finite_differences_ndarray_f64() {
    let device = ndarray_f64();
    let cases = hvp_cases();
    let refs: Vec<Vec<f64>> = cases.iter().map(|c| c.reference_fd_of_gradient()).collect();
    let errors = check_hvp::<F64>(&device, 1e-6, &cases, &refs);
    print_errors(
        "HVP relative error, NdArray<f64> vs FD of the f64 gradient",
        &errors,
    );
    // and against the autodiff-free reference
    let refs: Vec<Vec<f64>> = cases.iter().map(|c| c.reference_fd_of_value()).collect();
    let errors = check_hvp::<F64>(&device, 1e-6, &cases, &refs);
    print_errors(
        "HVP relative error, NdArray<f64> vs mixed FD of the f64 value",
        &errors,
    );
}

#[test]
fn hvp_matches_finite_differences_wgpu() {
    let device = wgpu();
    let cases = hvp_cases();
    let refs: Vec<Vec<f64>> = cases.iter().map(|c| c.reference_fd_of_gradient()).collect();
    let errors = check_hvp::<Wgpu>(&device, 1e-4, &cases, &refs);
    print_errors(
        "HVP relative error, wgpu (f32) vs f64 FD of the gradient",
        &errors,
    );
}

/// The Fisher matrix at θ_old is symmetric positive semi-definite: `uᵀ(Fv) = vᵀ(Fu)` and
/// `vᵀFv ≥ 0`; and the HVP is linear in v.
#[test]
fn fisher_products_are_symmetric_psd_and_linear() {
    let device = ndarray_f64();
    for case in hvp_cases()
        .into_iter()
        .filter(|c| matches!(c.f, HvpFn::Kl) && c.name.contains("Fisher"))
    {
        let mut rng = Rng::new(7);
        let u = unit_vector(case.theta.len(), &mut rng);
        let fv = case.library_hvp::<F64>(&device);
        let fu = HvpCase {
            v: u.clone(),
            ..case.clone()
        }
        .library_hvp::<F64>(&device);
        assert_close(
            &format!("{}: symmetry", case.name),
            dot(&u, &fv),
            dot(&case.v, &fu),
            1e-10,
            1e-3,
        );
        assert!(
            dot(&case.v, &fv) > 0.0,
            "{}: vᵀFv = {}",
            case.name,
            dot(&case.v, &fv)
        );
        let w: Vec<f64> = case
            .v
            .iter()
            .zip(&u)
            .map(|(a, b)| 2.0 * a - 3.0 * b)
            .collect();
        let fw = HvpCase {
            v: w,
            ..case.clone()
        }
        .library_hvp::<F64>(&device);
        let lin: Vec<f64> = fv.iter().zip(&fu).map(|(a, b)| 2.0 * a - 3.0 * b).collect();
        assert_vec_rel(&format!("{}: linearity", case.name), &fw, &lin, 1e-12);
    }
}

/// A policy of `burn::nn::Linear` layers, whose backward passes Burn does not record.
#[derive(burn::module::Module, Debug)]
struct LinearPolicy<B: burn::tensor::backend::Backend> {
    layer: burn::nn::Linear<B>,
}

/// `burn::nn` layers are not twice differentiable: the double backward is an error that names
/// the module and the first-order way out, not a panic reaching the caller.
#[test]
fn hvp_of_an_nn_linear_module_is_an_error_naming_it() {
    use apo_core::hvp::{hessian_vector_product, Autodiff2};
    use burn::nn::LinearConfig;
    use burn::tensor::Tensor;
    let device = ndarray_f64();
    let template = LinearPolicy::<Autodiff2<F64>> {
        layer: LinearConfig::new(3, 2).init(&device),
    };
    let n = 3 * 2 + 2;
    let theta: Vec<f64> = (0..n).map(|i| 0.1 * i as f64).collect();
    let v = vec![1.0; n];
    let obs = Tensor::<Autodiff2<F64>, 2>::ones([4, 3], &device);
    let err = hessian_vector_product::<F64, _>(&template, &theta, &v, &device, |p| {
        p.layer.forward(obs.clone()).tanh().sum().reshape([1])
    })
    .expect_err("nn::Linear is not twice differentiable");
    eprintln!("{err}");
    assert!(err.policy.contains("LinearPolicy"), "{err}");
    assert!(
        err.problem.contains("not twice differentiable") && err.problem.contains("FisherOperator"),
        "{err}"
    );
}
