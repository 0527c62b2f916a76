//! Exact evaluation against Monte Carlo.
//!
//! Tolerances: 5 standard errors of the Monte Carlo estimate (a false failure has
//! probability below 1e-6 per comparison; the seeds are fixed, so the outcome is
//! deterministic) plus the truncation error of the finite horizon: every sampled return is
//! within `b = truncation_bound` of the full one, which moves the mean by at most `b` and the
//! standard deviation by at most `b`, hence the variance by at most `b (2σ + b)`.

use apo_theory::{sample_returns, truncation_bound, Evaluation, Mdp, SampleStats, TabularPolicy};

const EPISODES: usize = 200_000;

/// Smallest horizon whose truncation bound is below 1e-9.
fn horizon_for(mdp: &Mdp) -> usize {
    (1..10_000)
        .find(|&h| truncation_bound(mdp, h) < 1e-9)
        .expect("gamma too close to 1")
}

fn check_against_mc(mdp: &Mdp, pi: &TabularPolicy, seed: u64) {
    let ev = Evaluation::new(mdp, pi).unwrap();
    let horizon = horizon_for(mdp);
    let b = truncation_bound(mdp, horizon);
    let returns = sample_returns(mdp, pi, EPISODES, horizon, seed);
    assert_eq!(returns.len(), EPISODES);
    let st = SampleStats::from_samples(&returns);
    let mean_tol = 5.0 * st.mean_stderr + b;
    assert!(
        (st.mean - ev.j).abs() <= mean_tol,
        "J: exact {}, MC {} ± {} (tolerance {mean_tol})",
        ev.j,
        st.mean,
        st.mean_stderr
    );
    let var_tol = 5.0 * st.variance_stderr + b * (2.0 * ev.return_variance.sqrt() + b);
    assert!(
        (st.variance - ev.return_variance).abs() <= var_tol,
        "Var: exact {}, MC {} ± {} (tolerance {var_tol})",
        ev.return_variance,
        st.variance,
        st.variance_stderr
    );
}

#[test]
fn mc_matches_exact_on_random_mdp_2x2() {
    let mdp = Mdp::random(2, 2, 0.5, 21);
    check_against_mc(&mdp, &TabularPolicy::random(2, 2, 22, 1.0), 23);
}

#[test]
fn mc_matches_exact_on_random_mdp_3x2() {
    let mdp = Mdp::random(3, 2, 0.8, 31);
    check_against_mc(&mdp, &TabularPolicy::random(3, 2, 32, 1.0), 33);
}

#[test]
fn mc_matches_exact_on_random_mdp_4x3() {
    let mdp = Mdp::random(4, 3, 0.9, 41);
    check_against_mc(&mdp, &TabularPolicy::random(4, 3, 42, 1.0), 43);
}

#[test]
fn mc_matches_exact_on_hand_made_mdps() {
    let mdp = Mdp::safe_or_risky(0.9);
    let half = TabularPolicy::from_probs(3, 2, vec![0.5, 0.5, 1.0, 0.0, 1.0, 0.0]).unwrap();
    check_against_mc(&mdp, &half, 51);
    let mdp = Mdp::chain_gamble(3, 0.9);
    check_against_mc(&mdp, &TabularPolicy::uniform(mdp.states, 2), 52);
}

#[test]
fn mean_variance_matches_mc_per_start_state() {
    // A random MDP whose rewards grow with the state, so that V differs between start states.
    let mut mdp = Mdp::random(3, 2, 0.8, 61);
    let block = mdp.actions * mdp.states;
    for (k, r) in mdp.reward.iter_mut().enumerate() {
        *r += 2.0 * (k / block) as f64;
    }
    let pi = TabularPolicy::random(3, 2, 62, 1.0);
    let ev = Evaluation::new(&mdp, &pi).unwrap();
    let horizon = horizon_for(&mdp);
    let (mut mv, mut se2) = (0.0, 0.0);
    for s in 0..mdp.states {
        let mut delta = vec![0.0; mdp.states];
        delta[s] = 1.0;
        let from_s = mdp.with_start(delta).unwrap();
        let st = SampleStats::from_samples(&sample_returns(
            &from_s,
            &pi,
            50_000,
            horizon,
            70 + s as u64,
        ));
        mv += mdp.start[s] * st.variance;
        se2 += (mdp.start[s] * st.variance_stderr).powi(2);
    }
    let tol = 5.0 * se2.sqrt() + 1e-6;
    assert!(
        (mv - ev.mean_variance).abs() <= tol,
        "MV: exact {}, MC {mv} (tolerance {tol})",
        ev.mean_variance
    );
    // VM is well above the tolerance, so the Monte Carlo estimate tells MV apart from the
    // total return variance MV + VM.
    assert!(
        ev.variance_mean > 10.0 * tol,
        "VM = {}, tolerance {tol}",
        ev.variance_mean
    );
}

#[test]
fn sampling_is_deterministic_in_the_seed_and_respects_the_horizon() {
    let mdp = Mdp::random(3, 2, 0.9, 1);
    let pi = TabularPolicy::uniform(3, 2);
    let a = sample_returns(&mdp, &pi, 100, 50, 9);
    assert_eq!(a, sample_returns(&mdp, &pi, 100, 50, 9));
    assert_ne!(a, sample_returns(&mdp, &pi, 100, 50, 10));
    assert!(sample_returns(&mdp, &pi, 10, 0, 9)
        .iter()
        .all(|&r| r == 0.0));
    // One step: the return is a single reward.
    let max_r = mdp.max_abs_reward();
    assert!(sample_returns(&mdp, &pi, 100, 1, 9)
        .iter()
        .all(|r| r.abs() <= max_r));
    // Truncated returns are bounded by Σ_{t<h} γ^t max|r|.
    let bound = (1.0 - 0.9f64.powi(50)) / 0.1 * max_r;
    assert!(a.iter().all(|r| r.abs() <= bound + 1e-12));
    let b = truncation_bound(&mdp, 50);
    assert!((b - 0.9f64.powi(50) * max_r / 0.1).abs() < 1e-15);
}

#[test]
fn sample_stats_hand_values() {
    let st = SampleStats::from_samples(&[1.0, 2.0, 3.0, 4.0]);
    assert_eq!(st.n, 4);
    assert!((st.mean - 2.5).abs() < 1e-15);
    assert!((st.variance - 5.0 / 3.0).abs() < 1e-15);
    assert!((st.mean_stderr - (5.0f64 / 12.0).sqrt()).abs() < 1e-15);
    // m2 = 1.25, m4 = (2·(1.5)^4 + 2·(0.5)^4) / 4 = 2.5625.
    assert!((st.variance_stderr - ((2.5625f64 - 1.5625) / 4.0).sqrt()).abs() < 1e-15);
    assert!(SampleStats::from_samples(&[1.0]).variance.is_nan());
}
