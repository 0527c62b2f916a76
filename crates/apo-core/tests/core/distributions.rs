//! Action distributions (log-prob, entropy, analytic KL) against closed forms computed by
//! hand in float64, and the built-in MLP policy against a plain-Rust forward pass.

use crate::common;

use std::f64::consts::{E, LN_2, PI};

use apo_core::distribution::DistParams;
use apo_core::flat::{flatten, unflatten};
use apo_core::policy::{Policy, PolicyFamily};
use burn::backend::Wgpu;
use burn::module::Module;
use burn::tensor::backend::Backend;
use common::*;

/// Hand-derived literals.
fn check_literals<B: Backend>(device: &B::Device, tol: f64) {
    // N((0.5, −1), diag(2², 0.5²)) at a = (1.5, −0.5): z = (0.5, 1),
    // log p = −½(0.25 + 1) − ln 2 − ln 0.5 − ln 2π = −0.625 − ln 2π
    let g = DistParams::<B>::Gaussian {
        mean: t2(&[vec![0.5, -1.0]], device),
        log_std: t2(&[vec![LN_2, -LN_2]], device),
    };
    let lp = scalar(g.log_prob(t2(&[vec![1.5, -0.5]], device)));
    assert_rel("gaussian log_prob", lp, -0.625 - (2.0 * PI).ln(), tol);
    // entropy Σ ½ ln(2πe σ²) = ln(2πe) + ln 2 + ln 0.5 = ln(2πe)
    assert_rel(
        "gaussian entropy",
        scalar(g.entropy()),
        (2.0 * PI * E).ln(),
        tol,
    );
    // KL(N(0, 1) ‖ N(1, 2²)) per dimension = ln 2 + (1 + 1)/(2·4) − ½ = ln 2 − ¼; two dims
    let old = DistParams::<B>::Gaussian {
        mean: t2(&[vec![0.0, 0.0]], device),
        log_std: t2(&[vec![0.0, 0.0]], device),
    };
    let new = DistParams::<B>::Gaussian {
        mean: t2(&[vec![1.0, -1.0]], device),
        log_std: t2(&[vec![LN_2, LN_2]], device),
    };
    assert_rel(
        "gaussian KL",
        scalar(new.kl_from(&old)),
        2.0 * (LN_2 - 0.25),
        tol,
    );

    // softmax(0, ln 2, ln 3) = (1/6, 2/6, 3/6)
    let c = DistParams::<B>::Categorical {
        logits: t2(&[vec![0.0, LN_2, 3f64.ln()]], device),
    };
    assert_rel(
        "categorical log_prob",
        scalar(c.log_prob(t2(&[vec![0.0, 0.0, 1.0]], device))),
        0.5f64.ln(),
        tol,
    );
    assert_rel(
        "categorical log_prob",
        scalar(c.log_prob(t2(&[vec![1.0, 0.0, 0.0]], device))),
        (1.0f64 / 6.0).ln(),
        tol,
    );
    let h = (6f64.ln()) / 6.0 + (3f64.ln()) / 3.0 + LN_2 / 2.0;
    assert_rel("categorical entropy", scalar(c.entropy()), h, tol);
    // KL((1/6, 1/3, 1/2) ‖ uniform) = 1/6 ln(1/2) + 1/3 ln 1 + 1/2 ln(3/2)
    let uniform = DistParams::<B>::Categorical {
        logits: t2(&[vec![0.3, 0.3, 0.3]], device),
    };
    assert_rel(
        "categorical KL",
        scalar(uniform.kl_from(&c)),
        -LN_2 / 6.0 + 0.5 * 1.5f64.ln(),
        tol,
    );
}

