//! The objectives (APO, PAPO, TRPO, PPO, A2C): every term, the whole objective and its
//! gradient, against float64 references written in the tests (`common/`), on NdArray<f64>
//! (tight tolerances) and on wgpu (float32 tolerances). The NdArray<f32> runs are in
//! `ndarray_f32.rs`.

use crate::common;

use apo_core::objective::{ApoParams, HMax, Objective};
use apo_core::policy::{MlpPolicyConfig, Policy, PolicyFamily};
use burn::backend::Wgpu;
use common::backend::*;
use common::*;

// ----- each term, each objective, at θ_j: NdArray<f64> and wgpu --------------------------

#[test]
fn terms_by_hand_ndarray_f64() {
    check_terms::<F64>(&ndarray_f64(), 1e-12);
}

#[test]
fn terms_by_hand_wgpu() {
    check_terms::<Wgpu>(&wgpu(), 1e-4);
}

#[test]
fn evaluate_every_objective_ndarray_f64() {
    check_evaluate::<F64>(&ndarray_f64(), 1e-12);
}

#[test]
fn evaluate_every_objective_wgpu() {
    check_evaluate::<Wgpu>(&wgpu(), 1e-4);
}

#[test]
fn terms_at_theta_j_take_the_algebra_values_ndarray_f64() {
    check_at_theta_j::<F64>(&ndarray_f64(), 1e-12);
}

#[test]
fn terms_at_theta_j_take_the_algebra_values_wgpu() {
    check_at_theta_j::<Wgpu>(&wgpu(), 1e-4);
}

// ----- gradients vs float64 finite differences ----------------------------------------

#[test]
fn gradients_match_finite_differences_ndarray_f64() {
    let errors = check_gradients::<F64>(&ndarray_f64(), 1e-7);
    print_errors("gradient relative error, NdArray<f64>", &errors);
}

#[test]
fn gradients_match_finite_differences_wgpu() {
    let errors = check_gradients::<Wgpu>(&wgpu(), 1e-4);
    print_errors("gradient relative error, wgpu (f32) vs f64 FD", &errors);
}

// ----- APO with k = 0 is TRPO, PAPO with k = 0 is PPO (values and gradients) ----------

fn value_and_grad(
    cfg: &MlpPolicyConfig,
    obj: &Objective,
    theta: &[f64],
    batch: &RefBatch,
) -> (f64, Vec<f64>) {
    library_gradient::<F64>(cfg, obj, theta, batch, &ndarray_f64())
}

#[test]
fn apo_with_k_zero_equals_trpo_and_papo_equals_ppo() {
    let apo0 = ApoParams {
        k: 0.0,
        omega1: 0.3,
        h_max: HMax::Fixed(0.7),
        gamma: 0.99,
        units: Default::default(),
        switch: Default::default(),
    };
    let pairs = [
        (Objective::Apo(apo0), Objective::Trpo),
        (
            Objective::Apo(ApoParams {
                h_max: HMax::Estimated,
                ..apo0
            }),
            Objective::Trpo,
        ),
        (
            Objective::Papo {
                params: apo0,
                clip: 0.2,
            },
            Objective::Ppo { clip: 0.2 },
        ),
    ];
    for (pname, cfg) in policy_cases() {
        let (theta_old, theta, batch) = gradient_point(&cfg, 0.0, 5);
        for (at_name, at) in [("θ_j", &theta_old), ("θ ≠ θ_j", &theta)] {
            for (a, b) in &pairs {
                let what = format!("{pname} at {at_name}: {a:?} vs {b:?}");
                let (fa, ga) = value_and_grad(&cfg, a, at, &batch);
                let (fb, gb) = value_and_grad(&cfg, b, at, &batch);
                assert_close(&format!("{what}: value"), fa, fb, 1e-14, 1.0);
                assert!(norm(&gb) > 1e-3, "{what}: zero gradient");
                assert_vec_rel(&format!("{what}: gradient"), &ga, &gb, 1e-13);
                // and both against the independent reference (value) at θ_j: mean(adv)
                if at_name == "θ_j" && matches!(b, Objective::Trpo) {
                    assert_close(
                        &format!("{what}: mean(adv)"),
                        fb,
                        mean(&batch.adv),
                        1e-12,
                        1.0,
                    );
                }
            }
        }
    }
}

