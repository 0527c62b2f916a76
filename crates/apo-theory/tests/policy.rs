//! Tabular policies, KL divergence and total variation.

use apo_theory::TabularPolicy;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn uniform_and_deterministic_policies() {
    let u = TabularPolicy::uniform(3, 4);
    u.validate().unwrap();
    assert!(u.probs.iter().all(|&p| p == 0.25));
    let d = TabularPolicy::deterministic(3, 4, &[3, 0, 2]);
    d.validate().unwrap();
    assert_eq!(d.prob(0, 3), 1.0);
    assert_eq!(d.prob(1, 0), 1.0);
    assert_eq!(d.prob(2, 2), 1.0);
    assert_eq!(d.row(2), &[0.0, 0.0, 1.0, 0.0]);
}

#[test]
fn softmax_matches_hand_values_and_is_stable() {
    let ln3 = 3f64.ln();
    let pi = TabularPolicy::from_logits(3, 2, &[0.0, ln3, 1000.0, 1000.0 + ln3, -1e4, 0.0]);
    pi.validate().unwrap();
    assert!(close(pi.prob(0, 0), 0.25, 1e-14) && close(pi.prob(0, 1), 0.75, 1e-14));
    // Huge logits: no overflow, same probabilities as the shifted row.
    assert!(close(pi.prob(1, 0), 0.25, 1e-12) && close(pi.prob(1, 1), 0.75, 1e-12));
    assert!(pi.prob(2, 0) < 1e-300 && close(pi.prob(2, 1), 1.0, 1e-15));
    let masked = TabularPolicy::from_logits(1, 3, &[f64::NEG_INFINITY, 0.0, 0.0]);
    assert_eq!(masked.row(0), &[0.0, 0.5, 0.5]);
}

#[test]
fn random_policy_is_deterministic_and_temperature_controls_spread() {
    let a = TabularPolicy::random(6, 4, 11, 1.0);
    assert_eq!(a, TabularPolicy::random(6, 4, 11, 1.0));
    assert_ne!(a, TabularPolicy::random(6, 4, 12, 1.0));
    a.validate().unwrap();
    let u = TabularPolicy::uniform(6, 4);
    let hot = TabularPolicy::random(6, 4, 11, 1e3);
    let cold = TabularPolicy::random(6, 4, 11, 1e-3);
    assert!(hot.max_tv(&u) < 1e-2, "{}", hot.max_tv(&u));
    for s in 0..6 {
        let max = cold.row(s).iter().cloned().fold(0.0, f64::max);
        assert!(max > 0.999, "state {s}: {:?}", cold.row(s));
    }
    assert!(a.max_tv(&u) > hot.max_tv(&u));
}

#[test]
fn kl_and_tv_hand_values() {
    let p = TabularPolicy::from_probs(2, 2, vec![0.5, 0.5, 1.0, 0.0]).unwrap();
    let q = TabularPolicy::from_probs(2, 2, vec![0.25, 0.75, 0.5, 0.5]).unwrap();
    let kl0 = 0.5 * (0.5f64 / 0.25).ln() + 0.5 * (0.5f64 / 0.75).ln();
    assert!(close(p.kl(&q, 0), kl0, 1e-15));
    assert!(close(p.kl(&q, 1), 2f64.ln(), 1e-15));
    assert!(close(p.max_kl(&q), 2f64.ln(), 1e-15));
    // KL(q ‖ p) at state 1 is infinite: q puts mass where p has none.
    assert_eq!(q.kl(&p, 1), f64::INFINITY);
    assert_eq!(p.kl(&p, 0), 0.0);
    assert!(close(p.tv(&q, 0), 0.25, 1e-15));
    assert!(close(p.tv(&q, 1), 0.5, 1e-15));
    assert!(close(p.max_tv(&q), 0.5, 1e-15));
    assert_eq!(p.tv(&q, 1), q.tv(&p, 1));
}

#[test]
fn kl_is_nonnegative_and_pinsker_holds() {
    for seed in 0..20 {
        let p = TabularPolicy::random(5, 4, seed, 1.5);
        let q = TabularPolicy::random(5, 4, seed + 100, 1.5);
        for s in 0..5 {
            let (kl, tv) = (p.kl(&q, s), p.tv(&q, s));
            assert!(kl >= 0.0 && (0.0..=1.0).contains(&tv));
            assert!(
                tv * tv <= 0.5 * kl + 1e-15,
                "Pinsker fails: tv {tv}, kl {kl}"
            );
            assert!(kl <= p.max_kl(&q) && tv <= p.max_tv(&q));
        }
    }
}

#[test]
fn from_probs_validates() {
    assert!(TabularPolicy::from_probs(2, 2, vec![0.5, 0.5, 0.6, 0.6]).is_err());
    assert!(TabularPolicy::from_probs(2, 2, vec![1.5, -0.5, 0.5, 0.5]).is_err());
    assert!(TabularPolicy::from_probs(2, 2, vec![0.5, 0.5, 0.5]).is_err());
}
