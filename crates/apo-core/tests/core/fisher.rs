//! The Fisher-vector product by first-order passes (`apo_core::fisher`) and the MLP policy's
//! forward-mode JVP (`Policy::distribution_jvp`), on Gaussian (3 actions) and categorical
//! (5 actions) MLP policies with 4 observations and hidden sizes (5, 4), at θ_j on a
//! 32-state batch collected by θ_j:
//!
//! 1. the JVP against float64 central differences of the plain-Rust reference policy in
//!    direction v (also for hidden sizes () and (6));
//! 2. `F v` against the double-backward Hessian-vector product of the mean KL at θ_j (the
//!    path it replaces, `hvp.rs` checks it against finite differences), for several v;
//! 3. `F v` against an explicit `Jᵀ M J / N` with the Jacobian J from float64 central
//!    differences of the reference policy (no library code), itself checked against the
//!    mixed finite-difference Hessian of the reference KL; and the log-std block `2 I`
//!    (hand-derived);
//! 4. the trust-region step with the policy's JVP and with finite differences (the same
//!    policy without a JVP) give the same step, and the step really uses the policy's JVP;
//! 5. a policy without a JVP gets the finite-difference product (against the explicit
//!    Fisher, in f64 and f32), and its step is the one of the HVP of the KL.
//!
//! Tolerances: 1e-9 relative (1e-8 against finite differences) on NdArray<f64>, 1e-4 on wgpu
//! (float32), as in `hvp.rs`.
//!
//! The cases and the backend-generic bodies of checks 1 and 3 are in `common/fisher.rs`;
//! `tests/ndarray_f32.rs` runs them on NdArray<f32> too.

use crate::common;

use apo_core::distribution::DistParams;
use apo_core::fisher::{fisher_vector_product, FisherOperator};
use apo_core::hvp::{hessian_vector_product, Autodiff2};
use apo_core::objective::{ApoParams, HMax, Objective};
use apo_core::policy::{ActionKind, MlpPolicy, MlpPolicyConfig, Policy, PolicyFamily};
use apo_core::trust_region::{
    conjugate_gradient, dot as tr_dot, trust_region_step, TrustRegionConfig,
};
use apo_core::Kernels;
use burn::backend::{Autodiff, Wgpu};
use burn::module::Module;
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;
use common::backend::{print_errors, HvpCase, HvpFn};
use common::fisher::{
    cases, check_fisher_vs_explicit, check_jvp, library_fisher, matvec, reference_fisher, Case,
    Jvp, NoJvpFamily,
};
use common::*;

// ---------------------------------------------------------------------------------------
// The HVP reference
// ---------------------------------------------------------------------------------------

/// The library's double-backward HVP of the mean KL at θ_j on NdArray<f64>.
fn library_kl_hvp(c: &Case, v: &[f64]) -> Vec<f64> {
    let case = HvpCase {
        name: c.name.clone(),
        cfg: c.cfg.clone(),
        theta: c.theta.clone(),
        batch: c.batch.clone(),
        v: v.to_vec(),
        f: HvpFn::Kl,
    };
    case.library_hvp::<F64>(&ndarray_f64())
}

// ---------------------------------------------------------------------------------------
// 1. The JVP of the distribution parameters
// ---------------------------------------------------------------------------------------

#[test]
fn jvp_matches_finite_differences_ndarray_f64() {
    let errors = check_jvp::<F64>(&ndarray_f64(), 1e-8);
    print_errors("J v relative error, NdArray<f64> vs f64 FD", &errors);
}

#[test]
fn jvp_matches_finite_differences_wgpu() {
    let errors = check_jvp::<Wgpu>(&wgpu(), 1e-4);
    print_errors("J v relative error, wgpu (f32) vs f64 FD", &errors);
}

// ---------------------------------------------------------------------------------------
// 2. F v = the double-backward HVP of the mean KL at θ_j
// ---------------------------------------------------------------------------------------

