//! The trust-region step: conjugate gradient, the natural-gradient step on a problem with
//! a known Fisher matrix, and the line search's guarantees.

use crate::common;

use apo_core::distribution::DistParams;
use apo_core::objective::{ApoParams, HMax, Objective};
use apo_core::policy::{Policy, PolicyFamily};
use apo_core::trust_region::{
    conjugate_gradient, trust_region_step, LineSearchOutcome, TrustRegionConfig,
};
use burn::module::{Module, Param};
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;
use common::*;

// ---------------------------------------------------------------------------------------
// Dense linear algebra, written here (the references)
// ---------------------------------------------------------------------------------------

fn matvec(a: &[Vec<f64>], x: &[f64]) -> Vec<f64> {
    a.iter().map(|row| dot(row, x)).collect()
}

/// Solves `A x = b` by Gaussian elimination with partial pivoting.
#[allow(clippy::needless_range_loop)] // textbook row operations, index by index
fn solve(a: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
    let n = b.len();
    let mut m: Vec<Vec<f64>> = a
        .iter()
        .zip(b)
        .map(|(row, bi)| row.iter().copied().chain([*bi]).collect())
        .collect();
    for col in 0..n {
        let p = (col..n)
            .max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))
            .unwrap();
        m.swap(col, p);
        for r in col + 1..n {
            let f = m[r][col] / m[col][col];
            for c in col..=n {
                m[r][c] -= f * m[col][c];
            }
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|c| m[r][c] * x[c]).sum();
        x[r] = (m[r][n] - s) / m[r][r];
    }
    x
}

// ---------------------------------------------------------------------------------------
// Conjugate gradient
// ---------------------------------------------------------------------------------------

fn random_spd(n: usize, rng: &mut Rng) -> Vec<Vec<f64>> {
    let m = rng.matrix(n, n, 1.0);
    (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    (0..n).map(|k| m[k][i] * m[k][j]).sum::<f64>() + if i == j { 1.0 } else { 0.0 }
                })
                .collect()
        })
        .collect()
}

#[test]
fn conjugate_gradient_solves_a_random_spd_system_to_its_tolerance() {
    let mut rng = Rng::new(1);
    let n = 20;
    for trial in 0..5 {
        let a = random_spd(n, &mut rng);
        let b = rng.normals(n, 1.0);
        for tol in [1e-6, 1e-12, 1e-20] {
            let sol = conjugate_gradient(|v| matvec(&a, v), &b, 500, tol);
            let ax = matvec(&a, &sol.x);
            let res_sq: f64 = ax.iter().zip(&b).map(|(p, q)| (p - q).powi(2)).sum();
            assert!(
                sol.residual_sq < tol,
                "trial {trial}: reported residual {} ≥ tol {tol}",
                sol.residual_sq
            );
            // the true residual, not only CG's recursive estimate
            assert!(
                res_sq < 10.0 * tol + 1e-24,
                "trial {trial}, tol {tol}: ‖Ax − b‖² = {res_sq:.3e}"
            );
            assert!(
                sol.iterations <= 200,
                "trial {trial}: {} iterations",
                sol.iterations
            );
            if tol <= 1e-12 {
                assert_vec_rel(
                    &format!("trial {trial}: x vs dense solve"),
                    &sol.x,
                    &solve(&a, &b),
                    1e-6,
                );
            }
        }
    }
}

#[test]
fn conjugate_gradient_respects_its_iteration_cap_and_reports_the_residual() {
    let mut rng = Rng::new(2);
    let a = random_spd(20, &mut rng);
    let b = rng.normals(20, 1.0);
    let mut calls = 0;
    let sol = conjugate_gradient(
        |v| {
            calls += 1;
            matvec(&a, v)
        },
        &b,
        3,
        1e-30,
    );
    assert_eq!(sol.iterations, 3);
    assert_eq!(calls, 3, "one product per iteration");
    let ax = matvec(&a, &sol.x);
    let res_sq: f64 = ax.iter().zip(&b).map(|(p, q)| (p - q).powi(2)).sum();
    assert_close("reported residual", sol.residual_sq, res_sq, 1e-8, 0.0);
    assert!(
        res_sq > 1e-6,
        "3 iterations cannot solve a 20-dimensional system"
    );

    // b = 0: x = 0 without any product
    let sol = conjugate_gradient(|_| panic!("no product needed"), &[0.0; 20], 10, 1e-10);
    assert_eq!((sol.iterations, sol.x), (0, vec![0.0; 20]));
}

