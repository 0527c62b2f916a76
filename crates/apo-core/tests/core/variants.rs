//! The variants of APO's penalty and line search (docs/algorithms.md, "Variants that keep the
//! step"): values written out by hand on a two-sample batch, the properties each variant is
//! for (the scale-free penalty does not see the reward scale; the held switch is decided at
//! θ_j; the switch off drops `min_J_sq`), and the improvement-ratio acceptance of the line
//! search, checked try by try. Values and gradients against the float64 reference on every
//! policy shape and on wgpu are in `objectives.rs` (the variant cases of `objective_cases`).

use crate::common;

use apo_core::objective::{ApoParams, HMax, Objective, PenaltyUnits, Switch};
use apo_core::trust_region::{trust_region_step, Acceptance, TrustRegionConfig};
use apo_core::LineSearchOutcome;
use common::backend::*;
use common::*;

/// A two-sample batch of a 1-D Gaussian policy: π_j = N(0, 1), actions 0.5 and −1, and the
/// candidate N(0.1, 1), so `ratio_i = exp(0.1 a_i − 0.005)`.
fn two_samples(delta: [f64; 2], value: [f64; 2], adv_scale: f64) -> (RefBatch, RefDist) {
    let old = RefDist::Gaussian {
        mean: vec![vec![0.0], vec![0.0]],
        log_std: vec![vec![0.0], vec![0.0]],
    };
    let actions = vec![vec![0.5], vec![-1.0]];
    let logp_old = old.log_prob(&actions);
    let batch = RefBatch {
        obs: vec![vec![0.0], vec![0.0]],
        actions,
        logp_old,
        dist_old: old,
        value: value.to_vec(),
        delta: delta.to_vec(),
        adv: vec![1.0, -1.0],
        ret: vec![0.0, 0.0],
        adv_scale,
    };
    let new = RefDist::Gaussian {
        mean: vec![vec![0.1], vec![0.1]],
        log_std: vec![vec![0.0], vec![0.0]],
    };
    (batch, new)
}

fn params(units: PenaltyUnits, switch: Switch) -> ApoParams {
    ApoParams {
        k: 2.0,
        omega1: 0.1,
        h_max: HMax::Fixed(0.5),
        gamma: 0.5,
        units,
        switch,
    }
}

/// The library's `(objective, min_j_sq_on)` for `params` on the two-sample batch.
fn library(params: ApoParams, batch: &RefBatch, dist: &RefDist) -> (f64, f64) {
    let device = ndarray_f64();
    let terms = Objective::Apo(params).evaluate(
        &dist.to_params::<F64>(&device),
        &batch.to_tensors::<F64>(&device),
    );
    (
        scalar(terms.objective),
        scalar(terms.min_j_sq_on.expect("APO terms")),
    )
}

