//! Wrappers and running statistics.

mod common;

use apo_envs::classic::{CartPole, Pendulum};
use apo_envs::{
    Action, Env, EnvError, NormalizeObservation, RescaleAction, RunningMeanStd, Space, TimeLimit,
};
use common::{close, Counter};

// ---------------------------------------------------------------- TimeLimit

#[test]
fn time_limit_truncates_at_the_limit_and_restarts_on_reset() {
    let mut env = TimeLimit::new(Counter::new(Space::uniform_box(1, -1.0, 1.0), None), 3);
    let mut obs = [0.0f32; 3];
    for _episode in 0..2 {
        env.reset(None, &mut obs);
        assert_eq!(env.elapsed_steps(), 0);
        for k in 1..=3 {
            let t = env.step(Action::Continuous(&[0.0]), &mut obs);
            assert_eq!(env.elapsed_steps(), k);
            assert!(!t.terminated);
            assert_eq!(t.truncated, k == 3, "step {k}");
        }
    }
    assert_eq!(env.max_episode_steps(), 3);
}

#[test]
fn time_limit_does_not_truncate_a_terminating_step() {
    let mut obs = [0.0f32; 3];
    // Terminates exactly on the last allowed step: terminated only.
    let mut env = TimeLimit::new(Counter::new(Space::uniform_box(1, -1.0, 1.0), Some(3)), 3);
    env.reset(None, &mut obs);
    env.step(Action::Continuous(&[0.0]), &mut obs);
    env.step(Action::Continuous(&[0.0]), &mut obs);
    let t = env.step(Action::Continuous(&[0.0]), &mut obs);
    assert!(t.terminated && !t.truncated);
    // Terminates before the limit: terminated only.
    let mut env = TimeLimit::new(Counter::new(Space::uniform_box(1, -1.0, 1.0), Some(2)), 5);
    env.reset(None, &mut obs);
    assert!(!env.step(Action::Continuous(&[0.0]), &mut obs).done());
    let t = env.step(Action::Continuous(&[0.0]), &mut obs);
    assert!(t.terminated && !t.truncated);
}

#[test]
fn time_limit_on_a_real_env() {
    let mut env = TimeLimit::new(Pendulum::new(), 200);
    let mut obs = [0.0f32; 3];
    env.reset(Some(0), &mut obs);
    let mut steps = 0;
    loop {
        steps += 1;
        let t = env.step(Action::Continuous(&[0.0]), &mut obs);
        if t.done() {
            assert!(t.truncated && !t.terminated);
            break;
        }
    }
    assert_eq!(steps, 200);
}

// ---------------------------------------------------------------- RescaleAction

#[test]
fn rescale_action_maps_linearly_and_clips() {
    let inner = Counter::new(
        Space::Box {
            low: vec![-2.0, 0.0, 10.0],
            high: vec![2.0, 1.0, 30.0],
            shape: vec![3],
        },
        None,
    );
    let mut env = RescaleAction::new(inner).expect("box with finite bounds");
    assert_eq!(env.action_space(), &Space::uniform_box(3, -1.0, 1.0));
    // low + (a + 1) / 2 · (high − low), per dimension.
    let cases: [([f32; 3], [f32; 3]); 5] = [
        ([-1.0, -1.0, -1.0], [-2.0, 0.0, 10.0]),
        ([1.0, 1.0, 1.0], [2.0, 1.0, 30.0]),
        ([0.0, 0.0, 0.0], [0.0, 0.5, 20.0]),
        ([0.5, -0.5, 0.25], [1.0, 0.25, 22.5]),
        // Outside [-1, 1]: clipped to the bounds.
        ([3.0, -7.0, 1.5], [2.0, 0.0, 30.0]),
    ];
    let mut out = [0.0f32; 3];
    for (a, expected) in cases {
        env.rescale(&a, &mut out);
        assert_eq!(out, expected, "rescale({a:?})");
    }
    // step passes the mapped action to the wrapped environment.
    let mut obs = [0.0f32; 3];
    env.reset(None, &mut obs);
    env.step(Action::Continuous(&[0.5, -0.5, 0.25]), &mut obs);
    assert_eq!(obs[2], 1.0, "the wrapped env saw 1.0 in dimension 0");
}

#[test]
fn rescale_action_drives_pendulum_with_full_torque() {
    // a = 1 → torque 2 (the bound); compare with the bare env given 2 directly.
    let mut wrapped = RescaleAction::new(Pendulum::new()).expect("box");
    let mut bare = Pendulum::new();
    let (mut o1, mut o2) = ([0.0f32; 3], [0.0f32; 3]);
    wrapped.reset(Some(5), &mut o1);
    bare.reset(Some(5), &mut o2);
    for a in [1.0f32, -1.0, 0.5] {
        let t1 = wrapped.step(Action::Continuous(&[a]), &mut o1);
        let t2 = bare.step(Action::Continuous(&[2.0 * a]), &mut o2);
        assert_eq!((o1, t1), (o2, t2));
    }
}

