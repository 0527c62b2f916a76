//! The rollout buffer: one-step advantages, GAE and rewards-to-go for each way a path
//! ends, against hand-computed trajectories; normalization; several paths in one batch.

use crate::common;

use apo_core::buffer::{normalize, BufferLayout, RolloutBuffer};
use apo_core::distribution::DistParams;
use apo_core::policy::ActionKind;
use apo_core::tensor_batch::TensorBatch;
use common::*;

const LAYOUT: BufferLayout = BufferLayout {
    observation_dim: 2,
    action_width: 1,
    dist_width: 2,
};

/// Stores a path of `(reward, value)` steps; the observation is `(path, t)` so rows can
/// be traced.
fn store_path(buf: &mut RolloutBuffer, path: f32, steps: &[(f32, f32)]) {
    for (t, &(r, v)) in steps.iter().enumerate() {
        buf.store(
            &[path, t as f32],
            &[t as f32 * 0.1],
            -(t as f32),
            &[path, -path],
            v,
            r,
        );
    }
}

fn f64s(v: &[f32]) -> Vec<f64> {
    v.iter().map(|&x| f64::from(x)).collect()
}

fn normalized(x: &[f64]) -> Vec<f64> {
    let m = mean(x);
    let sd = (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
    x.iter().map(|v| (v - m) / sd).collect()
}

/// γ = 0.5, λ = 0.5 (γλ = 0.25); every number below is exact in binary.
///
/// Path A, terminated (bootstrap 0): r = (1, 2, 3), V = (0.5, 1, 1.5)
///   delta = (1 + 0.5·1 − 0.5, 2 + 0.5·1.5 − 1, 3 + 0 − 1.5) = (1, 1.75, 1.5)
///   adv   = (1 + 0.25·2.125, 1.75 + 0.25·1.5, 1.5) = (1.53125, 2.125, 1.5)
///   ret   = (1 + 0.5·3.5, 2 + 0.5·3, 3) = (2.75, 3.5, 3)
/// Path B, truncated by the time limit (bootstrap V(s_T) = 2): r = (0, −1, 1, 0.5), V = (1, 0, −0.5, 2)
///   delta = (0 + 0 − 1, −1 + 0.5·(−0.5) − 0, 1 + 0.5·2 + 0.5, 0.5 + 0.5·2 − 2) = (−1, −1.25, 2.5, −0.5)
///   adv   = (−1 + 0.25·(−0.65625), −1.25 + 0.25·2.375, 2.5 + 0.25·(−0.5), −0.5)
///         = (−1.1640625, −0.65625, 2.375, −0.5)
///   ret   = (0.5·(−0.125), −1 + 0.5·1.75, 1 + 0.5·1.5, 0.5 + 0.5·2) = (−0.0625, −0.125, 1.75, 1.5)
/// Path C, cut by the end of the epoch (bootstrap V(s_T) = −1): r = (2, −2, 1), V = (1, 0.5, 0)
///   delta = (2 + 0.25 − 1, −2 + 0 − 0.5, 1 − 0.5 − 0) = (1.25, −2.5, 0.5)
///   adv   = (1.25 + 0.25·(−2.375), −2.5 + 0.25·0.5, 0.5) = (0.65625, −2.375, 0.5)
///   ret   = (2 + 0.5·(−1.75), −2 + 0.5·0.5, 1 − 0.5) = (1.125, −1.75, 0.5)
const A: [(f32, f32); 3] = [(1.0, 0.5), (2.0, 1.0), (3.0, 1.5)];
const B: [(f32, f32); 4] = [(0.0, 1.0), (-1.0, 0.0), (1.0, -0.5), (0.5, 2.0)];
const C: [(f32, f32); 3] = [(2.0, 1.0), (-2.0, 0.5), (1.0, 0.0)];
const A_DELTA: [f64; 3] = [1.0, 1.75, 1.5];
const A_ADV: [f64; 3] = [1.53125, 2.125, 1.5];
const A_RET: [f64; 3] = [2.75, 3.5, 3.0];
const B_DELTA: [f64; 4] = [-1.0, -1.25, 2.5, -0.5];
const B_ADV: [f64; 4] = [-1.1640625, -0.65625, 2.375, -0.5];
const B_RET: [f64; 4] = [-0.0625, -0.125, 1.75, 1.5];
const C_DELTA: [f64; 3] = [1.25, -2.5, 0.5];
const C_ADV: [f64; 3] = [0.65625, -2.375, 0.5];
const C_RET: [f64; 3] = [1.125, -1.75, 0.5];

fn single_path(steps: &[(f32, f32)], last_value: f32) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut buf = RolloutBuffer::new(LAYOUT, 0.5, 0.5, 8);
    store_path(&mut buf, 0.0, steps);
    buf.finish_path(last_value);
    let b = buf.take();
    (f64s(&b.delta), f64s(&b.adv), f64s(&b.ret))
}