#[test]
fn each_variant_takes_its_hand_computed_value_on_two_samples() {
    // ratio_1 = exp(0.05 − 0.005), ratio_2 = exp(−0.1 − 0.005); adv = (1, −1); k 2, ω1 0.1,
    // ω2 0.5, γ 0.5; delta = (2, −4), V = (6, 2), σ_A = 2
    let (r1, r2) = ((0.045f64).exp(), (-0.105f64).exp());
    let ms = (r1 - r2) / 2.0;
    // bias = 4γ/(1−γ)² · |mean(logp_old − logp)| · max(adv) = 8 · |mean(0.005 − 0.1 a)|
    let bias = 8.0 * ((0.005 - 0.05) + (0.005 + 0.1)) / 2.0;
    let t = |r: f64, d: f64| (r - 1.0) * d * d + 2.0 * r * d * 0.5;
    let (k, w1, g) = (2.0, 0.1, 0.5);
    // (delta, V) in the penalty's units, the switch on?
    let objective = |d: [f64; 2], v: [f64; 2], on: bool| {
        let mv = w1 * (t(r1, d[0]).abs() + t(r2, d[1]).abs()) / 2.0;
        let mean_v = (v[0] + v[1]) / 2.0;
        let spread = ((1.0 + 2.0 * v[0]) + (1.0 + 2.0 * v[1])) / 2.0;
        let min_j_sq = if on { ms * ms + 2.0 * mean_v * ms } else { 0.0 };
        ms - k * (mv + w1 * (1.0 - g * g) / k * spread - min_j_sq)
    };
    let raw = ([2.0, -4.0], [6.0, 2.0]);
    let scaled = ([1.0, -2.0], [3.0, 1.0]);
    let (batch, dist) = two_samples(raw.0, raw.1, 2.0);
    // the paper's switch: ms + mean(V) − bias = 0.0729 + 4 − 0.24 ≥ 0, on
    assert!(ms + 4.0 - bias >= 0.0);
    let cases = [
        ("paper", PenaltyUnits::Reward, Switch::Paper, raw, true),
        (
            "scale-free",
            PenaltyUnits::Advantage,
            Switch::Paper,
            scaled,
            true,
        ),
        ("held", PenaltyUnits::Reward, Switch::Held, raw, true),
        ("off", PenaltyUnits::Reward, Switch::Off, raw, false),
        (
            "scale-free, off",
            PenaltyUnits::Advantage,
            Switch::Off,
            scaled,
            false,
        ),
    ];
    for (name, units, switch, (d, v), on) in cases {
        let (got, got_on) = library(params(units, switch), &batch, &dist);
        assert_close(name, got, objective(d, v, on), 1e-12, 1.0);
        assert_eq!(got_on, f64::from(u8::from(on)), "{name}: switch");
    }
    // the variants differ from the paper where they should (the test can fail)
    let paper = library(params(PenaltyUnits::Reward, Switch::Paper), &batch, &dist).0;
    for (units, switch) in [
        (PenaltyUnits::Advantage, Switch::Paper),
        (PenaltyUnits::Reward, Switch::Off),
    ] {
        let other = library(params(units, switch), &batch, &dist).0;
        assert!(
            (other - paper).abs() > 1e-3,
            "{units:?}/{switch:?} equals the paper's"
        );
    }
}

#[test]
fn held_switch_is_decided_at_theta_j_and_the_papers_at_theta() {
    // mean(V) = −0.05 and mean(adv) = 0: off at θ_j. At θ the paper's margin is
    // ms − 0.05 − bias with ms = 0.0729 and bias 0.24: off too; with mean(V) = 0.2 the paper's
    // margin is 0.0729 + 0.2 − 0.24 ≥ 0 (on) and the held one 0.2 ≥ 0 (on); with mean(V) = 0.1
    // the paper's is 0.0729 + 0.1 − 0.24 < 0 (off) while the held one stays on.
    for (mean_v, paper_on, held_on) in
        [(-0.05, false, false), (0.2, true, true), (0.1, false, true)]
    {
        let (batch, dist) = two_samples([2.0, -4.0], [mean_v + 1.0, mean_v - 1.0], 2.0);
        let (_, paper) = library(params(PenaltyUnits::Reward, Switch::Paper), &batch, &dist);
        let (_, held) = library(params(PenaltyUnits::Reward, Switch::Held), &batch, &dist);
        assert_eq!(
            paper,
            f64::from(u8::from(paper_on)),
            "paper switch at mean(V) {mean_v}"
        );
        assert_eq!(
            held,
            f64::from(u8::from(held_on)),
            "held switch at mean(V) {mean_v}"
        );
    }
}

#[test]
fn scale_free_penalty_does_not_see_the_reward_scale() {
    let cfg = gaussian_cfg(4, &[8, 8], 3);
    let (_, theta, mut batch) = gradient_point(&cfg, 5.0, 21);
    batch.adv_scale = 1.7;
    let device = ndarray_f64();
    let value = |units: PenaltyUnits, b: &RefBatch| {
        let obj = Objective::Apo(params(units, Switch::Paper));
        let dist = ref_policy(&cfg, &theta, &b.obs);
        let terms = obj.evaluate(
            &dist.to_params::<F64>(&device),
            &b.to_tensors::<F64>(&device),
        );
        (
            scalar(terms.objective),
            library_gradient::<F64>(&cfg, &obj, &theta, b, &device).1,
        )
    };
    // rewards × 1000: delta, V and σ_A scale with them; the normalized advantages do not
    let mut big = batch.clone();
    let c = 1000.0;
    big.delta.iter_mut().for_each(|d| *d *= c);
    big.value.iter_mut().for_each(|v| *v *= c);
    big.adv_scale *= c;
    let (f, g) = value(PenaltyUnits::Advantage, &batch);
    let (f_big, g_big) = value(PenaltyUnits::Advantage, &big);
    assert_close("scale-free objective, rewards × 1000", f_big, f, 1e-10, 1.0);
    assert_vec_rel("scale-free gradient, rewards × 1000", &g_big, &g, 1e-9);
    // and it is the paper's penalty on delta / σ_A, V / σ_A
    let mut divided = batch.clone();
    divided.delta.iter_mut().for_each(|d| *d /= batch.adv_scale);
    divided.value.iter_mut().for_each(|v| *v /= batch.adv_scale);
    let (f_div, _) = value(PenaltyUnits::Reward, &divided);
    assert_close("scale-free = paper on scaled inputs", f, f_div, 1e-12, 1.0);
    // the paper's penalty does see the scale
    let (p, _) = value(PenaltyUnits::Reward, &batch);
    let (p_big, _) = value(PenaltyUnits::Reward, &big);
    assert!(
        (p_big - p).abs() > 1.0,
        "paper objective {p} vs ×1000 {p_big}"
    );
}

