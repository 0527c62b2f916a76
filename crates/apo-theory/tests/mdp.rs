//! Construction and validation of MDPs.

use apo_theory::{Evaluation, Mdp, TabularPolicy, TheoryError};

#[test]
fn random_mdp_is_valid_and_deterministic_in_the_seed() {
    let a = Mdp::random(5, 3, 0.9, 7);
    let b = Mdp::random(5, 3, 0.9, 7);
    let c = Mdp::random(5, 3, 0.9, 8);
    a.validate().unwrap();
    c.validate().unwrap();
    assert_eq!(a, b);
    assert_ne!(a.transition, c.transition);
    assert_ne!(a.reward, c.reward);
    assert_eq!(a.transition.len(), 5 * 3 * 5);
    assert!(a.reward.iter().all(|r| (-1.0..1.0).contains(r)));
    assert!(a.start.iter().all(|&p| p > 0.0));
    // Index layout (s * A + a) * S + s'.
    assert_eq!(a.index(2, 1, 4), (2 * 3 + 1) * 5 + 4);
    assert_eq!(a.transition_row(2, 1)[4], a.p(2, 1, 4));
    assert_eq!(a.reward_row(2, 1)[4], a.r(2, 1, 4));
}

#[test]
fn hand_made_mdps_are_valid() {
    for gamma in [0.0, 0.5, 0.99] {
        Mdp::single_state(1.5, gamma).validate().unwrap();
        Mdp::two_state_cycle(1.0, -2.0, gamma).validate().unwrap();
        let m = Mdp::safe_or_risky(gamma);
        m.validate().unwrap();
        assert_eq!((m.states, m.actions), (3, 2));
        for len in [1, 3] {
            let m = Mdp::chain_gamble(len, gamma);
            m.validate().unwrap();
            assert_eq!((m.states, m.actions), (2 * (len + 1), 2));
        }
    }
}

fn assert_err(mdp: &Mdp, culprit: &str) -> TheoryError {
    let err = mdp.validate().expect_err("validate should fail");
    let msg = err.to_string();
    assert!(
        msg.contains(culprit),
        "error {msg:?} does not name {culprit:?}"
    );
    err
}

#[test]
fn validate_rejects_bad_mdps_and_names_the_culprit() {
    let good = Mdp::random(3, 2, 0.9, 1);

    // A transition row that does not sum to 1.
    let mut m = good.clone();
    let k = m.index(1, 1, 2);
    m.transition[k] += 1e-6;
    let err = assert_err(&m, "P(.|s=1, a=1)");
    assert!(matches!(err, TheoryError::NotNormalized { .. }));

    // Within the tolerance is fine.
    let mut m = good.clone();
    m.transition[k] += 1e-12;
    m.validate().unwrap();

    // A negative probability (row still sums to 1).
    let mut m = good.clone();
    let (k0, k1) = (m.index(2, 0, 0), m.index(2, 0, 1));
    m.transition[k1] += m.transition[k0] + 0.3;
    m.transition[k0] = -0.3;
    let err = assert_err(&m, "P(s'=0 | s=2, a=0)");
    assert!(matches!(err, TheoryError::NegativeProbability { .. }));

    // Discount outside [0, 1).
    for gamma in [1.0, -0.1, f64::NAN] {
        let m = Mdp {
            gamma,
            ..good.clone()
        };
        assert!(matches!(m.validate(), Err(TheoryError::InvalidGamma(_))));
    }

    // Wrong table length.
    let mut m = good.clone();
    m.reward.pop();
    let err = assert_err(&m, "reward");
    assert_eq!(
        err,
        TheoryError::LengthMismatch {
            what: "reward",
            expected: 18,
            got: 17
        }
    );

    // Non-finite reward.
    let mut m = good.clone();
    let k = m.index(0, 1, 2);
    m.reward[k] = f64::NAN;
    let err = assert_err(&m, "r(s=0, a=1, s'=2)");
    assert!(matches!(err, TheoryError::NonFinite { .. }));

    // Start distribution not normalized.
    let mut m = good.clone();
    m.start[0] *= 0.5;
    let err = assert_err(&m, "start distribution");
    assert!(matches!(err, TheoryError::NotNormalized { .. }));
    assert!(good.with_start(vec![0.5, 0.5, 0.5]).is_err());

    // Empty spaces.
    let m = Mdp {
        states: 0,
        ..good.clone()
    };
    assert_eq!(
        m.validate(),
        Err(TheoryError::EmptySpace { what: "states" })
    );

    // Mdp::new validates.
    assert!(Mdp::new(1, 1, vec![0.5], vec![0.0], vec![1.0], 0.9).is_err());
    assert!(Mdp::new(1, 1, vec![1.0], vec![0.0], vec![1.0], 0.9).is_ok());
}

#[test]
fn evaluation_rejects_invalid_inputs() {
    let mdp = Mdp::random(3, 2, 0.9, 1);
    let wrong_shape = TabularPolicy::uniform(3, 3);
    assert!(matches!(
        Evaluation::new(&mdp, &wrong_shape),
        Err(TheoryError::ShapeMismatch { .. })
    ));
    let mut bad_policy = TabularPolicy::uniform(3, 2);
    bad_policy.probs[5] = 0.7;
    let err = Evaluation::new(&mdp, &bad_policy).unwrap_err();
    assert!(err.to_string().contains("π(.|s=2)"), "{err}");
    let bad_mdp = Mdp {
        gamma: 1.0,
        ..mdp.clone()
    };
    assert_eq!(
        Evaluation::new(&bad_mdp, &TabularPolicy::uniform(3, 2)),
        Err(TheoryError::InvalidGamma(1.0))
    );
}