fn check_fisher_vs_hvp<B: Backend>(device: &B::Device, tol: f64) {
    for c in cases() {
        let fvs = library_fisher::<B, _>(&c.cfg, &c, &c.vs, device, Kernels::Backend)
            .expect("the MLP policy has a JVP");
        for (i, (v, fv)) in c.vs.iter().zip(&fvs).enumerate() {
            let hv = library_kl_hvp(&c, v);
            assert!(norm(&hv) > 1e-3, "{}: degenerate HVP", c.name);
            let err = assert_vec_rel(&format!("{}, v{i}: F v vs HVP", c.name), fv, &hv, tol);
            eprintln!("  {err:9.2e}  {}, v{i}", c.name);
        }
    }
}

#[test]
fn fisher_product_equals_kl_hvp_ndarray_f64() {
    check_fisher_vs_hvp::<F64>(&ndarray_f64(), 1e-9);
    // the one-shot function is the operator's product
    let device = ndarray_f64();
    for c in cases() {
        let tb = c.batch.to_tensors::<F64>(&device);
        let once = fisher_vector_product(&c.cfg, &c.theta, tb.obs, &tb.dist_old, &c.vs[1]);
        assert_eq!(
            once,
            library_fisher::<F64, _>(&c.cfg, &c, &c.vs[1..2], &device, Kernels::Backend)
                .map(|mut f| f.remove(0)),
            "{}",
            c.name
        );
    }
}

#[test]
fn fisher_product_equals_kl_hvp_wgpu() {
    check_fisher_vs_hvp::<Wgpu>(&wgpu(), 1e-4);
}

// ---------------------------------------------------------------------------------------
// 3. F v against an explicit Jᵀ M J / N from a float64 finite-difference Jacobian
// ---------------------------------------------------------------------------------------

/// The explicit `Jᵀ M J / N` is the Hessian of the reference mean KL at θ_j (mixed central
/// differences of the KL's value): the formulas for M are right, independently of the library.
#[test]
fn explicit_fisher_is_the_kl_hessian() {
    for c in cases() {
        let f = reference_fisher(&c);
        for (i, v) in c.vs.iter().enumerate() {
            let hv = fd_hvp_of_value(
                |th| ref_mean_kl(&c.cfg, th, &c.batch),
                &c.theta,
                v,
                2e-4,
                2e-4,
            );
            let err = assert_vec_rel(
                &format!("{}, v{i}: Jᵀ M J v / N vs FD Hessian of the KL", c.name),
                &matvec(&f, v),
                &hv,
                1e-6,
            );
            eprintln!("  {err:9.2e}  {}, v{i}", c.name);
        }
    }
}

#[test]
fn fisher_product_matches_explicit_fisher_ndarray_f64() {
    let errors =
        check_fisher_vs_explicit::<F64>(&ndarray_f64(), Kernels::Backend, Jvp::Analytic, 1e-8);
    print_errors(
        "F v relative error, NdArray<f64> vs explicit Jᵀ M J / N",
        &errors,
    );
}

#[test]
fn fisher_product_matches_explicit_fisher_wgpu() {
    let errors = check_fisher_vs_explicit::<Wgpu>(&wgpu(), Kernels::Backend, Jvp::Analytic, 1e-4);
    print_errors(
        "F v relative error, wgpu (f32) vs explicit Jᵀ M J / N",
        &errors,
    );
}

/// Without a JVP, `J v` by a central finite difference of the distributions: ε_M^{2/3} ≈ 4e-11
/// in f64, the reference's own finite-difference Jacobian (h = 1e-5) limiting at ~1e-9.
#[test]
fn finite_difference_fisher_matches_explicit_fisher_ndarray_f64() {
    let errors = check_fisher_vs_explicit::<F64>(
        &ndarray_f64(),
        Kernels::Backend,
        Jvp::FiniteDifference,
        1e-8,
    );
    print_errors(
        "F v relative error, J v by f64 finite differences, NdArray<f64> vs explicit Jᵀ M J / N",
        &errors,
    );
}

/// The same in f32 on wgpu: ε_M^{2/3} ≈ 2.4e-5.
#[test]
fn finite_difference_fisher_matches_explicit_fisher_wgpu() {
    let errors =
        check_fisher_vs_explicit::<Wgpu>(&wgpu(), Kernels::Backend, Jvp::FiniteDifference, 1e-3);
    print_errors(
        "F v relative error, J v by f32 finite differences, wgpu vs explicit Jᵀ M J / N",
        &errors,
    );
}

