//! The practical APO objective evaluated exactly (`apo_theory::practical`): its terms at `π_j`
//! against the algebra, the scale-free variant's invariance to the reward scale, the switch
//! rules, and the trust-region step's promises (KL inside δ, the acceptance rule kept).

use apo_theory::checks::Problems;
use apo_theory::practical::{terms, update, Acceptance, Anchor, Switch, Units, Variant};
use apo_theory::{Mdp, TabularPolicy};

const PROBLEMS: Problems = Problems {
    states: 4,
    actions: 3,
    gamma: 0.95,
    temperature: 1.0,
};

fn close(what: &str, a: f64, e: f64, tol: f64) {
    assert!(
        (a - e).abs() <= tol * (1.0 + e.abs()),
        "{what}: got {a:.12e}, expected {e:.12e}"
    );
}

fn shifted(mdp: &Mdp, offset: f64, scale: f64) -> Mdp {
    let mut m = mdp.clone();
    m.reward.iter_mut().for_each(|r| *r = scale * (*r + offset));
    m
}

#[test]
fn at_pi_j_the_terms_take_their_algebra_values() {
    for seed in 0..10 {
        let (mdp, logits) = PROBLEMS.draw(seed);
        let mdp = shifted(&mdp, 0.5, 1.0);
        let pi_j = TabularPolicy::from_logits(4, 3, &logits);
        let anchor = Anchor::new(&mdp, &pi_j).expect("evaluates");
        let ev = anchor.evaluation();
        let v = Variant::paper(7.0);
        let t = terms(&mdp, &v, &anchor, &pi_j);
        // ratio 1: mean_surr = E[adv] = 0, KL 0, mv = ω1 E|2 delta ω2|, the switch on iff E[V] ≥ 0
        close("mean_surr", t.mean_surr, 0.0, 1e-12);
        close("KL", t.mean_kl, 0.0, 1e-15);
        let (mut mv, mut mean_v) = (0.0, 0.0);
        for s in 0..4 {
            mean_v += ev.d[s] * ev.v[s];
            for a in 0..3 {
                for s2 in 0..4 {
                    mv += ev.d[s]
                        * pi_j.prob(s, a)
                        * mdp.p(s, a, s2)
                        * (2.0 * ev.a3(s, a, s2) * 0.005).abs();
                }
            }
        }
        close("mv", t.mean_variance, 0.005 * mv, 1e-12);
        assert_eq!(t.switch_on, mean_v >= 0.0, "seed {seed}");
    }
}

#[test]
fn advantage_units_do_not_see_the_reward_scale_and_reward_units_do() {
    let (mdp, logits) = PROBLEMS.draw(3);
    let base = shifted(&mdp, 0.3, 1.0);
    let big = shifted(&mdp, 0.3, 250.0);
    let pi_j = TabularPolicy::from_logits(4, 3, &logits);
    let moved: Vec<f64> = logits
        .iter()
        .enumerate()
        .map(|(i, l)| l + 0.05 * ((i % 3) as f64 - 1.0))
        .collect();
    let pi = TabularPolicy::from_logits(4, 3, &moved);
    let at = |m: &Mdp, units| {
        let v = Variant {
            units,
            switch: Switch::Off,
            ..Variant::paper(7.0)
        };
        terms(m, &v, &Anchor::new(m, &pi_j).expect("evaluates"), &pi).objective
    };
    close(
        "advantage units, rewards × 250",
        at(&big, Units::Advantage),
        at(&base, Units::Advantage),
        1e-9,
    );
    let (a, b) = (at(&base, Units::Reward), at(&big, Units::Reward));
    assert!(
        (a - b).abs() > 1e-2 * a.abs().max(1e-6),
        "reward units {a} vs {b}"
    );
}

#[test]
fn the_switch_rules_hold_off_and_decide_as_documented() {
    let (mdp, logits) = PROBLEMS.draw(5);
    // positive values: the paper's switch is on at π_j and turns off far from it
    let mdp = shifted(&mdp, 1.0, 1.0);
    let pi_j = TabularPolicy::from_logits(4, 3, &logits);
    let anchor = Anchor::new(&mdp, &pi_j).expect("evaluates");
    let far: Vec<f64> = logits
        .iter()
        .enumerate()
        .map(|(i, l)| l + if i % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let pi = TabularPolicy::from_logits(4, 3, &far);
    let with = |switch| {
        terms(
            &mdp,
            &Variant {
                switch,
                ..Variant::paper(7.0)
            },
            &anchor,
            &pi,
        )
    };
    let (paper, held, off) = (with(Switch::Paper), with(Switch::Held), with(Switch::Off));
    assert!(
        !paper.switch_on,
        "the bias at this distance turns the paper's switch off"
    );
    assert!(held.switch_on && !off.switch_on);
    // off and the paper's switched-off state are the same objective
    close("off = paper off", off.objective, paper.objective, 1e-12);
    // held adds k · (ms² + 2 E[V] ms)
    let mean_v: f64 = (0..4)
        .map(|s| anchor.evaluation().d[s] * anchor.evaluation().v[s])
        .sum();
    let ms = held.mean_surr;
    close(
        "held = off + k min_J_sq",
        held.objective,
        off.objective + 7.0 * (ms * ms + 2.0 * mean_v * ms),
        1e-12,
    );
}

#[test]
fn every_update_keeps_its_kl_and_its_acceptance_rule() {
    for seed in 0..15 {
        let (mdp, mut logits) = PROBLEMS.draw(seed);
        let mdp = shifted(&mdp, 0.5, 1.0);
        for acceptance in [Acceptance::Improvement, Acceptance::Ratio(0.1)] {
            for (units, switch) in [
                (Units::Reward, Switch::Paper),
                (Units::Advantage, Switch::Off),
                (Units::Reward, Switch::Held),
            ] {
                let v = Variant {
                    units,
                    switch,
                    acceptance,
                    ..Variant::paper(7.0)
                };
                let before = logits.clone();
                let u = update(&mdp, &v, &mut logits).expect("updates");
                assert!(u.kl <= v.max_kl, "seed {seed}: KL {} > δ", u.kl);
                match u.accepted {
                    Some(_) => {
                        assert!(u.objective_gain >= 0.0);
                        if acceptance != Acceptance::Improvement {
                            assert!(u.objective_gain > 0.0);
                        }
                    }
                    None => assert_eq!(logits, before, "seed {seed}: rejected but moved"),
                }
            }
        }
    }
}

#[test]
fn trpo_with_k_zero_raises_j_inside_the_trust_region() {
    let (mut accepted, mut raised) = (0, 0);
    for seed in 0..20 {
        let (mdp, mut logits) = PROBLEMS.draw(seed);
        let u = update(&mdp, &Variant::paper(0.0), &mut logits).expect("updates");
        assert!(u.kl <= 0.02, "seed {seed}: KL {}", u.kl);
        accepted += usize::from(u.accepted.is_some());
        // the improvement of J is what TRPO's surrogate promises for a small step
        raised += usize::from(u.j_gain > 0.0);
    }
    assert_eq!(accepted, 20, "accepted updates");
    assert!(raised >= 18, "J raised in {raised} of 20 updates");
}
