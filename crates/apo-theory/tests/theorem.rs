//! Theorem 1's terms and checks: the equality at `π_j`, the terms' values on hand-computable
//! cases, the lower bound on random problems under the corrected reading, the counterexample
//! to the paper's MeanVariance lemma, exact APO iterations and Selberg's inequality.

use apo_theory::bound::{
    bound_k, confidence, discounted_advantage, epsilon, epsilon_pi, eta_max, h_max, j_lower,
    j_upper, mean_variance_bound, min_j_sq, variance_mean_bound, CrossTerm, MuNorm, OverStates,
    Reading, Surrogate,
};
use apo_theory::checks::{check_lower_bound, check_selberg, iterate, Problems, Step};
use apo_theory::{Evaluation, Mdp, TabularPolicy};

const CORRECTED: Reading = Reading {
    mu_norm: MuNorm::Induced,
    cross_term: CrossTerm::AbsoluteAdvantage,
};

fn close(what: &str, a: f64, e: f64, tol: f64) {
    assert!(
        (a - e).abs() <= tol * (1.0 + e.abs()),
        "{what}: got {a:.12e}, expected {e:.12e}"
    );
}

#[test]
fn at_pi_j_every_correction_vanishes_and_m_equals_b() {
    let problems = Problems {
        states: 4,
        actions: 3,
        gamma: 0.9,
        temperature: 1.0,
    };
    for seed in 0..20 {
        let (mdp, logits) = problems.draw(seed);
        let pi_j = TabularPolicy::from_logits(4, 3, &logits);
        let ev_j = Evaluation::new(&mdp, &pi_j).expect("evaluates");
        // Ā_{π_j,π_j} = 0, so T = 0, ε^π = 0, |η|max = |H|max = 0 and J^l = J^u = J(π_j)
        assert!(epsilon_pi(&pi_j, &ev_j) < 1e-12);
        assert!(discounted_advantage(&pi_j, &ev_j)
            .expect("solves")
            .iter()
            .all(|t| t.abs() < 1e-12));
        assert!(h_max(&pi_j, &pi_j, &ev_j)
            .expect("solves")
            .iter()
            .all(|h| h.abs() < 1e-12));
        assert!(eta_max(&pi_j, &pi_j, &ev_j)
            .expect("solves")
            .iter()
            .all(|h| h.abs() < 1e-12));
        close("J^l", j_lower(&pi_j, &pi_j, &ev_j), ev_j.j, 1e-12);
        close("J^u", j_upper(&pi_j, &pi_j, &ev_j), ev_j.j, 1e-12);
        for reading in [Reading::PAPER, CORRECTED] {
            let mv = mean_variance_bound(&mdp, &pi_j, &pi_j, &ev_j, reading, OverStates::Max)
                .expect("solves");
            let vm = variance_mean_bound(&mdp, &pi_j, &pi_j, &ev_j, reading, OverStates::Max)
                .expect("solves");
            close("MV_{π_j,π_j} = MV_{π_j}", mv, ev_j.mean_variance, 1e-10);
            close("VM_{π_j,π_j} = VM_{π_j}", vm, ev_j.variance_mean, 1e-10);
            for k in [0.0, 0.5, 7.0] {
                let s = Surrogate::new(&mdp, &pi_j, &pi_j, &ev_j, k, reading).expect("solves");
                close("M_k^j(π_j) = B_k(π_j)", s.m, s.b, 1e-10);
                close("B_k", s.b, bound_k(&ev_j, k), 1e-12);
            }
        }
    }
}