#[test]
fn rescale_action_rejects_discrete_and_unbounded_spaces() {
    let err = RescaleAction::new(CartPole::new()).expect_err("discrete");
    assert!(
        matches!(
            err,
            EnvError::UnsupportedSpace {
                wrapper: "RescaleAction",
                ..
            }
        ),
        "{err}"
    );
    let unbounded = Counter::new(
        Space::uniform_box(2, f32::NEG_INFINITY, f32::INFINITY),
        None,
    );
    assert!(RescaleAction::new(unbounded).is_err());
}

// ---------------------------------------------------------------- RunningMeanStd

/// A deterministic batch `[n, dim]` with distinct scales per dimension.
fn batch(n: usize, dim: usize, shift: f32) -> Vec<f32> {
    (0..n * dim)
        .map(|k| {
            let (i, d) = (k / dim, k % dim);
            ((i as f32 * 0.73 + d as f32).sin() * (d as f32 + 1.0) * 3.0) + shift + d as f32 * 10.0
        })
        .collect()
}

/// Two-pass mean and population variance of column `d`.
fn two_pass(batch: &[f32], dim: usize, d: usize) -> (f64, f64) {
    let column: Vec<f64> = batch
        .iter()
        .skip(d)
        .step_by(dim)
        .map(|x| f64::from(*x))
        .collect();
    let n = column.len() as f64;
    let mean = column.iter().sum::<f64>() / n;
    let var = column.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    (mean, var)
}

#[test]
fn running_mean_std_matches_two_pass_statistics() {
    let (n, dim) = (257, 4);
    let data = batch(n, dim, 1.5);
    let mut rms = RunningMeanStd::new(dim);
    assert_eq!(
        (rms.count(), rms.mean(), rms.var()),
        (0.0, &[0.0; 4][..], &[1.0; 4][..])
    );
    rms.update(&data, n);
    assert_eq!(rms.count(), n as f64);
    for d in 0..dim {
        let (mean, var) = two_pass(&data, dim, d);
        close(rms.mean()[d], mean, 1e-12, &format!("mean[{d}]"));
        close(rms.var()[d], var, 1e-10, &format!("var[{d}]"));
    }
}

#[test]
fn running_mean_std_merging_batches_equals_one_batch() {
    let dim = 3;
    let (a, b) = (batch(100, dim, 0.0), batch(37, dim, 50.0));
    let all: Vec<f32> = a.iter().chain(&b).copied().collect();

    let mut one = RunningMeanStd::new(dim);
    one.update(&all, 137);

    // Two updates in sequence.
    let mut seq = RunningMeanStd::new(dim);
    seq.update(&a, 100);
    seq.update(&b, 37);

    // Statistics of each batch, merged.
    let mut left = RunningMeanStd::new(dim);
    left.update(&a, 100);
    let mut right = RunningMeanStd::new(dim);
    right.update(&b, 37);
    left.merge(&right).expect("same dimension");

    // One row at a time.
    let mut rows = RunningMeanStd::new(dim);
    for row in all.chunks(dim) {
        rows.update(row, 1);
    }

    for other in [&seq, &left, &rows] {
        assert_eq!(other.count(), 137.0);
        for d in 0..dim {
            close(other.mean()[d], one.mean()[d], 1e-10, &format!("mean[{d}]"));
            close(other.var()[d], one.var()[d], 1e-9, &format!("var[{d}]"));
        }
    }
    // The merged variance is not the average of the two (the means differ by 50).
    let (va, vb) = (two_pass(&a, dim, 0).1, two_pass(&b, dim, 0).1);
    assert!(one.var()[0] > va.max(vb) * 10.0);
    assert!(matches!(
        left.merge(&RunningMeanStd::new(2)),
        Err(EnvError::DimensionMismatch {
            expected: 3,
            found: 2
        })
    ));
}