fn assert_exact(what: &str, got: &[f64], expected: &[f64]) {
    assert_eq!(got.len(), expected.len(), "{what}: length");
    for (i, (g, e)) in got.iter().zip(expected).enumerate() {
        assert_close(&format!("{what}[{i}]"), *g, *e, 1e-6, 1.0);
    }
}

#[test]
fn terminated_path_bootstraps_zero() {
    let (delta, adv, ret) = single_path(&A, 0.0);
    assert_exact("A delta", &delta, &A_DELTA);
    assert_exact("A ret", &ret, &A_RET);
    assert_exact("A adv (normalized)", &adv, &normalized(&A_ADV));
}

#[test]
fn truncated_path_bootstraps_the_last_value() {
    let (delta, adv, ret) = single_path(&B, 2.0);
    assert_exact("B delta", &delta, &B_DELTA);
    assert_exact("B ret", &ret, &B_RET);
    assert_exact("B adv (normalized)", &adv, &normalized(&B_ADV));
}

#[test]
fn path_cut_by_the_epoch_bootstraps_the_last_value() {
    let (delta, adv, ret) = single_path(&C, -1.0);
    assert_exact("C delta", &delta, &C_DELTA);
    assert_exact("C ret", &ret, &C_RET);
    assert_exact("C adv (normalized)", &adv, &normalized(&C_ADV));
}

#[test]
fn several_paths_in_one_batch_are_independent_and_normalized_together() {
    let mut buf = RolloutBuffer::new(LAYOUT, 0.5, 0.5, 4);
    store_path(&mut buf, 0.0, &A);
    buf.finish_path(0.0);
    store_path(&mut buf, 1.0, &B);
    buf.finish_path(2.0);
    store_path(&mut buf, 2.0, &C);
    buf.finish_path(-1.0);
    assert_eq!(buf.len(), 10);
    let batch = buf.take();
    assert!(buf.is_empty(), "take() empties the buffer");
    assert_eq!(batch.len, 10);

    let cat = |a: &[f64], b: &[f64], c: &[f64]| [a, b, c].concat();
    assert_exact(
        "delta",
        &f64s(&batch.delta),
        &cat(&A_DELTA, &B_DELTA, &C_DELTA),
    );
    assert_exact("ret", &f64s(&batch.ret), &cat(&A_RET, &B_RET, &C_RET));
    // normalization is over the whole batch, not per path
    let raw = cat(&A_ADV, &B_ADV, &C_ADV);
    assert_exact("adv", &f64s(&batch.adv), &normalized(&raw));
    let adv = f64s(&batch.adv);
    assert_close("mean(adv)", mean(&adv), 0.0, 1e-6, 1.0);
    assert_close(
        "std(adv)",
        (adv.iter().map(|a| a * a).sum::<f64>() / 10.0).sqrt(),
        1.0,
        1e-6,
        1.0,
    );

    // the stored per-step fields, in order
    let obs: Vec<(f32, f32)> = batch.obs.chunks(2).map(|o| (o[0], o[1])).collect();
    assert_eq!(obs[0], (0.0, 0.0));
    assert_eq!(obs[3], (1.0, 0.0));
    assert_eq!(obs[9], (2.0, 2.0));
    let values: Vec<f32> = A.iter().chain(&B).chain(&C).map(|s| s.1).collect();
    assert_eq!(batch.value, values);
    assert_eq!(batch.logp[4], -1.0);
    assert_eq!(&batch.dist[6..8], &[1.0, -1.0]);
    assert_eq!(batch.actions.len(), 10);

    // the buffer is reusable after take()
    store_path(&mut buf, 0.0, &A);
    buf.finish_path(0.0);
    let again = buf.take();
    assert_exact("A delta again", &f64s(&again.delta), &A_DELTA);
}

