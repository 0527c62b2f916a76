//! ESPO's, AlphaPPO's and V-MPO's pieces against independent computations: the α-divergence
//! against a numerical integral and its α → 1 limit against the KL, V-MPO's top half, the
//! gradients of its multipliers against their hand-derived forms, and their Adam step by hand.
//! (Their objectives and policy gradients are also in the every-objective checks of
//! `common/backend.rs`, on NdArray f64/f32 and wgpu.)

use crate::common;

use apo_core::distribution::DistParams;
use apo_core::objective::vmpo::{top_half, VmpoTerms, MIN_MULTIPLIER};
use apo_core::objective::{Multipliers, VmpoParams};
use apo_core::tensor_batch::TensorBatch;
use burn::backend::Autodiff;
use burn::tensor::Tensor;
use common::*;

type Ad = Autodiff<F64>;

/// `∫ f` over `[lo, hi]` by composite Simpson's rule with `n` (even) intervals.
fn simpson(f: impl Fn(f64) -> f64, lo: f64, hi: f64, n: usize) -> f64 {
    let h = (hi - lo) / n as f64;
    let inner: f64 = (1..n)
        .map(|i| f(lo + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 })
        .sum();
    (f(lo) + f(hi) + inner) * h / 3.0
}

fn normal_pdf(x: f64, mu: f64, sigma: f64) -> f64 {
    (-(x - mu).powi(2) / (2.0 * sigma * sigma)).exp()
        / (sigma * (2.0 * std::f64::consts::PI).sqrt())
}

/// One-dimensional Gaussians `(μ0, σ0, μ1, σ1, α)`, old first.
const GAUSSIAN_CASES: [(f64, f64, f64, f64, f64); 5] = [
    (0.0, 1.0, 0.0, 1.0, 0.5),
    (0.3, 0.6, -0.4, 0.9, 0.5),
    (1.0, 0.3, 0.2, 0.5, 0.2),
    (-0.5, 1.5, 0.5, 0.7, 0.8),
    (0.0, 0.5, 2.0, 0.5, 0.9),
];

fn gaussian(
    rows: &[(f64, f64)],
    device: &burn::backend::ndarray::NdArrayDevice,
) -> DistParams<F64> {
    RefDist::Gaussian {
        mean: rows.iter().map(|r| vec![r.0]).collect(),
        log_std: rows.iter().map(|r| vec![r.1.ln()]).collect(),
    }
    .to_params(device)
}

#[test]
fn gaussian_alpha_divergence_matches_a_numerical_integral() {
    let device = ndarray_f64();
    for (mu0, s0, mu1, s1, alpha) in GAUSSIAN_CASES {
        let (lo, hi) = (-15.0, 15.0);
        let overlap = simpson(
            |x| normal_pdf(x, mu0, s0).powf(alpha) * normal_pdf(x, mu1, s1).powf(1.0 - alpha),
            lo,
            hi,
            20_000,
        );
        let integral = (overlap - 1.0) / (alpha * (alpha - 1.0));
        let closed = gaussian_alpha_divergence(mu0, s0, mu1, s1, alpha);
        let what = format!("D_{alpha}(N({mu0}, {s0}²) ‖ N({mu1}, {s1}²))");
        assert_close(&format!("{what}: closed form"), closed, integral, 1e-9, 1.0);
        let old = gaussian(&[(mu0, s0)], &device);
        let new = gaussian(&[(mu1, s1)], &device);
        let lib = scalar(new.alpha_divergence_from(&old, alpha));
        assert_close(&format!("{what}: library"), lib, integral, 1e-9, 1.0);
        assert!(lib >= -1e-12, "{what}: negative divergence {lib}");
    }
}

#[test]
fn alpha_divergence_tends_to_the_kl_as_alpha_tends_to_one() {
    let device = ndarray_f64();
    let mut rng = Rng::new(21);
    let alpha = 1.0 - 1e-6;
    // Gaussians of 3 dimensions and categoricals over 5 actions, 6 states each
    let gauss = |rng: &mut Rng| RefDist::Gaussian {
        mean: rng.matrix(6, 3, 1.0),
        log_std: rng.matrix(6, 3, 0.4),
    };
    let cat = |rng: &mut Rng| RefDist::Categorical {
        logits: rng.matrix(6, 5, 1.5),
    };
    for (name, old, new) in [
        ("gaussian", gauss(&mut rng), gauss(&mut rng)),
        ("categorical", cat(&mut rng), cat(&mut rng)),
    ] {
        let (o, n) = (old.to_params::<F64>(&device), new.to_params::<F64>(&device));
        let div = host(n.alpha_divergence_from(&o, alpha));
        let kl = host(n.kl_from(&o));
        let kl_ref = new.kl_from(&old);
        for i in 0..6 {
            assert_close(
                &format!("{name} state {i}: KL"),
                kl[i],
                kl_ref[i],
                1e-12,
                1e-12,
            );
            // D_α = KL / α + O(1 − α)
            assert_close(
                &format!("{name} state {i}: D_α→1"),
                div[i],
                kl_ref[i],
                1e-5,
                1e-8,
            );
        }
        // equal distributions are at divergence 0, for any α
        let same = host(o.alpha_divergence_from(&o, 0.3));
        assert!(same.iter().all(|d| d.abs() < 1e-12), "{name}: {same:?}");
    }
}

