//! Backend-generic check bodies: written once, run on NdArray<f64> (tight tolerances),
//! wgpu (float32) and NdArray<f32> (its own binary). Every reference is computed in plain
//! `f64` on the host (see `common/mod.rs`), never by the backend under test.

use apo_core::collective::Comm;
use apo_core::hvp::{gradient, hessian_vector_product, Autodiff2};
use apo_core::objective::{
    apo, papo, ApoParams, HMax, Objective, PenaltyUnits, Switch, VmpoParams,
};
use apo_core::policy::{MlpPolicyConfig, Policy, PolicyFamily};
use burn::backend::Autodiff;
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

use super::*;

// ---------------------------------------------------------------------------------------
// 1. Each term of the objectives on a 5-sample batch, against loops written here
// ---------------------------------------------------------------------------------------

/// The 5-sample data of [`check_terms`]. With clip 0.1, samples 0–3 have their ratio
/// clipped and sample 4 does not.
pub struct Five {
    pub logp: [f64; 5],
    pub logp_old: [f64; 5],
    pub adv: [f64; 5],
    pub delta: [f64; 5],
    pub value: [f64; 5],
}

pub const FIVE: Five = Five {
    logp: [-0.80, -0.35, -2.10, -0.80, -1.55],
    logp_old: [-1.00, -0.50, -1.90, -0.95, -1.50],
    adv: [0.7, -1.3, 0.4, 2.1, -0.6],
    delta: [0.5, -0.9, 1.7, -0.2, 0.8],
    value: [1.5, 2.0, -0.5, 0.8, 1.2],
};