// ---------------------------------------------------------------------------------------
// A policy family with a known Fisher matrix
// ---------------------------------------------------------------------------------------

/// `π(a|x) = N(x W, σ² I)` with a fixed σ that is not a parameter. Then
/// `KL(π_j ‖ π_θ) = Σ_i ((x (W_j − W))_i)² / 2σ²` is exactly quadratic in `W`, with
/// Hessian `F = (1/N) Σ_n x_n x_nᵀ / σ² ⊗ I`.
#[derive(Module, Debug)]
struct LinearGaussian<B: Backend> {
    w: Param<Tensor<B, 2>>,
    #[module(skip)]
    log_std: f64,
}

impl<B: Backend> Policy<B> for LinearGaussian<B> {
    fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
        let mean = obs.matmul(self.w.val());
        let log_std = Tensor::full(mean.dims(), self.log_std, &mean.device());
        DistParams::Gaussian { mean, log_std }
    }
}

#[derive(Debug, Clone)]
struct LinearFamily {
    obs: usize,
    act: usize,
    log_std: f64,
}

impl PolicyFamily for LinearFamily {
    type Policy<B: Backend> = LinearGaussian<B>;

    fn init<B: Backend>(&self, device: &B::Device) -> LinearGaussian<B> {
        LinearGaussian {
            w: Param::from_tensor(Tensor::zeros([self.obs, self.act], device)),
            log_std: self.log_std,
        }
    }
}

/// `W` is flattened row-major `[obs, act]`: index `a · act + i`.
fn linear_dist(fam: &LinearFamily, w: &[f64], obs: &[Vec<f64>]) -> RefDist {
    let mean = obs
        .iter()
        .map(|x| {
            (0..fam.act)
                .map(|i| (0..fam.obs).map(|a| x[a] * w[a * fam.act + i]).sum())
                .collect()
        })
        .collect();
    RefDist::Gaussian {
        mean,
        log_std: vec![vec![fam.log_std; fam.act]; obs.len()],
    }
}

fn linear_batch(
    fam: &LinearFamily,
    w: &[f64],
    n: usize,
    value_mean: f64,
    rng: &mut Rng,
) -> RefBatch {
    let obs = rng.matrix(n, fam.obs, 1.0);
    let dist_old = linear_dist(fam, w, &obs);
    let actions = sample_actions(&dist_old, rng);
    let logp_old = dist_old.log_prob(&actions);
    RefBatch {
        obs,
        actions,
        logp_old,
        dist_old,
        value: (0..n).map(|_| value_mean + rng.normal()).collect(),
        delta: (0..n).map(|_| rng.normal()).collect(),
        adv: (0..n).map(|_| 0.3 + rng.normal()).collect(),
        ret: vec![0.0; n],
        adv_scale: 1.0,
    }
}

/// The Fisher matrix `(1/N) Σ x xᵀ / σ² ⊗ I` in the row-major `[obs, act]` layout.
fn linear_fisher(fam: &LinearFamily, b: &RefBatch) -> Vec<Vec<f64>> {
    let d = fam.obs * fam.act;
    let s2 = (2.0 * fam.log_std).exp();
    let n = b.len() as f64;
    let mut f = vec![vec![0.0; d]; d];
    for x in &b.obs {
        for a in 0..fam.obs {
            for c in 0..fam.obs {
                for i in 0..fam.act {
                    f[a * fam.act + i][c * fam.act + i] += x[a] * x[c] / s2 / n;
                }
            }
        }
    }
    f
}

/// `∇_W log π(a_n | x_n)` at `W_j`: `x_{n,a} (a_{n,i} − μ_{n,i}) / σ²`.
fn linear_grad_logp(fam: &LinearFamily, b: &RefBatch, n: usize) -> Vec<f64> {
    let RefDist::Gaussian { mean, .. } = &b.dist_old else {
        unreachable!()
    };
    let s2 = (2.0 * fam.log_std).exp();
    let mut g = vec![0.0; fam.obs * fam.act];
    for a in 0..fam.obs {
        for i in 0..fam.act {
            g[a * fam.act + i] = b.obs[n][a] * (b.actions[n][i] - mean[n][i]) / s2;
        }
    }
    g
}