/// One buffer per environment of a vector: `take_all` concatenates them in order and
/// normalizes the advantages over all of them.
#[test]
fn take_all_joins_the_buffers_of_several_environments() {
    let mut bufs = vec![
        RolloutBuffer::new(LAYOUT, 0.5, 0.5, 4),
        RolloutBuffer::new(LAYOUT, 0.5, 0.5, 4),
    ];
    store_path(&mut bufs[0], 0.0, &A);
    bufs[0].finish_path(0.0);
    store_path(&mut bufs[1], 1.0, &B);
    bufs[1].finish_path(2.0);
    store_path(&mut bufs[0], 2.0, &C);
    bufs[0].finish_path(-1.0);
    let batch = RolloutBuffer::take_all(&mut bufs);
    assert!(bufs.iter().all(|b| b.is_empty()));
    let cat = |a: &[f64], b: &[f64], c: &[f64]| [a, c, b].concat(); // buffer 0 (A, C), then buffer 1 (B)
    assert_exact(
        "delta",
        &f64s(&batch.delta),
        &cat(&A_DELTA, &B_DELTA, &C_DELTA),
    );
    assert_exact("ret", &f64s(&batch.ret), &cat(&A_RET, &B_RET, &C_RET));
    assert_exact(
        "adv",
        &f64s(&batch.adv),
        &normalized(&cat(&A_ADV, &B_ADV, &C_ADV)),
    );
    assert_eq!(batch.obs[2 * 3], 2.0, "row 3 is the first step of C");
}

/// γ = 0.99, λ = 0.97 on a longer random path, against the *sum* definitions
/// (not the backward recursion the buffer uses):
/// `adv_t = Σ_l (γλ)^l delta_{t+l}`, `ret_t = Σ_l γ^l r_{t+l} + γ^{T−t} V(s_T)`;
/// and the identities GAE(λ = 0) = delta, GAE(λ = 1) = ret − V.
#[test]
fn gae_and_returns_match_their_sum_definitions() {
    let mut rng = Rng::new(9);
    let steps: Vec<(f32, f32)> = (0..25)
        .map(|_| (rng.normal() as f32, rng.normal() as f32))
        .collect();
    let last = 0.75f32;
    let (g, l) = (0.99f64, 0.97f64);
    let r: Vec<f64> = steps.iter().map(|s| f64::from(s.0)).collect();
    let v: Vec<f64> = steps
        .iter()
        .map(|s| f64::from(s.1))
        .chain([f64::from(last)])
        .collect();
    let t_len = r.len();
    let delta: Vec<f64> = (0..t_len).map(|t| r[t] + g * v[t + 1] - v[t]).collect();
    let adv: Vec<f64> = (0..t_len)
        .map(|t| {
            (t..t_len)
                .map(|k| (g * l).powi((k - t) as i32) * delta[k])
                .sum()
        })
        .collect();
    let ret: Vec<f64> = (0..t_len)
        .map(|t| {
            (t..t_len)
                .map(|k| g.powi((k - t) as i32) * r[k])
                .sum::<f64>()
                + g.powi((t_len - t) as i32) * v[t_len]
        })
        .collect();

    for lambda in [l, 0.0, 1.0] {
        let mut buf = RolloutBuffer::new(LAYOUT, g, lambda, 25);
        store_path(&mut buf, 0.0, &steps);
        buf.finish_path(last);
        let b = buf.take();
        let expected_adv: Vec<f64> = if lambda == 0.0 {
            delta.clone()
        } else if lambda == 1.0 {
            (0..t_len).map(|t| ret[t] - v[t]).collect()
        } else {
            adv.clone()
        };
        assert_vec_rel(&format!("λ {lambda}: delta"), &f64s(&b.delta), &delta, 1e-6);
        assert_vec_rel(&format!("λ {lambda}: ret"), &f64s(&b.ret), &ret, 1e-6);
        assert_vec_rel(
            &format!("λ {lambda}: adv"),
            &f64s(&b.adv),
            &normalized(&expected_adv),
            1e-5,
        );
    }
}

