//! The backend-generic objective, gradient, HVP, JVP and Fisher-vector-product checks on
//! NdArray<f32>.
//!
//! This is a binary of its own on purpose: Burn 0.21 records the default float dtype per
//! device *type*, process-wide, and NdArray<f32> and NdArray<f64> share `NdArrayDevice`.
//! Whichever runs first in a process decides the dtype of both, so mixing them in one
//! test binary would make the float64 references silently run in float32 (or these
//! tests in float64). Here nothing touches NdArray<f64>: every reference is plain Rust
//! f64 (the HVP reference is the mixed finite difference of the reference value; the JVP and
//! Fisher references are central differences of the reference policy, `common/fisher.rs`).

mod common;

use burn::backend::ndarray::NdArrayDevice;
use burn::backend::NdArray;
use burn::tensor::DType;
use common::backend::*;
use common::fisher::{check_fisher_vs_explicit, check_jvp};

type F32 = NdArray<f32>;

fn device() -> NdArrayDevice {
    let device = NdArrayDevice::default();
    common::assert_float_dtype::<F32>(&device, DType::F32, "NdArray<f32>");
    device
}

#[test]
fn terms_by_hand_ndarray_f32() {
    check_terms::<F32>(&device(), 1e-5);
}

#[test]
fn evaluate_every_objective_ndarray_f32() {
    check_evaluate::<F32>(&device(), 1e-5);
}

#[test]
fn terms_at_theta_j_ndarray_f32() {
    check_at_theta_j::<F32>(&device(), 1e-5);
}

#[test]
fn gradients_match_finite_differences_ndarray_f32() {
    let errors = check_gradients::<F32>(&device(), 1e-4);
    print_errors("gradient relative error, NdArray<f32> vs f64 FD", &errors);
}

#[test]
fn hvp_matches_finite_differences_ndarray_f32() {
    let cases = hvp_cases();
    let refs: Vec<Vec<f64>> = cases.iter().map(|c| c.reference_fd_of_value()).collect();
    let errors = check_hvp::<F32>(&device(), 1e-4, &cases, &refs);
    print_errors(
        "HVP relative error, NdArray<f32> vs f64 mixed FD of the value",
        &errors,
    );
}

#[test]
fn jvp_matches_finite_differences_ndarray_f32() {
    let errors = check_jvp::<F32>(&device(), 1e-4);
    print_errors("J v relative error, NdArray<f32> vs f64 FD", &errors);
}

#[test]
fn fisher_product_matches_explicit_fisher_ndarray_f32() {
    let errors = check_fisher_vs_explicit::<F32>(&device(), 1e-4);
    print_errors(
        "F v relative error, NdArray<f32> vs explicit Jᵀ M J / N (f64 FD Jacobian)",
        &errors,
    );
}