#[test]
fn categorical_alpha_divergence_by_hand() {
    // p = (0.5, 0.5), q = (0.9, 0.1), α = 0.5: Σ √(p q) = √0.45 + √0.05,
    // D = (Σ − 1) / (0.5 · −0.5) = 4 (1 − Σ)
    let device = ndarray_f64();
    let p = RefDist::Categorical {
        logits: vec![vec![0.0, 0.0]],
    };
    let q = RefDist::Categorical {
        logits: vec![vec![0.9f64.ln(), 0.1f64.ln()]],
    };
    let expected = 4.0 * (1.0 - (0.45f64.sqrt() + 0.05f64.sqrt()));
    let d = scalar(
        q.to_params::<F64>(&device)
            .alpha_divergence_from(&p.to_params(&device), 0.5),
    );
    assert_close("D_0.5((½, ½) ‖ (0.9, 0.1))", d, expected, 1e-12, 1e-12);
}

#[test]
fn top_half_keeps_the_largest_advantages() {
    assert_eq!(top_half(&[0.5, -1.0, 2.0, 0.5, 3.0, -2.0]), vec![4, 2, 0]);
    // odd sizes keep ⌊n/2⌋; ties keep row order
    assert_eq!(top_half(&[1.0, 1.0, 1.0, 1.0, 1.0]), vec![0, 1]);
    assert_eq!(top_half(&[-3.0, 7.0, 0.0]), vec![1]);
    // one row keeps it; none keeps none
    assert_eq!(top_half(&[4.0]), vec![0]);
    assert!(top_half(&[]).is_empty());
}

/// A 6-row batch of 1-D Gaussian actions with hand-picked advantages.
fn vmpo_batch() -> (RefDist, RefBatch) {
    let old = RefDist::Gaussian {
        mean: vec![
            vec![0.1],
            vec![-0.3],
            vec![0.0],
            vec![0.4],
            vec![0.2],
            vec![-0.1],
        ],
        log_std: vec![vec![-0.5]; 6],
    };
    let actions = vec![
        vec![0.3],
        vec![-0.1],
        vec![0.5],
        vec![0.0],
        vec![-0.2],
        vec![0.1],
    ];
    let logp_old = old.log_prob(&actions);
    let batch = RefBatch {
        obs: vec![vec![0.0]; 6],
        actions,
        logp_old,
        dist_old: old,
        value: vec![0.0; 6],
        delta: vec![0.0; 6],
        adv: vec![1.5, -0.7, 0.2, 2.4, -1.1, 0.9],
        ret: vec![0.0; 6],
        adv_scale: 1.0,
    };
    let new = RefDist::Gaussian {
        mean: vec![
            vec![0.2],
            vec![-0.2],
            vec![0.1],
            vec![0.3],
            vec![0.1],
            vec![0.0],
        ],
        log_std: vec![vec![-0.4]; 6],
    };
    (new, batch)
}