/// Every named term function of `objective::apo` and `objective::papo` against plain loops.
pub fn check_terms<B: Backend>(device: &B::Device, tol: f64) {
    let d = &FIVE;
    let (omega1, omega2, gamma, k, clip) = (0.3, 0.7, 0.9, 2.0, 0.1);
    let t = |v: &[f64; 5]| t1::<B>(v, device);
    let n = 5.0;

    // ratio
    let ratio_ref: Vec<f64> = (0..5).map(|i| (d.logp[i] - d.logp_old[i]).exp()).collect();
    let ratio = apo::ratio(t(&d.logp), t(&d.logp_old));
    for (i, (a, e)) in host(ratio.clone()).iter().zip(&ratio_ref).enumerate() {
        assert_rel(&format!("ratio[{i}]"), *a, *e, tol);
    }

    // mean_surr
    let ms_ref = (0..5).map(|i| ratio_ref[i] * d.adv[i]).sum::<f64>() / n;
    assert_rel(
        "mean_surr",
        scalar(apo::mean_surr(&Comm::default(), ratio.clone(), t(&d.adv))),
        ms_ref,
        tol,
    );

    // variance_increment and mean_variance, with a constant h = ω2
    let h = [omega2; 5];
    let inc_ref: Vec<f64> = (0..5)
        .map(|i| {
            (ratio_ref[i] - 1.0) * d.delta[i] * d.delta[i]
                + 2.0 * ratio_ref[i] * d.delta[i] * omega2
        })
        .collect();
    let inc = host(apo::variance_increment(ratio.clone(), t(&d.delta), t(&h)));
    for i in 0..5 {
        assert_rel(&format!("variance_increment[{i}]"), inc[i], inc_ref[i], tol);
    }
    let mv_ref = omega1 * inc_ref.iter().map(|x| x.abs()).sum::<f64>() / n;
    assert_rel(
        "mean_variance",
        scalar(apo::mean_variance(
            &Comm::default(),
            ratio.clone(),
            t(&d.delta),
            t(&h),
            omega1,
        )),
        mv_ref,
        tol,
    );
    // the |·| matters on this data
    assert!(inc_ref.iter().any(|x| *x < 0.0) && inc_ref.iter().any(|x| *x > 0.0));

    // h_max in the fixed mode is ω2 everywhere
    let params = ApoParams {
        k,
        omega1,
        h_max: HMax::Fixed(omega2),
        gamma,
        units: Default::default(),
        switch: Default::default(),
    };
    let hm = host(apo::h_max(
        &Comm::default(),
        &params,
        ratio.clone(),
        t(&d.adv),
        || panic!("fixed mode must not evaluate the KL"),
    ));
    for v in hm {
        assert_rel("h_max (fixed)", v, omega2, tol);
    }

    // lower_bound_bias = 4γ |mean(logp_old − logp)| max(adv) / (1 − γ)²
    let mean_dlogp = (0..5).map(|i| d.logp_old[i] - d.logp[i]).sum::<f64>() / n;
    let max_adv = d.adv.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let bias_ref = 4.0 * gamma * mean_dlogp.abs() * max_adv / ((1.0 - gamma) * (1.0 - gamma));
    assert!(
        mean_dlogp < 0.0,
        "the data should make the |·| of the bias matter"
    );
    assert_rel(
        "lower_bound_bias",
        scalar(apo::lower_bound_bias(
            &Comm::default(),
            t(&d.logp),
            t(&d.logp_old),
            t(&d.adv),
            gamma,
        )),
        bias_ref,
        tol,
    );

    // min_j_sq on both sides of its switch, and exactly on the boundary (margin 0 is "on")
    let one = |x: f64| t1::<B>(&[x], device);
    let cases = [
        // (mean_surr, mean(V), bias, expected)
        (0.4, 1.1, 0.3, 0.4 * 0.4 + 2.0 * 1.1 * 0.4), // margin 1.2 ≥ 0: on
        (0.4, 1.1, 1.6, 0.0),                         // margin −0.1 < 0: off
        (0.5, 0.25, 0.75, 0.5 * 0.5 + 2.0 * 0.25 * 0.5), // margin exactly 0: on
        (-0.3, 2.0, 0.1, 0.09 - 1.2),                 // on, negative value
        (-0.3, -2.0, 0.0, 0.0),                       // off
    ];
    for (ms, mv, bias, expected) in cases {
        let off = apo::min_j_sq_off(one(ms), one(mv), one(bias));
        let got = scalar(apo::min_j_sq(one(ms), one(mv), off));
        assert_close(
            &format!("min_j_sq(ms {ms}, mean V {mv}, bias {bias})"),
            got,
            expected,
            tol,
            1.0,
        );
    }

    // variance_mean = ω1 (1 − γ²) / k · mean(|adv|² + 2 |adv| V) − min_J_sq
    let spread = (0..5)
        .map(|i| d.adv[i].abs().powi(2) + 2.0 * d.adv[i].abs() * d.value[i])
        .sum::<f64>()
        / n;
    for mjs in [0.0, 0.37] {
        let vm_ref = omega1 * (1.0 - gamma * gamma) / k * spread - mjs;
        let vm = scalar(apo::variance_mean(
            &Comm::default(),
            t(&d.adv),
            t(&d.value),
            one(mjs),
            omega1,
            gamma,
            k,
        ));
        assert_rel(&format!("variance_mean(min_j_sq {mjs})"), vm, vm_ref, tol);
    }

    // estimated_h_max = 2γ(1+γ)/(1−γ)² · max|adv| · KL + |ratio · adv|
    let kl = 0.0123;
    let max_abs_adv = d.adv.iter().map(|a| a.abs()).fold(0.0, f64::max);
    let est = host(apo::estimated_h_max(
        &Comm::default(),
        ratio.clone(),
        t(&d.adv),
        one(kl),
        gamma,
    ));
    for i in 0..5 {
        let e = 2.0 * gamma * (1.0 + gamma) / (1.0 - gamma).powi(2) * max_abs_adv * kl
            + (ratio_ref[i] * d.adv[i]).abs();
        assert_rel(&format!("estimated_h_max[{i}]"), est[i], e, tol);
    }
    let params_est = ApoParams {
        h_max: HMax::Estimated,
        ..params
    };
    let hm = host(apo::h_max(
        &Comm::default(),
        &params_est,
        ratio.clone(),
        t(&d.adv),
        || one(kl),
    ));
    for i in 0..5 {
        assert_rel(&format!("h_max (estimated)[{i}]"), hm[i], est[i], tol);
    }

    // clipping
    let clamp = |r: f64| r.max(1.0 - clip).min(1.0 + clip);
    let clipped = host(papo::clip_ratio(ratio.clone(), clip));
    for i in 0..5 {
        assert_rel(
            &format!("clip_ratio[{i}]"),
            clipped[i],
            clamp(ratio_ref[i]),
            tol,
        );
    }
    assert_eq!(
        (0..5)
            .filter(|&i| clamp(ratio_ref[i]) != ratio_ref[i])
            .count(),
        4,
        "4 of 5 ratios are clipped"
    );
    let cms_ref = (0..5)
        .map(|i| (ratio_ref[i] * d.adv[i]).min(clamp(ratio_ref[i]) * d.adv[i]))
        .sum::<f64>()
        / n;
    assert_rel(
        "clipped_mean_surr",
        scalar(papo::clipped_mean_surr(
            &Comm::default(),
            ratio.clone(),
            t(&d.adv),
            clip,
        )),
        cms_ref,
        tol,
    );
    assert!(
        (cms_ref - ms_ref).abs() > 1e-3,
        "clipping must change the surrogate on this data"
    );
    let tf = |r: f64, i: usize| (r - 1.0) * d.delta[i] * d.delta[i] + 2.0 * r * d.delta[i] * omega2;
    let cmv_ref = omega1
        * (0..5)
            .map(|i| tf(ratio_ref[i], i).min(tf(clamp(ratio_ref[i]), i)))
            .sum::<f64>()
        / n;
    let cmv = scalar(papo::clipped_mean_variance(
        &Comm::default(),
        ratio,
        t(&d.delta),
        t(&h),
        omega1,
        clip,
    ));
    assert_rel("clipped_mean_variance", cmv, cmv_ref, tol);
}