/// As k → 0⁺ the penalty's gradient `k (∇mv + ∇vm)` vanishes (the `1/k` inside `vm` only
/// scales a θ-independent constant), so APO's gradient tends to TRPO's: a check that
/// does not go through the `k = 0` shortcut.
#[test]
fn apo_gradient_tends_to_trpo_as_k_goes_to_zero() {
    for (pname, cfg) in policy_cases() {
        let (_, theta, batch) = gradient_point(&cfg, 5.0, 5);
        let (_, g_trpo) = value_and_grad(&cfg, &Objective::Trpo, &theta, &batch);
        let mut previous = f64::INFINITY;
        for k in [1e-1, 1e-3, 1e-5, 1e-7] {
            let obj = Objective::Apo(ApoParams {
                k,
                omega1: 0.3,
                h_max: HMax::Fixed(0.7),
                gamma: 0.5,
                units: Default::default(),
                switch: Default::default(),
            });
            let (_, g) = value_and_grad(&cfg, &obj, &theta, &batch);
            // the distance is k·‖∇mv + ∇vm‖ / ‖∇mean_surr‖: linear in k
            let err = rel_err(&g, &g_trpo);
            assert!(
                err < previous / 50.0,
                "{pname}: k = {k}: distance to TRPO's gradient {err:.3e} did not shrink ~100×"
            );
            previous = err;
        }
        assert!(
            previous < 1e-5,
            "{pname}: k = 1e-7 still {previous:.3e} away from TRPO's gradient"
        );
    }
}

/// At θ_j on a real MLP policy: ratio 1, so `mean_surr = mean(adv)`, the APO terms take
/// their ratio-1 values (computed here with the ratio set to 1 by hand), and the gradient
/// of TRPO's surrogate is `mean(adv · ∇logp)` (float64 finite differences of the
/// reference log-probabilities).
#[test]
fn at_theta_j_on_an_mlp_policy() {
    let device = ndarray_f64();
    for (pname, cfg) in policy_cases() {
        for value_mean in [5.0, -5.0] {
            let (theta_old, _, batch) = gradient_point(&cfg, value_mean, 8);
            let params = ApoParams {
                k: 2.0,
                omega1: 0.3,
                h_max: HMax::Fixed(0.7),
                gamma: 0.5,
                units: Default::default(),
                switch: Default::default(),
            };
            let policy = common_policy(&cfg, &theta_old, &device);
            let tb = batch.to_tensors::<F64>(&device);
            let terms = Objective::Apo(params).evaluate(&policy.distribution(tb.obs.clone()), &tb);
            let n = batch.len() as f64;
            let ms = mean(&batch.adv);
            let mv = 0.3
                * batch
                    .delta
                    .iter()
                    .map(|d| (2.0 * d * 0.7).abs())
                    .sum::<f64>()
                / n;
            let mean_v = mean(&batch.value);
            let min_j_sq = if ms + mean_v >= 0.0 {
                ms * ms + 2.0 * mean_v * ms
            } else {
                0.0
            };
            assert_eq!(
                ms + mean_v >= 0.0,
                value_mean > 0.0,
                "switch side of the test data"
            );
            let spread = batch
                .adv
                .iter()
                .zip(&batch.value)
                .map(|(a, v)| a * a + 2.0 * a.abs() * v)
                .sum::<f64>()
                / n;
            let vm = 0.3 * (1.0 - 0.25) / 2.0 * spread - min_j_sq;
            let what = format!("{pname}, mean V {value_mean}");
            assert_close(
                &format!("{what}: mean_surr"),
                scalar(terms.mean_surr),
                ms,
                1e-12,
                1.0,
            );
            assert_close(
                &format!("{what}: mv"),
                scalar(terms.mean_variance.unwrap()),
                mv,
                1e-12,
                1.0,
            );
            assert_close(
                &format!("{what}: vm"),
                scalar(terms.variance_mean.unwrap()),
                vm,
                1e-12,
                1.0,
            );
            assert_close(
                &format!("{what}: objective"),
                scalar(terms.objective),
                ms - 2.0 * (mv + vm),
                1e-12,
                1.0,
            );

            // ∇ mean(ratio · adv) at θ_j = mean(adv · ∇logp)
            let (_, g) =
                library_gradient::<F64>(&cfg, &Objective::Trpo, &theta_old, &batch, &device);
            let g_ref = fd_gradient(
                |th| {
                    let logp = ref_policy(&cfg, th, &batch.obs).log_prob(&batch.actions);
                    mean(
                        &logp
                            .iter()
                            .zip(&batch.adv)
                            .map(|(l, a)| l * a)
                            .collect::<Vec<_>>(),
                    )
                },
                &theta_old,
                1e-6,
            );
            assert_vec_rel(&format!("{what}: TRPO gradient at θ_j"), &g, &g_ref, 1e-7);
        }
    }
}

fn common_policy(
    cfg: &MlpPolicyConfig,
    theta: &[f64],
    device: &burn::backend::ndarray::NdArrayDevice,
) -> <MlpPolicyConfig as PolicyFamily>::Policy<F64> {
    apo_core::flat::unflatten(cfg.init::<F64>(device), t1::<F64>(theta, device))
}
