//! Exact evaluation: hand-computed values and identities that must hold to round-off.

use apo_theory::{Evaluation, Mdp, TabularPolicy};

fn assert_close(got: f64, want: f64, tol: f64, what: &str) {
    assert!(
        (got - want).abs() <= tol,
        "{what}: got {got}, want {want} (tolerance {tol})"
    );
}

/// Random (MDP, policy, other policy) triples with varied sizes and discounts.
fn random_cases() -> Vec<(Mdp, TabularPolicy, TabularPolicy)> {
    let configs = [
        (1, 1, 0.5),
        (2, 2, 0.0),
        (3, 2, 0.9),
        (5, 3, 0.95),
        (8, 4, 0.7),
    ];
    configs
        .iter()
        .enumerate()
        .map(|(i, &(ns, na, gamma))| {
            let seed = 1000 + i as u64;
            (
                Mdp::random(ns, na, gamma, seed),
                TabularPolicy::random(ns, na, seed + 1, 1.0),
                TabularPolicy::random(ns, na, seed + 2, 0.7),
            )
        })
        .collect()
}

#[test]
fn single_state_self_loop() {
    let (r, gamma) = (2.5, 0.9);
    let mdp = Mdp::single_state(r, gamma);
    let ev = Evaluation::new(&mdp, &TabularPolicy::uniform(1, 1)).unwrap();
    let v = r / (1.0 - gamma);
    assert_close(ev.v[0], v, 1e-12, "V");
    assert_close(ev.j, v, 1e-12, "J");
    assert_close(ev.q[0], v, 1e-12, "Q");
    assert_close(ev.adv[0], 0.0, 1e-12, "A");
    assert_close(ev.d[0], 1.0, 1e-12, "d");
    assert_close(ev.m2[0], v * v, 1e-9, "M");
    assert_close(ev.var_from(0), 0.0, 1e-9, "Var[R(0)]");
    assert_close(ev.return_variance, 0.0, 1e-9, "return variance");
    assert_close(ev.omega[0], 0.0, 1e-9, "ω");
}

#[test]
fn two_state_cycle_variance_comes_from_the_start_state() {
    let (r0, r1, gamma) = (1.0, -2.0, 0.5);
    let mdp = Mdp::two_state_cycle(r0, r1, gamma);
    let pi = TabularPolicy::uniform(2, 1);
    let ev = Evaluation::new(&mdp, &pi).unwrap();
    // V(0) = (1 − 1) / 0.75 = 0, V(1) = (−2 + 0.5) / 0.75 = −2.
    assert_close(ev.v[0], 0.0, 1e-12, "V(0)");
    assert_close(ev.v[1], -2.0, 1e-12, "V(1)");
    assert_close(ev.j, -1.0, 1e-12, "J");
    assert_close(ev.variance_mean, 1.0, 1e-12, "VM");
    assert_close(ev.mean_variance, 0.0, 1e-12, "MV");
    assert_close(ev.return_variance, 1.0, 1e-12, "return variance");
    // μ = (½, ½) is invariant under the swap, so d = μ.
    assert_close(ev.d[0], 0.5, 1e-12, "d(0)");
    // From state 0 only: d = (1/(1+γ), γ/(1+γ)).
    let ev0 = Evaluation::new(&mdp.with_start(vec![1.0, 0.0]).unwrap(), &pi).unwrap();
    assert_close(ev0.d[0], 1.0 / 1.5, 1e-12, "d(0) from δ_0");
    assert_close(ev0.d[1], 0.5 / 1.5, 1e-12, "d(1) from δ_0");
    assert_close(ev0.return_variance, 0.0, 1e-12, "variance from δ_0");
}