// ---------------------------------------------------------------------------------------
// 2. Objective::evaluate, every algorithm, against the reference objective
// ---------------------------------------------------------------------------------------

/// Objectives exercised by the evaluation and gradient checks, with the critic-value
/// offset of their batch and the side of the `min_J_sq` switch they must hit
/// (`None`: the objective has no switch).
pub fn objective_cases() -> Vec<(&'static str, Objective, f64, Option<bool>)> {
    let paper = ApoParams {
        k: 7.0,
        omega1: 0.005,
        h_max: HMax::Fixed(0.005),
        gamma: 0.99,
        units: Default::default(),
        switch: Default::default(),
    };
    let big = ApoParams {
        k: 2.0,
        omega1: 0.3,
        h_max: HMax::Fixed(0.7),
        gamma: 0.5,
        units: Default::default(),
        switch: Default::default(),
    };
    let est = ApoParams {
        k: 3.0,
        omega1: 0.01,
        h_max: HMax::Estimated,
        gamma: 0.9,
        units: Default::default(),
        switch: Default::default(),
    };
    vec![
        ("trpo", Objective::Trpo, 0.0, None),
        ("a2c", Objective::A2c, 0.0, None),
        ("ppo", Objective::Ppo { clip: 0.2 }, 0.0, None),
        (
            "alphappo",
            Objective::AlphaPpo {
                alpha: 0.5,
                beta: 0.5,
            },
            0.0,
            None,
        ),
        (
            "alphappo α 0.2, β 0.8",
            Objective::AlphaPpo {
                alpha: 0.2,
                beta: 0.8,
            },
            0.0,
            None,
        ),
        (
            "vmpo",
            Objective::Vmpo(VmpoParams {
                eps_eta: 0.008,
                eps_alpha: 0.05,
                eta: 1.0,
                alpha: 5.0,
            }),
            0.0,
            None,
        ),
        (
            "vmpo small η",
            Objective::Vmpo(VmpoParams {
                eps_eta: 0.1,
                eps_alpha: 0.01,
                eta: 0.3,
                alpha: 0.7,
            }),
            0.0,
            None,
        ),
        (
            "apo paper params (switch off)",
            Objective::Apo(paper),
            0.0,
            Some(false),
        ),
        (
            "apo large terms, γ 0.5 (switch on)",
            Objective::Apo(big),
            5.0,
            Some(true),
        ),
        (
            "apo large terms, γ 0.5 (switch off)",
            Objective::Apo(big),
            -5.0,
            Some(false),
        ),
        ("apo estimated |H|", Objective::Apo(est), 0.0, Some(false)),
        (
            "papo (switch on)",
            Objective::Papo {
                params: big,
                clip: 0.2,
            },
            5.0,
            Some(true),
        ),
        (
            "papo paper params",
            Objective::Papo {
                params: paper,
                clip: 0.2,
            },
            0.0,
            Some(false),
        ),
        (
            "papo estimated |H|",
            Objective::Papo {
                params: est,
                clip: 0.2,
            },
            0.0,
            Some(false),
        ),
        // the variants (docs/algorithms.md, "Variants that keep the step"); the batch's
        // adv_scale is 2.5 (gradient_point), so the scale-free penalty differs from the paper's
        (
            "apo scale-free, γ 0.5",
            Objective::Apo(ApoParams {
                units: PenaltyUnits::Advantage,
                ..big
            }),
            5.0,
            None,
        ),
        (
            "apo switch held (on)",
            Objective::Apo(ApoParams {
                switch: Switch::Held,
                ..big
            }),
            5.0,
            None,
        ),
        (
            "apo switch held (off)",
            Objective::Apo(ApoParams {
                switch: Switch::Held,
                ..big
            }),
            -5.0,
            None,
        ),
        (
            "apo switch off",
            Objective::Apo(ApoParams {
                switch: Switch::Off,
                ..big
            }),
            5.0,
            None,
        ),
        (
            "apo scale-free, switch off",
            Objective::Apo(ApoParams {
                units: PenaltyUnits::Advantage,
                switch: Switch::Off,
                ..big
            }),
            -5.0,
            None,
        ),
        (
            "papo scale-free, switch off",
            Objective::Papo {
                params: ApoParams {
                    units: PenaltyUnits::Advantage,
                    switch: Switch::Off,
                    ..big
                },
                clip: 0.2,
            },
            5.0,
            None,
        ),
    ]
}