/// `mean_n(c_n ∇logp_n)`.
fn weighted_score(fam: &LinearFamily, b: &RefBatch, c: impl Fn(usize) -> f64) -> Vec<f64> {
    let mut g = vec![0.0; fam.obs * fam.act];
    for n in 0..b.len() {
        let gl = linear_grad_logp(fam, b, n);
        for (gi, li) in g.iter_mut().zip(gl) {
            *gi += c(n) * li / b.len() as f64;
        }
    }
    g
}

/// The objective's gradient at θ_j, derived by hand for ratio 1 (∇ratio = ∇logp):
/// * TRPO: `∇mean_surr = mean(adv ∇logp)`;
/// * APO, fixed |H| = ω2: `t_n = 2 δ_n ω2`, `∇mv = ω1 mean(sign(t_n)(δ_n² + 2δ_n ω2) ∇logp_n)`,
///   `∇vm = −∇min_J_sq = −2 (mean_surr + mean V) ∇mean_surr` when the switch is on (else 0),
///   so `g = (1 + 2k (mean_surr + mean V)[on]) ∇mean_surr − k ∇mv`;
/// * APO, estimated |H| = |ratio · adv| + c·KL: at θ_j, ∇KL = 0 and ∇|ratio · adv| = |adv| ∇logp,
///   so `∇t_n = (δ_n² + 4 δ_n |adv_n|) ∇logp_n` and `sign(t_n) = sign(δ_n)`.
fn hand_gradient(fam: &LinearFamily, obj: &Objective, b: &RefBatch) -> Vec<f64> {
    let d_ms = weighted_score(fam, b, |n| b.adv[n]);
    match *obj {
        Objective::Trpo => d_ms,
        Objective::Apo(p) => {
            let ms = mean(&b.adv);
            let mv_ = mean(&b.value);
            let on = ms + mv_ >= 0.0;
            let d_mv = match p.h_max {
                HMax::Fixed(w2) => weighted_score(fam, b, |n| {
                    let dl = b.delta[n];
                    p.omega1 * (2.0 * dl * w2).signum() * (dl * dl + 2.0 * dl * w2)
                }),
                HMax::Estimated => weighted_score(fam, b, |n| {
                    let dl = b.delta[n];
                    p.omega1 * dl.signum() * (dl * dl + 4.0 * dl * b.adv[n].abs())
                }),
            };
            let c = 1.0 + if on { 2.0 * p.k * (ms + mv_) } else { 0.0 };
            d_ms.iter()
                .zip(&d_mv)
                .map(|(a, m)| c * a - p.k * m)
                .collect()
        }
        _ => unreachable!(),
    }
}