/// The log-std of a Gaussian policy enters no mean and has `M = 2` in every state, so
/// `F e = 2 e` for a direction `e` in the log-std parameters (the last `action_dim` ones).
#[test]
fn fisher_of_the_log_std_is_two() {
    let device = ndarray_f64();
    let c = &cases()[0];
    let ActionKind::Continuous { dim } = c.cfg.action else {
        unreachable!()
    };
    let p = c.theta.len();
    let es: Vec<Vec<f64>> = (0..dim)
        .map(|k| {
            (0..p)
                .map(|i| if i == p - dim + k { 1.0 } else { 0.0 })
                .collect()
        })
        .collect();
    for (e, fe) in es
        .iter()
        .zip(library_fisher::<F64, _>(&c.cfg, c, &es, &device, Kernels::Backend).expect("JVP"))
    {
        let two_e: Vec<f64> = e.iter().map(|x| 2.0 * x).collect();
        assert_vec_rel("F e_log_std", &fe, &two_e, 1e-14);
    }
}

// ---------------------------------------------------------------------------------------
// 4–5. The trust-region step, and policies without a JVP
// ---------------------------------------------------------------------------------------

/// The built-in MLP policy with its JVP doubled: the Fisher operator becomes `Jᵀ M (2 J) / N = 2 F`
/// (the `Jᵀ` pass differentiates the distribution itself).
#[derive(Module, Debug)]
struct DoubledJvp<B: Backend> {
    inner: MlpPolicy<B>,
}

impl<B: Backend> Policy<B> for DoubledJvp<B> {
    fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
        self.inner.distribution(obs)
    }

    fn distribution_jvp(&self, obs: Tensor<B, 2>, tangent: &Self) -> Option<DistParams<B>> {
        Some(match self.inner.distribution_jvp(obs, &tangent.inner)? {
            DistParams::Gaussian { mean, log_std } => DistParams::Gaussian {
                mean: mean.mul_scalar(2.0),
                log_std: log_std.mul_scalar(2.0),
            },
            DistParams::Categorical { logits } => DistParams::Categorical {
                logits: logits.mul_scalar(2.0),
            },
        })
    }
}

#[derive(Debug, Clone)]
struct DoubledJvpFamily(MlpPolicyConfig);

impl PolicyFamily for DoubledJvpFamily {
    type Policy<B: Backend> = DoubledJvp<B>;

    fn init<B: Backend>(&self, device: &B::Device) -> DoubledJvp<B> {
        DoubledJvp {
            inner: self.0.init(device),
        }
    }
}