/// The two policy shapes of the gradient and HVP checks.
pub fn policy_cases() -> Vec<(&'static str, MlpPolicyConfig)> {
    vec![
        ("gaussian", gaussian_cfg(4, &[8, 8], 3)),
        ("categorical", categorical_cfg(4, &[8, 8], 5)),
    ]
}

/// A batch collected by `θ_old` and a point `θ = θ_old + noise` where the objective is
/// evaluated (ratios spread around 1, some clipped at ε = 0.2).
pub fn gradient_point(
    cfg: &MlpPolicyConfig,
    value_mean: f64,
    seed: u64,
) -> (Vec<f64>, Vec<f64>, RefBatch) {
    let mut rng = Rng::new(seed);
    let theta_old = random_theta(cfg, &mut rng);
    let mut batch = sample_batch(cfg, &theta_old, 24, value_mean, &mut rng);
    // σ_A of the raw advantages: only the scale-free penalty reads it
    batch.adv_scale = 2.5;
    let theta: Vec<f64> = theta_old.iter().map(|t| t + 0.06 * rng.normal()).collect();
    (theta_old, theta, batch)
}

/// `Objective::evaluate` on given distributions (not a policy), each algorithm and each
/// term, against the reference.
pub fn check_evaluate<B: Backend>(device: &B::Device, tol: f64) {
    for (pname, cfg) in policy_cases() {
        for (oname, obj, value_mean, side) in objective_cases() {
            let (_, theta, batch) = gradient_point(&cfg, value_mean, 11);
            let dist = ref_policy(&cfg, &theta, &batch.obs);
            let r = ref_terms_dist(&obj, &dist, &batch);
            if let Some(on) = side {
                let m = r.switch_margin.expect("APO terms");
                assert_eq!(
                    m >= 0.0,
                    on,
                    "{pname}/{oname}: test data is on the wrong side of the switch (margin {m})"
                );
            }
            let tb = batch.to_tensors::<B>(device);
            let terms = obj.evaluate(&dist.to_params::<B>(device), &tb);
            let what = format!("{pname}/{oname}");
            let scale = r.mean_surr.abs()
                + r.mean_variance.unwrap_or(0.0).abs()
                + r.variance_mean.unwrap_or(0.0).abs()
                + r.min_j_sq.unwrap_or(0.0).abs();
            assert_close(
                &format!("{what}: objective"),
                scalar(terms.objective),
                r.objective,
                tol,
                scale,
            );
            assert_close(
                &format!("{what}: mean_surr"),
                scalar(terms.mean_surr),
                r.mean_surr,
                tol,
                scale,
            );
            assert_eq!(
                terms.mean_variance.is_some(),
                r.mean_variance.is_some(),
                "{what}: mv presence"
            );
            assert_eq!(
                terms.variance_mean.is_some(),
                r.variance_mean.is_some(),
                "{what}: vm presence"
            );
            if let (Some(a), Some(e)) = (terms.mean_variance, r.mean_variance) {
                assert_close(&format!("{what}: mean_variance"), scalar(a), e, tol, scale);
            }
            if let (Some(a), Some(e)) = (terms.variance_mean, r.variance_mean) {
                assert_close(&format!("{what}: variance_mean"), scalar(a), e, tol, scale);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// 3. Gradients w.r.t. the flat policy parameters vs float64 finite differences
// ---------------------------------------------------------------------------------------

/// `(f(θ), ∇f(θ))` of an objective of the built-in MLP policy on backend `B` (through the
/// library's `hvp::gradient` on `Autodiff<B>`).
pub fn library_gradient<B: Backend>(
    cfg: &MlpPolicyConfig,
    obj: &Objective,
    theta: &[f64],
    batch: &RefBatch,
    device: &B::Device,
) -> (f64, Vec<f64>) {
    let tb = batch.to_tensors::<Autodiff<B>>(device);
    let template = cfg.init::<Autodiff<B>>(device);
    gradient::<Autodiff<B>, _>(&template, theta, device, |p| {
        obj.evaluate(&p.distribution(tb.obs.clone()), &tb).objective
    })
}

/// The float64 finite-difference gradient of the reference objective, after checking
/// that no kink of the objective is within reach of the step.
pub fn reference_gradient(
    cfg: &MlpPolicyConfig,
    obj: &Objective,
    theta: &[f64],
    batch: &RefBatch,
    what: &str,
) -> (f64, Vec<f64>) {
    let r = ref_objective(cfg, obj, theta, batch);
    assert!(
        r.kink_margin > 1e-4,
        "{what}: data within {:.1e} of a kink; choose another seed",
        r.kink_margin
    );
    if let Some(m) = r.switch_margin {
        assert!(
            m.abs() > 1e-3,
            "{what}: data on the min_J_sq switch (margin {m:.1e})"
        );
    }
    if let Objective::Ppo { clip } | Objective::Papo { clip, .. } = *obj {
        let logp = ref_policy(cfg, theta, &batch.obs).log_prob(&batch.actions);
        let clipped = (0..batch.len())
            .filter(|&i| ((logp[i] - batch.logp_old[i]).exp() - 1.0).abs() > clip)
            .count();
        assert!(
            clipped > 0 && clipped < batch.len(),
            "{what}: {clipped} of {} ratios clipped; want some",
            batch.len()
        );
    }
    let g = fd_gradient(
        |th| ref_objective(cfg, obj, th, batch).differentiated,
        theta,
        1e-6,
    );
    (r.objective, g)
}

/// Every objective's gradient, for both policy families, against float64 central
/// differences of the reference objective. Returns `(case, relative error)`.
pub fn check_gradients<B: Backend>(device: &B::Device, tol: f64) -> Vec<(String, f64)> {
    let mut errors = Vec::new();
    for (pname, cfg) in policy_cases() {
        for (oname, obj, value_mean, _) in objective_cases() {
            let what = format!("{pname}/{oname}");
            let (_, theta, batch) = gradient_point(&cfg, value_mean, 11);
            let (f_ref, g_ref) = reference_gradient(&cfg, &obj, &theta, &batch, &what);
            let (f, g) = library_gradient::<B>(&cfg, &obj, &theta, &batch, device);
            assert_close(&format!("{what}: value"), f, f_ref, tol, 1e-2);
            assert!(
                norm(&g_ref) > 1e-3,
                "{what}: degenerate (zero) reference gradient"
            );
            let err = assert_vec_rel(&format!("{what}: gradient"), &g, &g_ref, tol);
            errors.push((what, err));
        }
    }
    errors
}

// ---------------------------------------------------------------------------------------
// 4. Hessian-vector products
// ---------------------------------------------------------------------------------------

/// The scalar function whose Hessian is applied.
#[derive(Debug, Clone)]
pub enum HvpFn {
    /// Mean `KL(π_old ‖ π_θ)` (the Fisher matrix at θ = θ_old).
    Kl,
    Objective(Objective),
}

#[derive(Debug, Clone)]
pub struct HvpCase {
    pub name: String,
    pub cfg: MlpPolicyConfig,
    pub theta: Vec<f64>,
    pub batch: RefBatch,
    pub v: Vec<f64>,
    pub f: HvpFn,
}

impl HvpCase {
    /// The function in plain f64 (reference).
    pub fn reference_value(&self, theta: &[f64]) -> f64 {
        match &self.f {
            HvpFn::Kl => ref_mean_kl(&self.cfg, theta, &self.batch),
            HvpFn::Objective(obj) => ref_objective(&self.cfg, obj, theta, &self.batch).objective,
        }
    }

    fn graph<B: Backend>(
        &self,
        p: &<MlpPolicyConfig as PolicyFamily>::Policy<B>,
        tb: &apo_core::TensorBatch<B>,
    ) -> Tensor<B, 1> {
        let dist = p.distribution(tb.obs.clone());
        match &self.f {
            HvpFn::Kl => dist.kl_from(&tb.dist_old).mean(),
            HvpFn::Objective(obj) => obj.evaluate(&dist, tb).objective,
        }
    }

    /// The library's gradient of the function on `Autodiff<B>`.
    pub fn library_gradient<B: Backend>(&self, theta: &[f64], device: &B::Device) -> Vec<f64> {
        let tb = self.batch.to_tensors::<Autodiff<B>>(device);
        let template = self.cfg.init::<Autodiff<B>>(device);
        gradient::<Autodiff<B>, _>(&template, theta, device, |p| self.graph(p, &tb)).1
    }

    /// The library's Hessian-vector product on `Autodiff<Autodiff<B>>`.
    pub fn library_hvp<B: Backend>(&self, device: &B::Device) -> Vec<f64> {
        let tb = self.batch.to_tensors::<Autodiff2<B>>(device);
        let template = self.cfg.init::<Autodiff2<B>>(device);
        hessian_vector_product::<B, _>(&template, &self.theta, &self.v, device, |p| {
            self.graph(p, &tb)
        })
        .expect("the built-in MLP is twice differentiable")
    }

    /// Reference 1: central differences, in direction `v`, of the library's gradient on
    /// NdArray<f64> (whose float64-ness `ndarray_f64()` checks). Only for binaries that
    /// never touch NdArray<f32>.
    pub fn reference_fd_of_gradient(&self) -> Vec<f64> {
        let device = ndarray_f64();
        fd_directional(
            |th| self.library_gradient::<F64>(th, &device),
            &self.theta,
            &self.v,
            1e-5,
        )
    }

    /// Reference 2: mixed central differences of the plain-f64 reference value (no
    /// autodiff at all).
    pub fn reference_fd_of_value(&self) -> Vec<f64> {
        fd_hvp_of_value(
            |th| self.reference_value(th),
            &self.theta,
            &self.v,
            2e-4,
            2e-4,
        )
    }
}

/// The HVP cases: for a Gaussian MLP (obs 4, hidden (8, 8), action 3) and a categorical
/// MLP (obs 4, hidden (8, 8), 5 actions): the mean KL at θ = θ_old (the Fisher matrix of
/// the trust region), the mean KL at θ ≠ θ_old, and APO's objective at θ ≠ θ_old.
pub fn hvp_cases() -> Vec<HvpCase> {
    let apo = Objective::Apo(ApoParams {
        k: 2.0,
        omega1: 0.3,
        h_max: HMax::Fixed(0.7),
        gamma: 0.5,
        units: Default::default(),
        switch: Default::default(),
    });
    let mut cases = Vec::new();
    for (i, (pname, cfg)) in policy_cases().into_iter().enumerate() {
        let (theta_old, theta, batch) = gradient_point(&cfg, 5.0, 21 + i as u64);
        let v = unit_vector(theta.len(), &mut Rng::new(99 + i as u64));
        for (fname, at, f) in [
            ("KL at θ_old (Fisher)", &theta_old, HvpFn::Kl),
            ("KL at θ ≠ θ_old", &theta, HvpFn::Kl),
            ("APO objective at θ ≠ θ_old", &theta, HvpFn::Objective(apo)),
        ] {
            cases.push(HvpCase {
                name: format!("{pname}: {fname}"),
                cfg: cfg.clone(),
                theta: at.clone(),
                batch: batch.clone(),
                v: v.clone(),
                f,
            });
        }
    }
    cases
}

/// The library's HVP on backend `B` against `references[i]` for each case. Returns
/// `(case, relative error)`.
pub fn check_hvp<B: Backend>(
    device: &B::Device,
    tol: f64,
    cases: &[HvpCase],
    references: &[Vec<f64>],
) -> Vec<(String, f64)> {
    cases
        .iter()
        .zip(references)
        .map(|(case, reference)| {
            if let HvpFn::Objective(obj) = &case.f {
                let r = ref_objective(&case.cfg, obj, &case.theta, &case.batch);
                assert!(
                    r.kink_margin > 1e-3,
                    "{}: data near a kink ({:.1e})",
                    case.name,
                    r.kink_margin
                );
            }
            let hv = case.library_hvp::<B>(device);
            assert!(
                norm(reference) > 1e-3,
                "{}: degenerate reference",
                case.name
            );
            let err = assert_vec_rel(&format!("HVP {}", case.name), &hv, reference, tol);
            (case.name.clone(), err)
        })
        .collect()
}

pub fn print_errors(title: &str, errors: &[(String, f64)]) {
    eprintln!("{title}:");
    for (name, e) in errors {
        eprintln!("  {e:9.2e}  {name}");
    }
}

// ---------------------------------------------------------------------------------------
// 5. At θ = θ_j (ratio 1): the terms take the algebra's values (hand-derived literals)
// ---------------------------------------------------------------------------------------

/// A 4-sample batch whose `logp_old` is the log-density of the actions under the very
/// distributions evaluated, so `ratio = 1`. The expected values are worked out by hand
/// (all are exact binary fractions):
///
/// adv = (1, −2, 3, 0.5), delta = (1, 2, −1, 0.5), ω1 = 0.5, ω2 = 0.25, γ = 0.5, k = 2.
/// * mean_surr = mean(adv) = 2.5 / 4 = 0.625 (TRPO, PPO, APO, PAPO alike);
/// * mv = ω1 · mean(|2 · delta · ω2|) = 0.5 · mean(0.5 · |delta|) = 0.25 · 4.5 / 4 = 0.28125;
/// * PAPO's mv has no |·|: 0.25 · mean(delta) = 0.25 · 2.5 / 4 = 0.15625;
/// * estimated |H| = |adv| (the KL term is 0): mv = 0.5 · mean(|2 delta |adv||) = 0.5 · 16.5 / 4 = 2.0625;
/// * bias = 0, so the switch is `mean_surr + mean(V) ≥ 0`;
///   V = (2, 1, 0, 1), mean 1: on, min_J_sq = 0.625² + 2 · 0.625 = 1.640625;
///   spread = mean(adv² + 2|adv|V) = (5 + 8 + 9 + 1.25) / 4 = 5.8125,
///   vm = 0.5 · 0.75 / 2 · 5.8125 − 1.640625 = 1.08984375 − 1.640625 = −0.55078125,
///   objective = 0.625 − 2 (0.28125 − 0.55078125) = 1.1640625;
///   V = (−3, −2, −4, −3), mean −3: off, min_J_sq = 0, spread = −26.75 / 4 = −6.6875,
///   vm = 0.1875 · (−6.6875) = −1.25390625, objective = 0.625 + 2 · 0.97265625 = 2.5703125.
pub fn check_at_theta_j<B: Backend>(device: &B::Device, tol: f64) {
    let mean_ = vec![vec![0.3], vec![-0.2], vec![0.5], vec![0.0]];
    let dist = RefDist::Gaussian {
        mean: mean_,
        log_std: vec![vec![-0.5]; 4],
    };
    let actions = vec![vec![0.1], vec![0.4], vec![0.2], vec![-0.3]];
    let logp_old = dist.log_prob(&actions);
    let batch = |value: [f64; 4]| RefBatch {
        obs: vec![vec![0.0]; 4],
        actions: actions.clone(),
        logp_old: logp_old.clone(),
        dist_old: dist.clone(),
        value: value.to_vec(),
        delta: vec![1.0, 2.0, -1.0, 0.5],
        adv: vec![1.0, -2.0, 3.0, 0.5],
        ret: vec![0.0; 4],
        adv_scale: 1.0,
    };
    let on = batch([2.0, 1.0, 0.0, 1.0]);
    let off = batch([-3.0, -2.0, -4.0, -3.0]);
    let fixed = ApoParams {
        k: 2.0,
        omega1: 0.5,
        h_max: HMax::Fixed(0.25),
        gamma: 0.5,
        units: Default::default(),
        switch: Default::default(),
    };
    let est = ApoParams {
        h_max: HMax::Estimated,
        ..fixed
    };
    // (name, objective, batch, mean_surr, mv, vm, objective)
    #[allow(clippy::type_complexity)]
    let cases: Vec<(
        &str,
        Objective,
        &RefBatch,
        f64,
        Option<f64>,
        Option<f64>,
        f64,
    )> = vec![
        ("trpo", Objective::Trpo, &on, 0.625, None, None, 0.625),
        (
            "ppo",
            Objective::Ppo { clip: 0.2 },
            &on,
            0.625,
            None,
            None,
            0.625,
        ),
        (
            "apo k = 0",
            Objective::Apo(ApoParams { k: 0.0, ..fixed }),
            &on,
            0.625,
            None,
            None,
            0.625,
        ),
        (
            "apo, switch on",
            Objective::Apo(fixed),
            &on,
            0.625,
            Some(0.28125),
            Some(-0.55078125),
            1.1640625,
        ),
        (
            "apo, switch off",
            Objective::Apo(fixed),
            &off,
            0.625,
            Some(0.28125),
            Some(-1.25390625),
            2.5703125,
        ),
        (
            "apo estimated |H|",
            Objective::Apo(est),
            &on,
            0.625,
            Some(2.0625),
            Some(-0.55078125),
            0.625 - 2.0 * (2.0625 - 0.55078125),
        ),
        (
            "papo",
            Objective::Papo {
                params: fixed,
                clip: 0.2,
            },
            &on,
            0.625,
            Some(0.15625),
            Some(-0.55078125),
            1.4140625,
        ),
    ];
    let dist_b = dist.to_params::<B>(device);
    for (name, obj, b, ms, mv, vm, objective) in cases {
        let tb = b.to_tensors::<B>(device);
        let terms = obj.evaluate(&dist_b, &tb);
        // ratio is exactly 1 in f64 (logp_old is the same density)
        let ratio = host(apo::ratio(
            dist_b.log_prob(tb.actions.clone()),
            tb.logp_old.clone(),
        ));
        for r in ratio {
            assert_close(&format!("{name}: ratio"), r, 1.0, tol, 1.0);
        }
        assert_close(
            &format!("{name}: mean_surr"),
            scalar(terms.mean_surr),
            ms,
            tol,
            1.0,
        );
        assert_close(
            &format!("{name}: objective"),
            scalar(terms.objective),
            objective,
            tol,
            1.0,
        );
        assert_eq!(
            terms.mean_variance.is_some(),
            mv.is_some(),
            "{name}: mv presence"
        );
        if let (Some(a), Some(e)) = (terms.mean_variance, mv) {
            assert_close(&format!("{name}: mean_variance"), scalar(a), e, tol, 1.0);
        }
        if let (Some(a), Some(e)) = (terms.variance_mean, vm) {
            assert_close(&format!("{name}: variance_mean"), scalar(a), e, tol, 1.0);
        }
    }
    // and the bias really is 0 at ratio 1
    let tb = on.to_tensors::<B>(device);
    let bias = scalar(apo::lower_bound_bias(
        &Comm::default(),
        dist_b.log_prob(tb.actions.clone()),
        tb.logp_old.clone(),
        tb.adv.clone(),
        0.5,
    ));
    assert_close("bias at θ_j", bias, 0.0, tol, 1.0);
}