#[test]
fn vmpo_multiplier_gradients_match_their_hand_derived_forms() {
    let device = ndarray_f64();
    let (new, batch) = vmpo_batch();
    let params = VmpoParams {
        eps_eta: 0.008,
        eps_alpha: 0.05,
        eta: 0.7,
        alpha: 5.0,
    };
    let tb: TensorBatch<Ad> = batch.to_tensors(&device);
    let dist: DistParams<Ad> = new.to_params(&device);
    let eta = Tensor::<Ad, 1>::full([1], params.eta, &device).require_grad();
    let alpha = Tensor::<Ad, 1>::full([1], params.alpha, &device).require_grad();
    let logp = dist.log_prob(tb.actions.clone());
    let terms = VmpoTerms::new(&dist, logp, &tb, &params, eta.clone(), alpha.clone());
    let grads = terms.loss().backward();
    let g_eta = scalar(eta.grad(&grads).expect("η's gradient"));
    let g_alpha = scalar(alpha.grad(&grads).expect("α's gradient"));

    // the top half is rows 3, 0, 5 (advantages 2.4, 1.5, 0.9); ψ = softmax(a/η);
    // ∂/∂η [η ε_η + η log mean exp(a/η)] = ε_η + log mean exp(a/η) − Σ ψ a / η
    //                                     = ε_η + H(ψ) − ln 3
    let a = [2.4, 1.5, 0.9];
    let e: Vec<f64> = a.iter().map(|x| (x / params.eta).exp()).collect();
    let z: f64 = e.iter().sum();
    let psi: Vec<f64> = e.iter().map(|x| x / z).collect();
    let entropy: f64 = psi.iter().map(|p| -p * p.ln()).sum();
    let expected_eta = params.eps_eta + entropy - 3f64.ln();
    let direct = params.eps_eta + (z / 3.0).ln()
        - psi.iter().zip(&a).map(|(p, x)| p * x).sum::<f64>() / params.eta;
    assert_close(
        "the two hand forms of ∂/∂η",
        expected_eta,
        direct,
        1e-12,
        1e-12,
    );
    assert_close("∂loss/∂η", g_eta, expected_eta, 1e-10, 1e-10);
    // ∂/∂α = ε_α − KL
    let kl = mean(&new.kl_from(&batch.dist_old));
    assert_close("∂loss/∂α", g_alpha, params.eps_alpha - kl, 1e-10, 1e-10);

    // the loss's value against the reference, and the KL term
    let logp_new = new.log_prob(&batch.actions);
    let (policy, temperature, trust) = ref_vmpo(&params, &logp_new, kl, &batch.adv);
    assert_close(
        "policy loss",
        scalar(terms.policy_loss),
        policy,
        1e-12,
        1e-12,
    );
    assert_close(
        "temperature loss",
        scalar(terms.temperature_loss),
        temperature,
        1e-12,
        1e-12,
    );
    assert_close(
        "trust-region loss (= α ε_α in value)",
        scalar(terms.trust_region_loss),
        trust,
        1e-12,
        1e-12,
    );
    assert_close("KL", scalar(terms.kl), kl, 1e-12, 1e-12);
}

#[test]
fn multipliers_take_adam_steps_and_are_clamped() {
    // Adam's first step moves by lr · g / (|g| + ε) (bias-corrected moments g and g²)
    let lr = 3e-4;
    let mut m = Multipliers::new(1.0, 5.0);
    m.step(-0.25, 0.05, lr);
    let first = |g: f64| lr * g / (g.abs() + 1e-8);
    assert_close("η after one step", m.eta, 1.0 - first(-0.25), 1e-12, 1e-12);
    assert_close("α after one step", m.alpha, 5.0 - first(0.05), 1e-12, 1e-12);
    // second step with gradient g2: m = 0.9·0.1·g1 + 0.1·g2, v = 0.999·0.001·g1² + 0.001·g2²,
    // Δ = −lr · (m / (1 − 0.9²)) / (√(v / (1 − 0.999²)) + ε)
    let (g1, g2) = (-0.25, 0.5);
    let m1 = 0.9 * 0.1 * g1 + 0.1 * g2;
    let v1 = 0.999 * 0.001 * g1 * g1 + 0.001 * g2 * g2;
    let c2 = 1.0 - 0.999f64.powi(2);
    let delta = -lr * (m1 / (1.0 - 0.81)) / ((v1 / c2).sqrt() + 1e-8);
    let eta_1 = m.eta;
    m.step(g2, 0.0, lr);
    assert_close("η after two steps", m.eta, eta_1 + delta, 1e-9, 1e-12);
    // clamped at 1e-8
    let mut small = Multipliers::new(1e-6, 1e-6);
    small.step(1.0, 1.0, 1e-2);
    assert_eq!((small.eta, small.alpha), (MIN_MULTIPLIER, MIN_MULTIPLIER));
    // apply() carries the learned values into the objective's parameters
    let p = VmpoParams {
        eps_eta: 0.1,
        eps_alpha: 0.2,
        eta: 9.0,
        alpha: 9.0,
    };
    let applied = small.apply(p);
    assert_eq!(
        (
            applied.eps_eta,
            applied.eps_alpha,
            applied.eta,
            applied.alpha
        ),
        (0.1, 0.2, MIN_MULTIPLIER, MIN_MULTIPLIER)
    );
}