/// The rollout adds one observation per step; that path must be the same arithmetic as
/// merging the statistics of that one vector (its mean is itself, its variance 0), bit for bit,
/// so that a run's normalization does not depend on which path computed it.
#[test]
fn running_mean_std_one_vector_is_the_merge_of_its_own_statistics_exactly() {
    let dim = 5;
    let data = batch(300, dim, -3.0);
    let (mut rows, mut merged) = (RunningMeanStd::new(dim), RunningMeanStd::new(dim));
    for row in data.chunks(dim) {
        rows.update(row, 1);
        let mean = row.iter().map(|x| f64::from(*x)).collect();
        let own = RunningMeanStd::from_moments(mean, vec![0.0; dim], 1.0).expect("same length");
        merged.merge(&own).expect("same dimension");
        assert_eq!(rows, merged);
    }
    assert_eq!(rows.count(), 300.0);
    let (mean, var) = two_pass(&data, dim, 2);
    close(rows.mean()[2], mean, 1e-10, "mean[2]");
    close(rows.var()[2], var, 1e-9, "var[2]");
}

#[test]
fn running_mean_std_normalizes_and_clips_in_place() {
    let mut rms = RunningMeanStd::new(2);
    // Column 0: {1, 3} → mean 2, var 1. Column 1: {10, 10} → mean 10, var 0.
    rms.update(&[1.0, 10.0, 3.0, 10.0], 2);
    let mut x = [4.0f32, 10.0, 2.0, 10.0 + 1e-3, -100.0, 9.0];
    rms.normalize(&mut x);
    let s0 = (1.0f64 + 1e-8).sqrt();
    close(f64::from(x[0]), 2.0 / s0, 1e-6, "x[0]");
    assert_eq!(x[1], 0.0);
    assert_eq!(x[2], 0.0);
    // (1e-3) / sqrt(1e-8) = 10 (clipped at 10), (−1) / 1e-4 = −10000 → −10, −102 / 1 → −10.
    close(f64::from(x[3]), 10.0, 1e-3, "x[3]");
    assert_eq!(x[4], -10.0);
    assert_eq!(x[5], -10.0);
    // Empty statistics (mean 0, var 1) only clip.
    let mut y = [0.5f32, 20.0];
    RunningMeanStd::new(2).normalize(&mut y);
    close(f64::from(y[0]), 0.5, 1e-7, "y[0]");
    assert_eq!(y[1], 10.0);
}

#[test]
fn running_mean_std_serializes() {
    let mut rms = RunningMeanStd::new(3);
    rms.update(&batch(10, 3, 2.0), 10);
    let json = serde_json::to_string(&rms).expect("serialize");
    let back: RunningMeanStd = serde_json::from_str(&json).expect("deserialize");
    assert_eq!(back, rms);
}

// ---------------------------------------------------------------- NormalizeObservation

#[test]
fn normalize_observation_updates_in_training_and_freezes_in_evaluation() {
    let mut env = NormalizeObservation::new(Counter::new(Space::uniform_box(1, -5.0, 5.0), None))
        .expect("box");
    assert_eq!(env.observation_space(), &Space::uniform_box(3, -10.0, 10.0));
    assert!(env.training());
    let mut obs = [0.0f32; 3];
    let mut raw = Vec::new();
    env.reset(None, &mut obs); // raw [0, 0, 0]
    raw.extend([0.0f32, 0.0, 0.0]);
    for a in [1.0f32, -2.0, 4.0] {
        env.step(Action::Continuous(&[a]), &mut obs);
        let t = raw.len() / 3;
        raw.extend([0.0, t as f32, a]);
    }
    // Statistics of every raw observation, the reset one included.
    let mut expected = RunningMeanStd::new(3);
    expected.update(&raw, 4);
    assert_eq!(env.stats().count(), 4.0);
    for d in 0..3 {
        close(env.stats().mean()[d], expected.mean()[d], 1e-12, "mean");
        close(env.stats().var()[d], expected.var()[d], 1e-12, "var");
    }
    // The last observation was normalized with the statistics after its own update.
    let mut last = [0.0f32, 3.0, 4.0];
    expected.normalize(&mut last);
    assert_eq!(obs, last);

    // Frozen: statistics unchanged, observations still normalized.
    env.set_training(false);
    let frozen = env.stats().clone();
    env.step(Action::Continuous(&[2.0]), &mut obs);
    assert_eq!(env.stats(), &frozen);
    let mut expected_obs = [0.0f32, 4.0, 2.0];
    frozen.normalize(&mut expected_obs);
    assert_eq!(obs, expected_obs);

    // Restore from a checkpoint.
    let mut other = NormalizeObservation::new(Counter::new(Space::uniform_box(1, -5.0, 5.0), None))
        .expect("box");
    other.set_stats(frozen.clone()).expect("same dimension");
    assert_eq!(other.stats(), &frozen);
    assert!(matches!(
        other.set_stats(RunningMeanStd::new(4)),
        Err(EnvError::DimensionMismatch {
            expected: 3,
            found: 4
        })
    ));
}