#[test]
fn normalize_gives_mean_zero_std_one_and_zeros_for_a_constant() {
    let mut x = vec![1.0f32, 2.0, 3.0, 4.0, 10.0];
    normalize(&mut x);
    let xs = f64s(&x);
    assert_exact("normalized", &xs, &normalized(&[1.0, 2.0, 3.0, 4.0, 10.0]));
    let mut c = vec![3.5f32; 4];
    normalize(&mut c);
    assert_eq!(c, vec![0.0; 4]);
    let mut empty: Vec<f32> = vec![];
    normalize(&mut empty);
}

#[test]
#[should_panic(expected = "unfinished path")]
fn take_with_an_unfinished_path_panics() {
    let mut buf = RolloutBuffer::new(LAYOUT, 0.99, 0.97, 4);
    store_path(&mut buf, 0.0, &A);
    let _ = buf.take();
}

#[test]
#[should_panic(expected = "observation width")]
fn store_checks_widths() {
    let mut buf = RolloutBuffer::new(LAYOUT, 0.99, 0.97, 4);
    buf.store(&[1.0], &[0.0], 0.0, &[0.0, 0.0], 0.0, 0.0);
}

/// A batch on a device: Gaussian distribution rows are `[means…, log-stds…]`, categorical
/// rows are logits.
#[test]
fn tensor_batch_reads_the_stored_distributions() {
    let device = ndarray_f64();
    let layout = BufferLayout {
        observation_dim: 1,
        action_width: 2,
        dist_width: 4,
    };
    let mut buf = RolloutBuffer::new(layout, 0.9, 0.9, 2);
    buf.store(
        &[0.0],
        &[0.1, 0.2],
        -1.0,
        &[1.0, 2.0, -0.5, -0.25],
        0.0,
        1.0,
    );
    buf.store(
        &[1.0],
        &[0.3, 0.4],
        -2.0,
        &[3.0, 4.0, -1.5, -1.25],
        0.0,
        1.0,
    );
    buf.finish_path(0.0);
    let batch = buf.take();
    let tb = TensorBatch::<F64>::new(&batch, ActionKind::Continuous { dim: 2 }, &device);
    // the host batch is f32; on a float64 backend the tensors must be float64
    assert_eq!(tb.obs.dtype(), burn::tensor::DType::F64);
    assert_eq!(tb.adv.dtype(), burn::tensor::DType::F64);
    let DistParams::Gaussian { mean, log_std } = &tb.dist_old else {
        panic!("family")
    };
    assert_eq!(host(mean.clone()), vec![1.0, 2.0, 3.0, 4.0]);
    assert_eq!(host(log_std.clone()), vec![-0.5, -0.25, -1.5, -1.25]);
    assert_eq!(host(tb.logp_old.clone()), vec![-1.0, -2.0]);
    let tb = TensorBatch::<F64>::new(&batch, ActionKind::Discrete { n: 4 }, &device);
    let DistParams::Categorical { logits } = &tb.dist_old else {
        panic!("family")
    };
    assert_eq!(logits.dims(), [2, 4]);
    // and the minibatch selection keeps rows together
    let sel = tb.select(&[1]);
    assert_eq!(host(sel.obs), vec![1.0]);
    assert_eq!(host(sel.logp_old), vec![-2.0]);
}