#[test]
fn safe_or_risky_by_hand() {
    let gamma = 0.9;
    let mdp = Mdp::safe_or_risky(gamma);
    let safe = TabularPolicy::deterministic(3, 2, &[Mdp::SAFE_ACTION, 0, 0]);
    let risky = TabularPolicy::deterministic(3, 2, &[Mdp::RISKY_ACTION, 0, 0]);
    let es = Evaluation::new(&mdp, &safe).unwrap();
    let er = Evaluation::new(&mdp, &risky).unwrap();
    assert_close(es.j, 1.0, 1e-12, "J safe");
    assert_close(er.j, 1.0, 1e-12, "J risky");
    assert_close(es.return_variance, 0.0, 1e-12, "Var safe");
    assert_close(er.return_variance, 4.0, 1e-12, "Var risky");
    assert_close(es.omega[0], 0.0, 1e-12, "ω(0) safe");
    assert_close(er.omega[0], 4.0, 1e-12, "ω(0) risky");
    for ev in [&es, &er] {
        assert_close(ev.q_at(0, Mdp::SAFE_ACTION), 1.0, 1e-12, "Q(0, safe)");
        assert_close(ev.q_at(0, Mdp::RISKY_ACTION), 1.0, 1e-12, "Q(0, risky)");
        assert_close(ev.variance_mean, 0.0, 1e-12, "VM (μ = δ_0)");
        assert_close(ev.v[1], 0.0, 1e-12, "V(absorbing)");
        assert_close(ev.var_from(2), 0.0, 1e-12, "Var(absorbing)");
    }
    assert_close(er.q3(0, Mdp::RISKY_ACTION, 1), 3.0, 1e-12, "q3 win");
    assert_close(er.a3(0, Mdp::RISKY_ACTION, 1), 2.0, 1e-12, "a3 win");
    assert_close(er.a3(0, Mdp::RISKY_ACTION, 2), -2.0, 1e-12, "a3 loss");
    // d: one step in state 0, then absorbed.
    assert_close(es.d[0], 1.0 - gamma, 1e-12, "d safe (0)");
    assert_close(es.d[1], gamma, 1e-12, "d safe (1)");
    assert_close(es.d[2], 0.0, 1e-12, "d safe (2)");
    assert_close(er.d[1], gamma / 2.0, 1e-12, "d risky (1)");
    assert_close(er.d[2], gamma / 2.0, 1e-12, "d risky (2)");
    // Risky with probability p: J = 1, Var = ω(0) = 4p.
    for p in [0.1, 0.25, 0.5] {
        let mixed = TabularPolicy::from_probs(3, 2, vec![1.0 - p, p, 0.5, 0.5, 0.5, 0.5]).unwrap();
        let em = Evaluation::new(&mdp, &mixed).unwrap();
        assert_close(em.j, 1.0, 1e-12, "J mixed");
        assert_close(em.return_variance, 4.0 * p, 1e-12, "Var mixed");
        assert_close(em.omega[0], 4.0 * p, 1e-12, "ω mixed");
    }
}

#[test]
fn chain_gamble_same_mean_different_variance() {
    let (len, gamma) = (4, 0.9);
    let mdp = Mdp::chain_gamble(len, gamma);
    let ns = mdp.states;
    let g = |k: usize| (0..k).map(|t| gamma.powi(t as i32)).sum::<f64>();
    let g2: f64 = (0..len).map(|t| gamma.powi(2 * t as i32)).sum();
    // Every policy has the same values.
    for pi in [
        TabularPolicy::random(ns, 2, 5, 1.0),
        TabularPolicy::deterministic(ns, 2, &vec![Mdp::GAMBLE_ACTION; ns]),
    ] {
        let ev = Evaluation::new(&mdp, &pi).unwrap();
        assert_close(ev.j, g(len), 1e-12, "J");
        for i in 0..=len {
            assert_close(ev.v[2 * i], g(len - i), 1e-12, "V(2i)");
            assert_close(ev.v[2 * i + 1], g(len - i), 1e-12, "V(2i+1)");
        }
    }
    // Gambling with probability p everywhere: Var = 9p Σ_{t<len} γ^{2t}.
    for p in [0.0, 0.3, 1.0] {
        let probs = (0..ns).flat_map(|_| [1.0 - p, p]).collect();
        let pi = TabularPolicy::from_probs(ns, 2, probs).unwrap();
        let ev = Evaluation::new(&mdp, &pi).unwrap();
        assert_close(ev.return_variance, 9.0 * p * g2, 1e-10, "Var");
        assert_close(ev.omega[0], 9.0 * p, 1e-10, "ω(0)");
    }
}

#[test]
fn values_satisfy_the_bellman_equation_from_the_raw_tables() {
    for (mdp, pi, _) in random_cases() {
        let ev = Evaluation::new(&mdp, &pi).unwrap();
        let scale = 1.0 / (1.0 - mdp.gamma);
        for s in 0..mdp.states {
            let mut rhs = 0.0;
            for a in 0..mdp.actions {
                let mut q = 0.0;
                for s2 in 0..mdp.states {
                    q += mdp.p(s, a, s2) * (mdp.r(s, a, s2) + mdp.gamma * ev.v[s2]);
                }
                assert_close(ev.q_at(s, a), q, 1e-12 * scale, "Q(s,a)");
                rhs += pi.prob(s, a) * q;
            }
            assert_close(ev.v[s], rhs, 1e-12 * scale, "Bellman V(s)");
        }
    }
}