#[test]
fn trust_region_step_equals_the_closed_form_natural_gradient_step() {
    let fam = LinearFamily {
        obs: 3,
        act: 2,
        log_std: -0.3,
    };
    let device = ndarray_f64();
    let config = TrustRegionConfig {
        max_kl: 0.01,
        cg_iters: 50,
        cg_damping: 0.0,
        cg_residual_tol: 1e-24,
        ..Default::default()
    };
    let apo = ApoParams {
        k: 2.0,
        omega1: 0.3,
        h_max: HMax::Fixed(0.7),
        gamma: 0.5,
        units: Default::default(),
        switch: Default::default(),
    };
    let cases = [
        ("trpo", Objective::Trpo, 0.0),
        ("apo, switch on", Objective::Apo(apo), 3.0),
        ("apo, switch off", Objective::Apo(apo), -3.0),
        (
            "apo, estimated |H|",
            Objective::Apo(ApoParams {
                h_max: HMax::Estimated,
                ..apo
            }),
            3.0,
        ),
    ];
    for (seed, (name, obj, value_mean)) in cases.into_iter().enumerate() {
        let mut rng = Rng::new(100 + seed as u64);
        let w_j = rng.normals(fam.obs * fam.act, 0.7);
        let batch = linear_batch(&fam, &w_j, 40, value_mean, &mut rng);
        let f = linear_fisher(&fam, &batch);
        let g = hand_gradient(&fam, &obj, &batch);
        let x = solve(&f, &g);
        let scale = (2.0 * config.max_kl / dot(&x, &matvec(&f, &x))).sqrt();
        let step: Vec<f64> = x.iter().map(|xi| scale * xi).collect();

        let report = trust_region_step(
            &fam,
            &obj,
            &w_j,
            &batch.to_tensors::<F64>(&device),
            &config,
            apo_core::Kernels::Backend,
        );
        // the linear family has no JVP: its Fisher products come by finite differences
        // (rounding ~1e-10 each in f64), which undamped CG amplifies to ~1e-8
        let err = assert_vec_rel(
            &format!("{name}: full step"),
            &report.full_step,
            &step,
            1e-7,
        );
        eprintln!(
            "{name}: full step relative error {err:.2e}, outcome {:?}",
            report.outcome
        );
        assert!(
            report.cg_iterations <= 6 + 1,
            "{name}: CG on a 6-dim problem took {}",
            report.cg_iterations
        );

        // KL is exactly ½ ΔᵀFΔ for this family: check the returned point's KL both ways
        let delta: Vec<f64> = report.theta.iter().zip(&w_j).map(|(a, b)| a - b).collect();
        let kl_quadratic = 0.5 * dot(&delta, &matvec(&f, &delta));
        let kl_direct =
            mean(&linear_dist(&fam, &report.theta, &batch.obs).kl_from(&batch.dist_old));
        assert_close(
            &format!("{name}: KL closed forms"),
            kl_direct,
            kl_quadratic,
            1e-10,
            1e-12,
        );
        assert_close(
            &format!("{name}: reported KL"),
            report.kl,
            kl_direct,
            1e-10,
            1e-12,
        );
        assert!(kl_direct <= config.max_kl, "{name}: KL {kl_direct} > δ");
        match report.outcome {
            // the full step sits on the boundary ½ΔᵀFΔ = δ, which rounding can put just outside
            LineSearchOutcome::Accepted { r#try } => {
                assert!(r#try <= 1, "{name}: accepted only at try {}", r#try)
            }
            other => panic!("{name}: {other:?}"),
        }
    }
}

// ---------------------------------------------------------------------------------------
// The line search never breaks the KL bound, improves the objective, keeps θ_j otherwise
// ---------------------------------------------------------------------------------------

struct Outcomes {
    accepted_first: usize,
    backtracked: usize,
    rejected: usize,
    /// Tries refused because their KL (computed here) exceeded δ.
    kl_refusals: usize,
}

/// Runs a trust-region step on the MLP policy and checks every promise of the line
/// search with independently computed KL and objective values.
fn check_line_search(
    name: &str,
    cfg: &apo_core::MlpPolicyConfig,
    obj: &Objective,
    theta_j: &[f64],
    batch: &RefBatch,
    config: &TrustRegionConfig,
    outcomes: &mut Outcomes,
) {
    let device = ndarray_f64();
    let report = trust_region_step(
        cfg,
        obj,
        theta_j,
        &batch.to_tensors::<F64>(&device),
        config,
        apo_core::Kernels::Backend,
    );
    let before = ref_objective(cfg, obj, theta_j, batch).objective;
    let scale = before.abs().max(1.0);
    assert_close(
        &format!("{name}: objective_before"),
        report.objective_before,
        before,
        1e-10,
        scale,
    );
    let kl = ref_mean_kl(cfg, &report.theta, batch);
    assert!(
        kl <= config.max_kl * (1.0 + 1e-12),
        "{name}: KL of the returned θ is {kl} > δ = {}",
        config.max_kl
    );
    let candidate = |i: usize| -> Vec<f64> {
        let frac = config.backtrack_coeff.powi(i as i32);
        theta_j
            .iter()
            .zip(&report.full_step)
            .map(|(t, s)| t + frac * s)
            .collect()
    };
    // a try is acceptable when KL ≤ δ and the objective did not decrease (with a little
    // slack for the last bits, which may differ between the library and the reference)
    let acceptable = |th: &[f64], slack: f64| {
        ref_mean_kl(cfg, th, batch) <= config.max_kl * (1.0 + slack)
            && ref_objective(cfg, obj, th, batch).objective >= before - slack * scale
    };
    match report.outcome {
        LineSearchOutcome::Accepted { r#try } => {
            assert_vec_rel(
                &format!("{name}: θ = θ_j + ξ^try Δ"),
                &report.theta,
                &candidate(r#try),
                1e-13,
            );
            let after = ref_objective(cfg, obj, &report.theta, batch).objective;
            assert!(
                after >= before - 1e-12 * scale,
                "{name}: objective fell from {before} to {after}"
            );
            assert!(
                report.objective_after >= report.objective_before,
                "{name}: reported objective fell"
            );
            assert_close(
                &format!("{name}: objective_after"),
                report.objective_after,
                after,
                1e-10,
                scale,
            );
            // KL of nearby distributions is a difference of O(1) terms: ~1e-16 absolute noise
            assert_close(&format!("{name}: reported KL"), report.kl, kl, 1e-9, 1e-6);
            for i in 0..r#try {
                assert!(!acceptable(&candidate(i), -1e-9), "{name}: try {i} was acceptable but try {try} was taken", try = r#try);
                if ref_mean_kl(cfg, &candidate(i), batch) > config.max_kl {
                    outcomes.kl_refusals += 1;
                }
            }
            if r#try == 0 {
                outcomes.accepted_first += 1;
            } else {
                outcomes.backtracked += 1;
            }
        }
        LineSearchOutcome::Rejected | LineSearchOutcome::NoStep => {
            assert_eq!(
                report.theta, theta_j,
                "{name}: θ changed although the search failed"
            );
            assert_eq!(report.objective_after, report.objective_before, "{name}");
            if report.outcome == LineSearchOutcome::Rejected {
                for i in 0..config.backtrack_iters {
                    assert!(
                        !acceptable(&candidate(i), -1e-9),
                        "{name}: try {i} was acceptable but the search failed"
                    );
                }
                outcomes.rejected += 1;
            }
        }
    }
}

/// Over several batches, both policy families, TRPO and APO (up to k = 1000), and two
/// trust regions: the default (δ = 0.01, damping 0.1) and a wide, undamped one
/// (δ = 0.2, damping 1e-3) where the quadratic model underestimates the KL, so that
/// tries with KL > δ occur and must be refused.
#[test]
fn line_search_never_breaks_the_kl_bound() {
    let configs = [
        TrustRegionConfig {
            max_kl: 0.01,
            ..Default::default()
        },
        TrustRegionConfig {
            max_kl: 0.2,
            cg_damping: 1e-3,
            ..Default::default()
        },
    ];
    let objectives = [
        ("trpo", Objective::Trpo),
        (
            "apo paper params",
            Objective::Apo(ApoParams {
                k: 7.0,
                omega1: 0.005,
                h_max: HMax::Fixed(0.005),
                gamma: 0.99,
                units: Default::default(),
                switch: Default::default(),
            }),
        ),
        (
            "apo k = 100",
            Objective::Apo(ApoParams {
                k: 100.0,
                omega1: 0.05,
                h_max: HMax::Fixed(0.5),
                gamma: 0.9,
                units: Default::default(),
                switch: Default::default(),
            }),
        ),
        (
            "apo k = 1000, estimated |H|",
            Objective::Apo(ApoParams {
                k: 1000.0,
                omega1: 0.01,
                h_max: HMax::Estimated,
                gamma: 0.95,
                units: Default::default(),
                switch: Default::default(),
            }),
        ),
    ];
    let mut outcomes = Outcomes {
        accepted_first: 0,
        backtracked: 0,
        rejected: 0,
        kl_refusals: 0,
    };
    for (pname, cfg) in common::backend::policy_cases() {
        for seed in 0..3u64 {
            let mut rng = Rng::new(1000 + seed);
            let theta_j = random_theta(&cfg, &mut rng);
            let batch = sample_batch(&cfg, &theta_j, 48, 1.0, &mut rng);
            for (oname, obj) in &objectives {
                for config in &configs {
                    let name = format!("{pname}, seed {seed}, {oname}, δ {}", config.max_kl);
                    check_line_search(&name, &cfg, obj, &theta_j, &batch, config, &mut outcomes);
                }
            }
        }
    }
    eprintln!(
        "line search: {} accepted at try 0, {} after backtracking, {} rejected; {} tries refused for KL > δ",
        outcomes.accepted_first, outcomes.backtracked, outcomes.rejected, outcomes.kl_refusals
    );
    assert!(
        outcomes.backtracked > 0,
        "no case exercised the backtracking"
    );
    assert!(
        outcomes.kl_refusals > 0,
        "no try exceeded the KL bound: the bound was not exercised"
    );
}

/// APO with γ = 0.99 and large critic values: at θ_j the bias is 0 and the `min_J_sq`
/// switch is on, but any visible step makes the bias `4γ |mean Δlogp| max(adv) / (1−γ)²`
/// exceed `mean_surr + mean(V)`, switching `min_J_sq` off and lowering the objective by
/// `k · min_J_sq`. The linearized step cannot see that (the switch is not differentiated):
/// with 10 tries the search must give up and keep θ_j; with 100 it finds a tiny step.
#[test]
fn line_search_keeps_theta_when_no_try_is_acceptable() {
    let apo = Objective::Apo(ApoParams {
        k: 7.0,
        omega1: 0.005,
        h_max: HMax::Fixed(0.005),
        gamma: 0.99,
        units: Default::default(),
        switch: Default::default(),
    });
    let cfg = gaussian_cfg(4, &[8, 8], 3);
    let mut rng = Rng::new(77);
    let theta_j = random_theta(&cfg, &mut rng);
    let mut batch = sample_batch(&cfg, &theta_j, 48, 10.0, &mut rng);
    batch.adv.iter_mut().for_each(|a| *a += 0.5);
    let r = ref_objective(&cfg, &apo, &theta_j, &batch);
    assert!(
        r.switch_margin.unwrap() > 0.0 && r.min_j_sq.unwrap() > 1.0,
        "test data: switch on with a large min_J_sq"
    );

    let mut outcomes = Outcomes {
        accepted_first: 0,
        backtracked: 0,
        rejected: 0,
        kl_refusals: 0,
    };
    let short = TrustRegionConfig {
        max_kl: 0.01,
        backtrack_iters: 10,
        ..Default::default()
    };
    check_line_search(
        "10 tries",
        &cfg,
        &apo,
        &theta_j,
        &batch,
        &short,
        &mut outcomes,
    );
    assert_eq!(outcomes.rejected, 1, "the search should have been rejected");

    let long = TrustRegionConfig {
        max_kl: 0.01,
        backtrack_iters: 100,
        ..Default::default()
    };
    check_line_search(
        "100 tries",
        &cfg,
        &apo,
        &theta_j,
        &batch,
        &long,
        &mut outcomes,
    );
    assert_eq!(
        outcomes.backtracked, 1,
        "with 100 tries a tiny step is accepted"
    );
}

/// Zero advantages and zero deltas: the gradient is 0, there is no step, θ_j is kept.
#[test]
fn zero_gradient_gives_no_step() {
    let cfg = categorical_cfg(3, &[5], 4);
    let mut rng = Rng::new(5);
    let theta_j = random_theta(&cfg, &mut rng);
    let mut batch = sample_batch(&cfg, &theta_j, 16, 0.0, &mut rng);
    batch.adv.iter_mut().for_each(|a| *a = 0.0);
    let report = trust_region_step(
        &cfg,
        &Objective::Trpo,
        &theta_j,
        &batch.to_tensors::<F64>(&ndarray_f64()),
        &TrustRegionConfig::default(),
        apo_core::Kernels::Backend,
    );
    assert_eq!(report.outcome, LineSearchOutcome::NoStep);
    assert_eq!(report.theta, theta_j);
    assert!(report.full_step.iter().all(|s| *s == 0.0));
}

#[test]
fn default_config_is_the_papers() {
    let c = TrustRegionConfig::default();
    assert_eq!(
        (c.max_kl, c.backtrack_coeff, c.backtrack_iters),
        (0.02, 0.8, 100)
    );
}