#[test]
fn terms_by_hand_on_the_safe_or_risky_mdp() {
    // From the start state, safe pays 1, risky pays +3 or −1 (then absorbing, reward 0).
    // π_j: risky with probability ½ everywhere it matters; π: risky with probability p.
    let gamma = 0.9;
    let mdp = Mdp::safe_or_risky(gamma);
    let mix = |p: f64| {
        let mut probs = vec![0.5; 6];
        probs[0] = 1.0 - p;
        probs[1] = p;
        TabularPolicy::from_probs(3, 2, probs).expect("valid")
    };
    let pi_j = mix(0.5);
    let pi = mix(0.8);
    let ev_j = Evaluation::new(&mdp, &pi_j).expect("evaluates");
    // both actions have Q = 1 at the start: every advantage A(s,a) is 0, so ε = ε^π = 0, T = 0,
    // J^l = J^u = J = 1 and |H|max = |η|max = 0
    assert_eq!(epsilon(&ev_j), 0.0);
    close("J^l", j_lower(&pi, &pi_j, &ev_j), 1.0, 1e-12);
    close("min J²", min_j_sq(1.0, 1.0), 1.0, 0.0);
    // A(0,risky,s') = ±2, A(0,safe,·) = 0; E_{π}[A²] − E_{π_j}[A²] = 4 (0.8 − 0.5) = 1.2 at the
    // start state, 0 elsewhere; MV_{π_j} = Σμ Var = 4 · ½ = 2 (μ = δ_start), Ω_{π_j} = (2, 0, 0):
    // MV_{π,π_j} = 1.2/(1 − γ²) + 2 + 2γ²/(1 − γ²)² √(½ D_KL^max) · 2
    let kl = pi.kl(&pi_j, 0);
    let expected_mv = 1.2 / (1.0 - gamma * gamma)
        + 2.0
        + 2.0 * gamma * gamma / (1.0 - gamma * gamma).powi(2) * (0.5 * kl).sqrt() * 2.0;
    let mv = mean_variance_bound(&mdp, &pi, &pi_j, &ev_j, Reading::PAPER, OverStates::Max)
        .expect("solves");
    close("MV_{π,π_j}", mv, expected_mv, 1e-12);
    // VM_{π,π_j} = 0 − min J² + E_μ[V²] = −1 + 1 = 0
    let vm = variance_mean_bound(&mdp, &pi, &pi_j, &ev_j, Reading::PAPER, OverStates::Max)
        .expect("solves");
    close("VM_{π,π_j}", vm, 0.0, 1e-12);
    // and the truth: V(π) = 4 · 0.8 = 3.2 ≤ MV + VM
    let ev = Evaluation::new(&mdp, &pi).expect("evaluates");
    close("V(π)", ev.return_variance, 3.2, 1e-12);
    assert!(ev.return_variance <= mv + vm);
    // Selberg's confidence by hand: 1 − 1/(k² V + 1)
    close(
        "confidence",
        confidence(&ev, 0.5),
        1.0 - 1.0 / (0.25 * 3.2 + 1.0),
        1e-12,
    );
}

#[test]
fn the_corrected_reading_is_a_lower_bound_on_random_problems() {
    for (states, actions, gamma) in [(2, 2, 0.5), (3, 2, 0.9), (4, 3, 0.99)] {
        let problems = Problems {
            states,
            actions,
            gamma,
            temperature: 1.0,
        };
        let report =
            check_lower_bound(&problems, 0..150, &[0.1, 1.0, 7.0], 1, CORRECTED).expect("solves");
        assert_eq!(report.cases, 150 * 3 * 6);
        assert_eq!(
            report.violations, 0,
            "S {states}, A {actions}, γ {gamma}: {:?}",
            report.worst
        );
        assert!(report.max_gap_at_pi_j < 1e-9);
        assert_eq!(report.not_finite, 0);
    }
}

/// A candidate whose surrogate or bound is not finite is counted apart, neither a pass nor a
/// violation, and never the worst case: `apo theory` refuses to report a check it could not
/// make (its `--temperature` range keeps the default problems finite).
#[test]
fn candidates_that_cannot_be_evaluated_are_counted_apart() {
    let problems = Problems {
        states: 3,
        actions: 2,
        gamma: 0.9,
        temperature: 100.0,
    };
    let report =
        check_lower_bound(&problems, 0..3, &[0.1, 1.0, 7.0], 2, CORRECTED).expect("solves");
    assert!(report.not_finite > 0, "{report:?}");
    assert!(report.not_finite <= report.cases);
    if let Some(w) = &report.worst {
        assert!(w.gap().is_finite(), "{w:?}");
    }
}