#[test]
fn advantages_average_to_zero_under_the_policy() {
    for (mdp, pi, _) in random_cases() {
        let ev = Evaluation::new(&mdp, &pi).unwrap();
        for s in 0..mdp.states {
            let mean_adv: f64 = (0..mdp.actions)
                .map(|a| pi.prob(s, a) * ev.adv_at(s, a))
                .sum();
            assert_close(mean_adv, 0.0, 1e-12 / (1.0 - mdp.gamma), "Σ_a π A");
            // a3 averages to A(s,a) over s'.
            for a in 0..mdp.actions {
                let mean_a3: f64 = (0..mdp.states)
                    .map(|s2| mdp.p(s, a, s2) * ev.a3(s, a, s2))
                    .sum();
                assert_close(mean_a3, ev.adv_at(s, a), 1e-12, "Σ_s' P a3");
            }
        }
    }
}

#[test]
fn discounted_state_distribution_matches_its_power_series() {
    for (mdp, pi, _) in random_cases() {
        let ev = Evaluation::new(&mdp, &pi).unwrap();
        let ns = mdp.states;
        assert_close(ev.d.iter().sum(), 1.0, 1e-12, "Σ d");
        assert!(ev.d.iter().all(|&x| x >= -1e-15), "d ≥ 0: {:?}", ev.d);
        // (1 − γ) Σ_t γ^t μ P_π^t, truncated where γ^t < 1e-15.
        let mut dist = mdp.start.clone();
        let mut series = vec![0.0; ns];
        let mut w = 1.0 - mdp.gamma;
        while w > 1e-16 {
            for (acc, &x) in series.iter_mut().zip(&dist) {
                *acc += w * x;
            }
            let next: Vec<f64> = (0..ns)
                .map(|s2| (0..ns).map(|s| dist[s] * ev.p_pi[s * ns + s2]).sum())
                .collect();
            dist = next;
            w *= mdp.gamma;
        }
        for (s, (&d, &want)) in ev.d.iter().zip(&series).enumerate() {
            assert_close(d, want, 1e-12, &format!("d({s}) vs power series"));
        }
    }
}

#[test]
fn performance_difference_lemma() {
    for (mdp, pi, pi2) in random_cases() {
        let ev = Evaluation::new(&mdp, &pi).unwrap();
        let ev2 = Evaluation::new(&mdp, &pi2).unwrap();
        let mut expected_adv = 0.0;
        for s in 0..mdp.states {
            for a in 0..mdp.actions {
                expected_adv += ev2.d[s] * pi2.prob(s, a) * ev.adv_at(s, a);
            }
        }
        let rhs = expected_adv / (1.0 - mdp.gamma);
        assert_close(ev2.j - ev.j, rhs, 1e-10, "J(π') − J(π)");
    }
}

#[test]
fn law_of_total_variance_over_the_start_state() {
    for (mdp, pi, _) in random_cases() {
        let ev = Evaluation::new(&mdp, &pi).unwrap();
        let tol = 1e-10 / (1.0 - mdp.gamma).powi(2);
        assert_close(
            ev.return_variance,
            ev.mean_variance + ev.variance_mean,
            tol,
            "Var = MV + VM",
        );
        assert!(ev.mean_variance >= -tol && ev.variance_mean >= -tol);
        // Each start state alone: its return variance is var_from(s) and VM = 0; averaging
        // over μ gives MV.
        let mut mv = 0.0;
        for s in 0..mdp.states {
            let mut delta = vec![0.0; mdp.states];
            delta[s] = 1.0;
            let es = Evaluation::new(&mdp.with_start(delta).unwrap(), &pi).unwrap();
            assert_close(es.return_variance, ev.var_from(s), tol, "Var from δ_s");
            assert_close(es.variance_mean, 0.0, tol, "VM from δ_s");
            assert_close(es.j, ev.v[s], tol, "J from δ_s");
            mv += mdp.start[s] * es.return_variance;
        }
        assert_close(ev.mean_variance, mv, tol, "MV");
    }
}

#[test]
fn variance_bellman_equation_with_omega() {
    // Var[R(s)] = ω(s) + γ² Σ_s' P_π(s'|s) Var[R(s')], derived from M independently of how
    // ω is computed.
    for (mdp, pi, _) in random_cases() {
        let ev = Evaluation::new(&mdp, &pi).unwrap();
        let ns = mdp.states;
        let var = ev.variances_from();
        let tol = 1e-10 / (1.0 - mdp.gamma).powi(2);
        for s in 0..ns {
            let next: f64 = (0..ns).map(|s2| ev.p_pi[s * ns + s2] * var[s2]).sum();
            let rhs = ev.omega[s] + mdp.gamma * mdp.gamma * next;
            assert_close(var[s], rhs, tol, "variance Bellman");
            assert!(ev.omega[s] >= -tol, "ω(s) = {} < 0", ev.omega[s]);
        }
    }
}