fn objectives() -> [(&'static str, Objective); 2] {
    [
        ("trpo", Objective::Trpo),
        (
            "apo",
            Objective::Apo(ApoParams {
                k: 7.0,
                omega1: 0.05,
                h_max: HMax::Fixed(0.05),
                gamma: 0.9,
                units: Default::default(),
                switch: Default::default(),
            }),
        ),
    ]
}

/// The same step with the policy's JVP (MlpPolicy) and with `J v` by finite differences (the
/// same policy without a JVP): same CG iterations, same accepted try, θ and the full step
/// equal up to the finite difference's error (1e-10 in f64) amplified by the conditioning of
/// the damped Fisher (measured at worst 1.6e-5 on the full step, with damping 1e-3). Two trust regions: the
/// default and a wide, weakly damped one that backtracks.
#[test]
fn trust_region_step_is_the_same_with_the_jvp_and_with_finite_differences() {
    let device = ndarray_f64();
    let configs = [
        TrustRegionConfig::default(),
        TrustRegionConfig {
            max_kl: 0.2,
            cg_damping: 1e-3,
            ..Default::default()
        },
    ];
    let mut tries = Vec::new();
    for c in cases() {
        for (oname, obj) in objectives() {
            for config in &configs {
                let name = format!("{}, {oname}, δ {}", c.name, config.max_kl);
                let mut batch = c.batch.clone();
                batch.adv.iter_mut().for_each(|a| *a += 0.3);
                let tb = batch.to_tensors::<F64>(&device);
                let fisher =
                    trust_region_step(&c.cfg, &obj, &c.theta, &tb, config, Kernels::Backend);
                let fd = trust_region_step(
                    &NoJvpFamily(c.cfg.clone()),
                    &obj,
                    &c.theta,
                    &tb,
                    config,
                    Kernels::Backend,
                );
                assert_eq!(fisher.outcome, fd.outcome, "{name}: outcome");
                assert_eq!(
                    fisher.cg_iterations, fd.cg_iterations,
                    "{name}: CG iterations"
                );
                let err = assert_vec_rel(
                    &format!("{name}: full step"),
                    &fisher.full_step,
                    &fd.full_step,
                    1e-4,
                );
                assert_vec_rel(&format!("{name}: θ"), &fisher.theta, &fd.theta, 1e-4);
                assert_close(
                    &format!("{name}: objective before"),
                    fisher.objective_before,
                    fd.objective_before,
                    1e-14,
                    1.0,
                );
                assert_close(
                    &format!("{name}: objective after"),
                    fisher.objective_after,
                    fd.objective_after,
                    1e-5,
                    1.0,
                );
                assert_close(&format!("{name}: KL"), fisher.kl, fd.kl, 1e-4, 1e-6);
                assert_close(
                    &format!("{name}: CG residual"),
                    fisher.cg_residual_sq,
                    fd.cg_residual_sq,
                    1e-5,
                    1e-12,
                );
                eprintln!("  {err:9.2e}  {name}: {:?}", fisher.outcome);
                tries.push(fisher.outcome);
            }
        }
    }
    assert!(
        tries
            .iter()
            .any(|t| matches!(t, apo_core::LineSearchOutcome::Accepted { r#try } if *r#try > 0)),
        "no case backtracked: {tries:?}"
    );
}

/// The step uses the policy's JVP: doubling it makes the operator 2 F, so (without
/// damping, CG being scale-equivariant, exactly so for a factor 2) x halves and the full
/// step `sqrt(2δ / xᵀFx) x` is divided by √2.
#[test]
fn trust_region_step_uses_the_policys_jvp() {
    let device = ndarray_f64();
    let config = TrustRegionConfig {
        cg_damping: 0.0,
        ..Default::default()
    };
    for c in cases() {
        let tb = c.batch.to_tensors::<F64>(&device);
        let plain = trust_region_step(
            &c.cfg,
            &Objective::Trpo,
            &c.theta,
            &tb,
            &config,
            Kernels::Backend,
        );
        let doubled = trust_region_step(
            &DoubledJvpFamily(c.cfg.clone()),
            &Objective::Trpo,
            &c.theta,
            &tb,
            &config,
            Kernels::Backend,
        );
        let expected: Vec<f64> = plain
            .full_step
            .iter()
            .map(|s| s / std::f64::consts::SQRT_2)
            .collect();
        assert!(norm(&expected) > 1e-3, "{}: no step", c.name);
        assert_eq!(doubled.cg_iterations, plain.cg_iterations, "{}", c.name);
        assert_vec_rel(
            &format!("{}: full step with the JVP doubled", c.name),
            &doubled.full_step,
            &expected,
            1e-12,
        );
    }
}

/// Without a JVP the Fisher product is the finite-difference one (equal to the JVP's to its
/// error), and the step is the one built by hand from the double-backward HVP of the mean KL
/// (the reference the first-order path replaces): CG on `HVP + damping · I`, scaled to the
/// trust region.
#[test]
fn policy_without_jvp_takes_the_step_of_the_kl_hessian() {
    let device = ndarray_f64();
    let config = TrustRegionConfig::default();
    for c in cases() {
        let family = NoJvpFamily(c.cfg.clone());
        let tb = c.batch.to_tensors::<F64>(&device);
        let fd = fisher_vector_product(&family, &c.theta, tb.obs.clone(), &tb.dist_old, &c.vs[0])
            .expect("the finite-difference product");
        let jvp = fisher_vector_product(&c.cfg, &c.theta, tb.obs.clone(), &tb.dist_old, &c.vs[0])
            .expect("the MLP's product");
        assert_vec_rel(&format!("{}: F v by FD vs JVP", c.name), &fd, &jvp, 1e-8);
        // no host form: asking for the host kernels keeps Burn's path
        let op = FisherOperator::new(&family, &c.theta, tb.obs.clone(), &tb.dist_old)
            .with_kernels(Kernels::Host);
        assert_eq!(op.kernels(), Kernels::Backend, "{}", c.name);

        let report = trust_region_step(
            &family,
            &Objective::Trpo,
            &c.theta,
            &tb,
            &config,
            Kernels::Backend,
        );
        // the step by hand, from the library's gradient and HVP
        let tb1 = c.batch.to_tensors::<Autodiff<F64>>(&device);
        let (_, g) = apo_core::hvp::gradient(
            &family.init::<Autodiff<F64>>(&device),
            &c.theta,
            &device,
            |p| {
                Objective::Trpo
                    .evaluate(&p.distribution(tb1.obs.clone()), &tb1)
                    .objective
            },
        );
        let tb2 = c.batch.to_tensors::<Autodiff2<F64>>(&device);
        let template2 = family.init::<Autodiff2<F64>>(&device);
        let avp = |v: &[f64]| -> Vec<f64> {
            let hv = hessian_vector_product::<F64, _>(&template2, &c.theta, v, &device, |p| {
                p.distribution(tb2.obs.clone())
                    .kl_from(&tb2.dist_old)
                    .mean()
            })
            .expect("the built-in MLP is twice differentiable");
            hv.iter()
                .zip(v)
                .map(|(h, vi)| h + config.cg_damping * vi)
                .collect()
        };
        let cg = conjugate_gradient(&avp, &g, config.cg_iters, config.cg_residual_tol);
        let scale = (2.0 * config.max_kl / tr_dot(&cg.x, &avp(&cg.x))).sqrt();
        let step: Vec<f64> = cg.x.iter().map(|x| scale * x).collect();
        let err = assert_vec_rel(
            &format!("{}: full step", c.name),
            &report.full_step,
            &step,
            1e-6,
        );
        eprintln!("  {err:9.2e}  {}: full step, FD products vs HVP", c.name);
        assert_eq!(report.cg_iterations, cg.iterations, "{}", c.name);
        // and θ moved
        assert!(report.theta != c.theta, "{}: {:?}", c.name, report.outcome);
    }
}

/// The trust-region step with its Fisher-vector products on the host kernels (f32) is the
/// step of Burn's graph (f64 here) up to f32 rounding, for both policy families and APO.
/// The products agree to ~1e−7 (`tests/ndarray_f32.rs`); ten CG iterations on the damped
/// Fisher amplify that by its conditioning: 4.2e−4 measured at worst, bound 2e−3.
#[test]
fn trust_region_step_on_host_kernels_matches_burns() {
    let device = ndarray_f64();
    let config = TrustRegionConfig::default();
    let apo = Objective::Apo(ApoParams {
        k: 7.0,
        omega1: 0.05,
        h_max: HMax::Fixed(0.05),
        gamma: 0.9,
        units: Default::default(),
        switch: Default::default(),
    });
    for c in cases() {
        let tb = c.batch.to_tensors::<F64>(&device);
        for obj in [Objective::Trpo, apo] {
            let burn = trust_region_step(&c.cfg, &obj, &c.theta, &tb, &config, Kernels::Backend);
            let host = trust_region_step(&c.cfg, &obj, &c.theta, &tb, &config, Kernels::Host);
            assert_eq!(burn.outcome, host.outcome, "{}", c.name);
            let step = |r: &apo_core::TrustRegionReport| -> Vec<f64> {
                r.theta.iter().zip(&c.theta).map(|(a, b)| a - b).collect()
            };
            assert_vec_rel(
                &format!("{}: host vs Burn step", c.name),
                &step(&host),
                &step(&burn),
                2e-3,
            );
        }
    }
}