#[test]
fn the_papers_mean_variance_lemma_fails_on_a_two_state_mdp() {
    // `apo theory --states 2 --actions 2 --gamma 0.5`: seed 584 (docs/theory.md). Where
    // A_{π_j}(s,a,s') < 0 and H(s,a,s') < 0, the appendix's step 2E[A H] ≤ 2E[A]|H|max fails.
    let problems = Problems {
        states: 2,
        actions: 2,
        gamma: 0.5,
        temperature: 1.0,
    };
    // the candidates of `apo theory`'s defaults (k ∈ {0.1, 1, 7}, 2 draws per distance)
    let ks = [0.1, 1.0, 7.0];
    let paper = check_lower_bound(&problems, 584..585, &ks, 2, Reading::PAPER).expect("solves");
    let worst = paper.worst.expect("candidates");
    assert!(paper.violations > 0, "{worst:?}");
    let t = worst.terms;
    assert!(
        t.true_mean_variance > t.mean_variance,
        "the MV lemma fails: {t:?}"
    );
    assert!(
        t.true_variance_mean <= t.variance_mean,
        "the VM lemma holds: {t:?}"
    );
    assert!(t.j >= t.j_lower, "the mean's lower bound holds: {t:?}");
    // the corrected cross term repairs it on the same candidates
    let fixed = check_lower_bound(&problems, 584..585, &ks, 2, CORRECTED).expect("solves");
    assert_eq!(fixed.violations, 0, "{:?}", fixed.worst);
    // reading ‖μᵀ‖∞ as the largest entry of μ breaks the VarianceMean lemma (γ 0.9)
    let max_entry = Reading {
        mu_norm: MuNorm::MaxEntry,
        cross_term: CrossTerm::AbsoluteAdvantage,
    };
    let problems = Problems {
        gamma: 0.9,
        ..problems
    };
    let broken = check_lower_bound(&problems, 0..300, &ks, 1, max_entry).expect("solves");
    let worst = broken.worst.expect("candidates");
    assert!(broken.violations > 10, "{worst:?}");
    assert!(
        worst.terms.true_variance_mean > worst.terms.variance_mean,
        "{worst:?}"
    );
}

#[test]
fn exact_apo_iterations_never_lower_the_bound() {
    let problems = Problems {
        states: 3,
        actions: 2,
        gamma: 0.9,
        temperature: 1.0,
    };
    for seed in 0..5 {
        for k in [0.1, 1.0] {
            let bounds =
                iterate(&problems, seed, k, Step::Exact, CORRECTED, 4, 10).expect("solves");
            assert_eq!(bounds.len(), 5);
            for w in bounds.windows(2) {
                assert!(w[1] >= w[0] - 1e-9, "seed {seed}, k {k}: {bounds:?}");
            }
        }
        // the trust-region surrogate moves further (its steps are not limited by M's KL terms)
        let exact = iterate(&problems, seed, 1.0, Step::Exact, CORRECTED, 3, 10).expect("solves");
        let practical = iterate(
            &problems,
            seed,
            1.0,
            Step::TrustRegion {
                max_kl: 0.02,
                over: OverStates::Average,
            },
            CORRECTED,
            3,
            10,
        )
        .expect("solves");
        assert_eq!(practical.len(), exact.len());
        assert_eq!(practical[0], exact[0], "both start at π_0");
    }
}

#[test]
fn selbergs_confidence_holds_on_sampled_returns() {
    let problems = Problems {
        states: 3,
        actions: 2,
        gamma: 0.8,
        temperature: 1.0,
    };
    let cases = check_selberg(&problems, 0..5, &[0.1, 1.0, 3.0], 20_000, 120).expect("solves");
    assert_eq!(cases.len(), 15);
    for c in &cases {
        assert!((0.0..=1.0).contains(&c.confidence));
        assert!(
            c.empirical + 4.0 * c.stderr.max(1e-4) >= c.confidence,
            "P(R ≥ B_k) {} below {}: {c:?}",
            c.empirical,
            c.confidence
        );
    }
}

#[test]
fn selbergs_confidence_holds_on_an_exact_return_distribution() {
    // safe_or_risky with the risky action taken with probability p: the return is 1 (safe,
    // probability 1 − p), 3 or −1 (risky, p/2 each), so J = 1, V = 4p and
    // P(R ≥ B_k) sums the atoms at or above B_k = 1 − 4pk exactly
    let mdp = Mdp::safe_or_risky(0.9);
    for p in [0.1, 0.5, 1.0] {
        let mut probs = vec![0.5; 6];
        probs[0] = 1.0 - p;
        probs[1] = p;
        let pi = TabularPolicy::from_probs(3, 2, probs).expect("valid");
        let ev = Evaluation::new(&mdp, &pi).expect("evaluates");
        close("V", ev.return_variance, 4.0 * p, 1e-12);
        let atoms = [(1.0, 1.0 - p), (3.0, p / 2.0), (-1.0, p / 2.0)];
        for k in [0.1, 0.25, 0.5, 1.0, 3.0] {
            let bound = bound_k(&ev, k);
            close("B_k", bound, 1.0 - 4.0 * p * k, 1e-12);
            let exact: f64 = atoms
                .iter()
                .filter(|(r, _)| *r >= bound - 1e-12)
                .map(|(_, w)| w)
                .sum();
            let conf = confidence(&ev, k);
            assert!(
                exact >= conf - 1e-12,
                "p {p}, k {k}: P(R ≥ {bound}) = {exact} < {conf}"
            );
        }
    }
}