#[test]
fn ratio_acceptance_takes_the_first_try_whose_improvement_reaches_the_ratio() {
    let device = ndarray_f64();
    let cfg = gaussian_cfg(4, &[8, 8], 3);
    let mut counts = [0usize; 2];
    for seed in 0..6u64 {
        let mut rng = Rng::new(300 + seed);
        let theta_j = random_theta(&cfg, &mut rng);
        let mut batch = sample_batch(&cfg, &theta_j, 48, 4.0, &mut rng);
        batch.adv_scale = 3.0;
        for (ratio, obj) in [
            (0.1, Objective::Trpo),
            (
                0.5,
                Objective::Apo(ApoParams {
                    k: 7.0,
                    omega1: 0.005,
                    h_max: HMax::Fixed(0.005),
                    gamma: 0.99,
                    units: PenaltyUnits::Advantage,
                    switch: Switch::Off,
                }),
            ),
            (
                0.9,
                Objective::Apo(params(PenaltyUnits::Reward, Switch::Paper)),
            ),
        ] {
            let config = TrustRegionConfig {
                max_kl: 0.05,
                cg_damping: 1e-3,
                acceptance: Acceptance::Ratio,
                accept_ratio: ratio,
                ..Default::default()
            };
            let tb = batch.to_tensors::<F64>(&device);
            let report = trust_region_step(
                &cfg,
                &obj,
                &theta_j,
                &tb,
                &config,
                apo_core::Kernels::Backend,
            );
            let (f0, g) = library_gradient::<F64>(&cfg, &obj, &theta_j, &batch, &device);
            let predicted = dot(&g, &report.full_step);
            let try_at = |i: usize| {
                let frac = config.backtrack_coeff.powi(i as i32);
                let th: Vec<f64> = theta_j
                    .iter()
                    .zip(&report.full_step)
                    .map(|(t, s)| t + frac * s)
                    .collect();
                let actual = ref_objective(&cfg, &obj, &th, &batch).objective - f0;
                let kl = ref_mean_kl(&cfg, &th, &batch);
                (kl <= config.max_kl, actual, ratio * frac * predicted)
            };
            // a margin of rounding around the test's threshold
            let slack = 1e-9 * f0.abs().max(1.0);
            let last = match report.outcome {
                LineSearchOutcome::Accepted { r#try } => {
                    let (inside, actual, needed) = try_at(r#try);
                    assert!(inside && actual > 0.0 && actual >= needed - slack, "seed {seed}, ratio {ratio}: accepted try {try} has improvement {actual} < {needed}", try = r#try);
                    counts[usize::from(r#try > 0)] += 1;
                    r#try
                }
                LineSearchOutcome::Rejected => config.backtrack_iters,
                LineSearchOutcome::NoStep => 0,
            };
            for i in 0..last {
                let (inside, actual, needed) = try_at(i);
                assert!(
                    !(inside && actual > slack && actual >= needed + slack),
                    "seed {seed}, ratio {ratio}: try {i} qualified (improvement {actual} ≥ {needed}) but was passed over"
                );
            }
        }
    }
    // both a full step and a backtracked one were taken: the rule was exercised
    assert!(
        counts[0] > 0 && counts[1] > 0,
        "accepted at try 0 / later: {counts:?}"
    );
}