/// Random batches against the plain-f64 closed forms; KL(p ‖ p) = 0; KL ≥ 0.
fn check_random<B: Backend>(device: &B::Device, tol: f64) {
    let mut rng = Rng::new(3);
    let n = 16;
    let gauss = |rng: &mut Rng| RefDist::Gaussian {
        mean: rng.matrix(n, 3, 1.0),
        log_std: rng.matrix(n, 3, 0.5),
    };
    let cat = |rng: &mut Rng| RefDist::Categorical {
        logits: rng.matrix(n, 5, 1.5),
    };
    for (family, p, q) in [
        ("gaussian", gauss(&mut rng), gauss(&mut rng)),
        ("categorical", cat(&mut rng), cat(&mut rng)),
    ] {
        let actions = sample_actions(&q, &mut rng);
        let (pb, qb) = (p.to_params::<B>(device), q.to_params::<B>(device));
        let lp = host(pb.log_prob(t2(&actions, device)));
        for (i, (a, e)) in lp.iter().zip(p.log_prob(&actions)).enumerate() {
            assert_rel(&format!("{family} log_prob[{i}]"), *a, e, tol);
        }
        for (i, (a, e)) in host(pb.entropy()).iter().zip(p.entropy()).enumerate() {
            assert_rel(&format!("{family} entropy[{i}]"), *a, e, tol);
        }
        let kl = host(qb.kl_from(&pb));
        for (i, (a, e)) in kl.iter().zip(q.kl_from(&p)).enumerate() {
            assert!(e > 1e-3, "test data: KL too small to be a useful check");
            assert_rel(&format!("{family} KL(p‖q)[{i}]"), *a, e, tol);
        }
        for (i, v) in host(pb.kl_from(&pb)).iter().enumerate() {
            assert!(v.abs() <= tol, "{family} KL(p‖p)[{i}] = {v}");
        }
    }
}

#[test]
fn closed_forms_ndarray_f64() {
    let device = ndarray_f64();
    check_literals::<F64>(&device, 1e-14);
    check_random::<F64>(&device, 1e-12);
}

#[test]
fn closed_forms_wgpu() {
    let device = wgpu();
    check_literals::<Wgpu>(&device, 1e-5);
    check_random::<Wgpu>(&device, 1e-4);
}

/// The built-in MLP policy computes `tanh(x W1 + b1) → tanh(· W2 + b2) → · W3 + b3` with
/// the parameters read, in the order of `flat::flatten`, as `[W1 (in×out, row-major), b1,
/// W2, b2, W3, b3, log_std]` — the layout the plain-Rust reference policy assumes.
#[test]
fn mlp_policy_matches_reference_forward() {
    let device = ndarray_f64();
    let mut rng = Rng::new(17);
    for cfg in [
        gaussian_cfg(4, &[8, 6], 3),
        categorical_cfg(5, &[7], 4),
        gaussian_cfg(2, &[], 1),
    ] {
        let theta = random_theta(&cfg, &mut rng);
        let policy = cfg.init::<F64>(&device);
        assert_eq!(
            policy.num_params(),
            policy_params(&cfg),
            "{cfg:?}: parameter count"
        );
        let policy = unflatten(policy, t1::<F64>(&theta, &device));
        assert_eq!(host(flatten(&policy)), theta, "flatten ∘ unflatten = id");
        let obs = rng.matrix(6, cfg.observation_dim, 1.0);
        let reference = ref_policy(&cfg, &theta, &obs);
        match (policy.distribution(t2(&obs, &device)), reference) {
            (
                DistParams::Gaussian { mean, log_std },
                RefDist::Gaussian {
                    mean: m,
                    log_std: s,
                },
            ) => {
                let (mean, log_std) = (host(mean), host(log_std));
                let (m, s): (Vec<f64>, Vec<f64>) = (m.concat(), s.concat());
                assert!(rel_err(&mean, &m) < 1e-13, "{cfg:?}: means");
                assert!(rel_err(&log_std, &s) < 1e-13, "{cfg:?}: log-stds");
            }
            (DistParams::Categorical { logits }, RefDist::Categorical { logits: l }) => {
                assert!(
                    rel_err(&host(logits), &l.concat()) < 1e-13,
                    "{cfg:?}: logits"
                );
            }
            _ => panic!("{cfg:?}: wrong family"),
        }
    }
}

/// A fresh Gaussian policy's log-std is the configured `init_log_std`, state-independent.
#[test]
fn initial_log_std_is_state_independent() {
    let device = ndarray_f64();
    let mut cfg = gaussian_cfg(3, &[4], 2);
    cfg.init_log_std = -0.7;
    let policy = cfg.init::<F64>(&device);
    let obs = Rng::new(1).matrix(5, 3, 1.0);
    let DistParams::Gaussian { log_std, .. } = policy.distribution(t2(&obs, &device)) else {
        panic!("family")
    };
    assert_eq!(log_std.dims(), [5, 2]);
    for v in host(log_std) {
        assert_close("log_std", v, -0.7, 1e-15, 1.0);
    }
}
