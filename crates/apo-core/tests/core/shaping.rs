//! Risk shaping (MVPI, CVaR, return capping, tail weighting) against hand computations: the
//! augmented and capped rewards, the α-quantile and the episodes it selects or weights, the
//! cap's update, the advantages computed again from shaped rewards by an independent float64
//! GAE, and the reductions to PPO (λ = 0, α = 1, C = ∞, w = 1), in the batch and in the
//! learner's update.

use crate::common;

use apo_core::algorithm::{
    AlgoConfig, AlgorithmConfig, CvarConfig, MvpiConfig, PpoConfig, TailPpoConfig,
};
use apo_core::buffer::{Batch, BufferLayout, PathEnd, RolloutBuffer};
use apo_core::policy::{ActionKind, MlpPolicyConfig};
use apo_core::proximal::ProximalConfig;
use apo_core::shaping::{
    capped_rewards, episode_returns, lower_quantile, mean_variance_rewards, shape, ShapingError,
    ShapingRule, ShapingState,
};
use apo_core::value::ValueConfig;
use apo_core::{Comm, Learner};
use common::*;
use rand::rngs::StdRng;
use rand::SeedableRng;

const LAYOUT: BufferLayout = BufferLayout {
    observation_dim: 2,
    action_width: 1,
    dist_width: 2,
};
const GAMMA: f64 = 0.5;
const LAMBDA: f64 = 0.5;

/// Path A, terminated: r = (1, 2, 3), V = (0.5, 1, 1.5), return 6.
const A: [(f32, f32); 3] = [(1.0, 0.5), (2.0, 1.0), (3.0, 1.5)];
/// Path B, truncated by the time limit (bootstrap 2): r = (0, −1, 1, 0.5), return 0.5.
const B: [(f32, f32); 4] = [(0.0, 1.0), (-1.0, 0.0), (1.0, -0.5), (0.5, 2.0)];
/// Path C, cut by the end of the epoch (bootstrap −1): r = (2, −2, 1), reached 1.
const C: [(f32, f32); 3] = [(2.0, 1.0), (-2.0, 0.5), (1.0, 0.0)];

/// A path's `(reward, value)` steps, the value it bootstraps from (`None`: terminated) and
/// whether it ends an episode.
type Path = (&'static [(f32, f32)], Option<f32>, bool);

/// The batch of paths A, B and C, in that order, through the rollout's own calls.
fn batch() -> Batch {
    let mut buf = RolloutBuffer::new(LAYOUT, GAMMA, LAMBDA, 10);
    let paths: [Path; 3] = [
        (&A, None, true),
        (&B, Some(2.0), true),
        (&C, Some(-1.0), false),
    ];
    for (p, (steps, bootstrap, episode)) in paths.iter().enumerate() {
        for (t, &(r, _)) in steps.iter().enumerate() {
            buf.store(&[p as f32, t as f32], &[0.1], -1.0, &[0.0, 0.0], 0.0, r);
        }
        // the observation (-1, p) stands for the path's bootstrap state
        let obs = [-1.0, p as f32];
        match (bootstrap, episode) {
            (None, _) => buf.end_path(None),
            (Some(_), true) => buf.end_path(Some(&obs)),
            (Some(_), false) => buf.cut_path(&obs),
        }
    }
    let critic = |obs: &[f32], n: usize, out: &mut Vec<f32>| {
        out.clear();
        for row in obs.chunks(2).take(n) {
            out.push(if row[0] < 0.0 {
                paths[row[1] as usize].1.unwrap_or(0.0)
            } else {
                paths[row[0] as usize].0[row[1] as usize].1
            });
        }
    };
    buf.finish_paths(critic);
    buf.take()
}

/// An independent float64 GAE of one path: (delta, adv, ret).
fn gae(rewards: &[f64], values: &[f64], last: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = rewards.len();
    let mut delta = vec![0.0; n];
    for t in 0..n {
        let next = if t + 1 < n { values[t + 1] } else { last };
        delta[t] = rewards[t] + GAMMA * next - values[t];
    }
    let mut adv = vec![0.0; n];
    let mut ret = vec![0.0; n];
    for t in (0..n).rev() {
        adv[t] = delta[t]
            + if t + 1 < n {
                GAMMA * LAMBDA * adv[t + 1]
            } else {
                0.0
            };
        ret[t] = rewards[t] + GAMMA * if t + 1 < n { ret[t + 1] } else { last };
    }
    (delta, adv, ret)
}

fn normalized(x: &[f64]) -> Vec<f64> {
    let m = mean(x);
    let sd = (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
    x.iter().map(|v| (v - m) / sd).collect()
}

fn f64s(v: &[f32]) -> Vec<f64> {
    v.iter().map(|&x| f64::from(x)).collect()
}

/// `batch`'s delta, adv and ret against the independent GAE of `rewards` over its paths
/// (adv normalized over all rows).
fn check_advantages(what: &str, batch: &Batch, rewards: &[f64]) {
    let (mut delta, mut adv, mut ret) = (Vec::new(), Vec::new(), Vec::new());
    for (start, end, path) in batch.path_ranges() {
        let values = f64s(&batch.value[start..end]);
        let (d, a, r) = gae(&rewards[start..end], &values, f64::from(path.last_value));
        delta.extend(d);
        adv.extend(a);
        ret.extend(r);
    }
    let adv = normalized(&adv);
    for (name, got, want) in [
        ("delta", &batch.delta, &delta),
        ("adv", &batch.adv, &adv),
        ("ret", &batch.ret, &ret),
    ] {
        assert_eq!(got.len(), want.len(), "{what}: {name}");
        for (i, (&g, &w)) in got.iter().zip(want.iter()).enumerate() {
            assert!(
                (f64::from(g) - w).abs() <= 1e-6 * (1.0 + w.abs()),
                "{what}: {name}[{i}] = {g}, want {w}"
            );
        }
    }
}

#[test]
fn the_batch_records_its_rewards_and_paths() {
    let b = batch();
    assert_eq!(f64s(&b.reward), [1., 2., 3., 0., -1., 1., 0.5, 2., -2., 1.]);
    assert_eq!(
        b.paths,
        [
            PathEnd {
                end: 3,
                last_value: 0.0,
                episode: true
            },
            PathEnd {
                end: 7,
                last_value: 2.0,
                episode: true
            },
            PathEnd {
                end: 10,
                last_value: -1.0,
                episode: false
            },
        ]
    );
    // the cut path C is no episode: its return is not counted
    assert_eq!(episode_returns(&b), [6.0, 0.5]);
    // the stored advantages are the independent GAE of the rewards
    check_advantages("as collected", &b, &f64s(&b.reward));
}

#[test]
fn mean_variance_rewards_are_r_minus_lambda_r2_plus_2_lambda_r_y() {
    // λ = 0.5, y = 2: 1 − 0.5 + 2 = 2.5; 2 − 2 + 4 = 4; 3 − 4.5 + 6 = 4.5; −1 − 0.5 − 2 = −3.5
    assert_eq!(
        mean_variance_rewards(&[1.0, 2.0, 3.0, -1.0], 0.5, 2.0),
        [2.5, 4.0, 4.5, -3.5]
    );
    // y is the mean reward of every row: (6 + 0.5 + 1) / 10 = 0.75
    let b = batch();
    let mut state = ShapingState::default();
    let rule = ShapingRule::MeanVariance { lambda: 0.5 };
    let s = shape(&b, rule, &mut state, GAMMA, LAMBDA, &Comm::default()).expect("shapes");
    assert_eq!(s.report.level, 0.75);
    assert_eq!(s.report.kept, 1.0);
    assert!(s.value.is_none(), "the critic fits the augmented returns");
    assert!(state.is_empty());
    let want: Vec<f64> = f64s(&b.reward)
        .iter()
        .map(|r| r - 0.5 * r * r + 2.0 * 0.5 * r * 0.75)
        .collect();
    assert_eq!(f64s(&s.policy.reward), want);
    check_advantages("mvpi", &s.policy, &want);
    // the rows themselves are the batch's
    assert_eq!((&s.policy.obs, &s.policy.logp), (&b.obs, &b.logp));
}

#[test]
fn the_lower_quantile_is_the_ceil_alpha_n_th_smallest() {
    let q = |alpha: f64| lower_quantile(&mut [5.0, 1.0, 3.0, 2.0, 4.0], alpha);
    // 0.07 · 100 is 7.000000000000001 in floating point: still the 7th smallest
    let hundred: Vec<f64> = (1..=100).map(f64::from).collect();
    assert_eq!(lower_quantile(&mut hundred.clone(), 0.07), Some(7.0));
    assert_eq!(lower_quantile(&mut hundred[..30].to_vec(), 0.1), Some(3.0));
    assert_eq!(q(0.4), Some(2.0)); // ⌈2⌉ = 2nd
    assert_eq!(q(0.41), Some(3.0)); // ⌈2.05⌉ = 3rd
    assert_eq!(q(1.0), Some(5.0));
    assert_eq!(q(1e-9), Some(1.0)); // at least the smallest
    assert_eq!(lower_quantile(&mut [], 0.5), None);
}

#[test]
fn cvar_keeps_the_episodes_at_or_below_the_quantile_and_the_critic_every_row() {
    let b = batch();
    let comm = Comm::default();
    // α = 0.5 of the returns (6, 0.5): the 1st smallest, 0.5: episode B only (C is cut)
    let mut state = ShapingState::default();
    let s = shape(
        &b,
        ShapingRule::WorstEpisodes { alpha: 0.5 },
        &mut state,
        GAMMA,
        LAMBDA,
        &comm,
    )
    .expect("shapes");
    assert_eq!(s.report.level, 0.5);
    assert_eq!(s.report.kept, 0.4);
    assert_eq!(s.policy.len, 4);
    assert_eq!(s.policy.obs, b.obs[6..14]);
    assert_eq!(s.policy.logp, b.logp[3..7]);
    assert_eq!(
        s.policy.paths,
        [PathEnd {
            end: 4,
            last_value: 2.0,
            episode: true
        }]
    );
    // B's advantages, normalized over B's rows alone
    check_advantages("cvar", &s.policy, &f64s(&b.reward[3..7]));
    assert_eq!(s.value.as_ref(), Some(&b), "the critic fits every row");
    // a tie at the quantile keeps both episodes: returns (6, 0.5, 0.5)
    let mut tied = b.clone();
    tied.paths[2].episode = true;
    tied.reward[8] = -2.5; // C: 2 − 2.5 + 1 = 0.5
    let s = shape(
        &tied,
        ShapingRule::WorstEpisodes { alpha: 0.5 },
        &mut ShapingState::default(),
        GAMMA,
        LAMBDA,
        &comm,
    )
    .expect("shapes");
    assert_eq!(s.report.level, 0.5);
    assert_eq!(s.policy.len, 7, "B and C");
    // no episode ended: nothing to rank, every row is kept
    let mut cut = b.clone();
    cut.paths.iter_mut().for_each(|p| p.episode = false);
    let s = shape(
        &cut,
        ShapingRule::WorstEpisodes { alpha: 0.5 },
        &mut ShapingState::default(),
        GAMMA,
        LAMBDA,
        &comm,
    )
    .expect("shapes");
    assert!(s.report.level.is_nan());
    assert_eq!(s.policy, cut);
}

#[test]
fn capped_rewards_sum_to_the_capped_return() {
    let paths = |ends: &[usize]| {
        ends.iter()
            .map(|&end| PathEnd {
                end,
                last_value: 0.0,
                episode: true,
            })
            .collect::<Vec<_>>()
    };
    // R = (1, 3, 6), C = 2.5: (1, 2.5 − 1, 2.5 − 2.5) = (1, 1.5, 0); sum 2.5 = min(6, 2.5)
    // then R = (2, 0, 1), C = 2.5: nothing reaches the cap: (2, −2, 1)
    assert_eq!(
        capped_rewards(&[1.0, 2.0, 3.0, 2.0, -2.0, 1.0], &paths(&[3, 6]), 2.5),
        [1.0, 1.5, 0.0, 2.0, -2.0, 1.0]
    );
    // R = (2, 0, 1), C = 1: (1, 0 − 1, 1 − 0) = (1, −1, 1): a return that falls back below
    // the cap earns again what it lost
    assert_eq!(
        capped_rewards(&[2.0, -2.0, 1.0], &paths(&[3]), 1.0),
        [1.0, -1.0, 1.0]
    );
    // C = ∞: the rewards as they are
    let b = batch();
    assert_eq!(capped_rewards(&b.reward, &b.paths, f64::INFINITY), b.reward);
}

#[test]
fn the_capped_return_is_what_the_value_targets_sum_to() {
    // γ = 1, λ = 1, V = 0, terminated: ret_0 is the episode's shaped return, min(R, C)
    let mut buf = RolloutBuffer::new(LAYOUT, 1.0, 1.0, 4);
    for r in [1.0, 2.0, 3.0, -1.0] {
        buf.store(&[0.0, 0.0], &[0.0], 0.0, &[0.0, 0.0], 0.0, r);
    }
    buf.finish_path(0.0);
    let b = buf.take();
    let mut state = ShapingState { cap: Some(2.5) };
    let rule = ShapingRule::ReturnCap {
        alpha: 1.0,
        eta: 0.0,
        min_cap: f64::NEG_INFINITY,
    };
    let s = shape(&b, rule, &mut state, 1.0, 1.0, &Comm::default()).expect("shapes");
    // R = (1, 3, 6, 5): capped (1, 1.5, 0, 0), sum 2.5 = min(5, 2.5)
    assert_eq!(s.policy.reward, [1.0, 1.5, 0.0, 0.0]);
    assert_eq!(s.policy.ret, [2.5, 1.5, 0.0, 0.0]);
    // the steps after the cap is reached have no advantage left: their gradient is 0 but
    // through the critic's values (here 0): delta = 0
    assert_eq!(s.policy.delta[2..], [0.0, 0.0]);
}

#[test]
fn the_cap_starts_at_the_first_quantile_and_moves_by_eta_above_the_minimum() {
    let b = batch(); // episode returns (6, 0.5): VaR_0.5 = 0.5
    let comm = Comm::default();
    let rule = |eta: f64, min_cap: f64| ShapingRule::ReturnCap {
        alpha: 0.5,
        eta,
        min_cap,
    };
    let mut state = ShapingState::default();
    let s = shape(
        &b,
        rule(0.25, f64::NEG_INFINITY),
        &mut state,
        GAMMA,
        LAMBDA,
        &comm,
    )
    .expect("shapes");
    assert_eq!(
        s.report.level, 0.5,
        "the first epoch is shaped with its own VaR"
    );
    assert_eq!(state.cap, Some(0.5));
    let want = capped_rewards(&b.reward, &b.paths, 0.5);
    check_advantages("capped at 0.5", &s.policy, &f64s(&want));
    // C = 2, η = 0.25: shaped with 2, then 2 + 0.25 (0.5 − 2) = 1.625
    let mut state = ShapingState { cap: Some(2.0) };
    let s = shape(
        &b,
        rule(0.25, f64::NEG_INFINITY),
        &mut state,
        GAMMA,
        LAMBDA,
        &comm,
    )
    .expect("shapes");
    assert_eq!(s.report.level, 2.0);
    assert_eq!(state.cap, Some(1.625));
    // ... but never below C_M = 1.8
    let mut state = ShapingState { cap: Some(2.0) };
    shape(&b, rule(0.25, 1.8), &mut state, GAMMA, LAMBDA, &comm).expect("shapes");
    assert_eq!(state.cap, Some(1.8));
    // an epoch with no episode leaves the cap where it was
    let mut cut = b.clone();
    cut.paths.iter_mut().for_each(|p| p.episode = false);
    let mut state = ShapingState { cap: Some(2.0) };
    shape(
        &cut,
        rule(0.25, f64::NEG_INFINITY),
        &mut state,
        GAMMA,
        LAMBDA,
        &comm,
    )
    .expect("shapes");
    assert_eq!(state.cap, Some(2.0));
}

/// Tail weighting keeps every row and multiplies the normalized advantages of the episodes at
/// or below `VaR_α` by `w`: by hand, with α = 0.5 of the returns (6, 0.5), episode B's four
/// rows (3..7) get `w·A`, A's and the cut path C's rows keep PPO's advantage; and the clipped
/// surrogate of a weighted row is `w` times PPO's.
#[test]
fn tail_weighting_multiplies_the_advantages_of_the_episodes_at_or_below_the_quantile() {
    let b = batch();
    let comm = Comm::default();
    let s = shape(
        &b,
        ShapingRule::TailWeight {
            alpha: 0.5,
            weight: 4.0,
        },
        &mut ShapingState::default(),
        GAMMA,
        LAMBDA,
        &comm,
    )
    .expect("shapes");
    assert_eq!(s.report.level, 0.5);
    assert_eq!(s.report.kept, 1.0);
    assert!(s.value.is_none(), "the critic fits the batch as collected");
    let want: Vec<f32> = b
        .adv
        .iter()
        .enumerate()
        .map(|(i, &a)| if (3..7).contains(&i) { 4.0 * a } else { a })
        .collect();
    assert_eq!(s.policy.adv, want);
    assert_eq!(
        Batch {
            adv: b.adv.clone(),
            ..s.policy.clone()
        },
        b,
        "only adv changes"
    );
    // PPO's clipped surrogate min(ρA, clip(ρ, 1 ± ε)A) is positively homogeneous in A
    let surrogate = |ratio: f64, adv: f64| (ratio * adv).min(ratio.clamp(0.8, 1.2) * adv);
    for (ratio, adv) in [(0.5, 1.3), (1.1, -0.7), (1.5, 2.0), (0.9, -1.1)] {
        assert!((surrogate(ratio, 4.0 * adv) - 4.0 * surrogate(ratio, adv)).abs() < 1e-12);
    }
    // no episode ended: nothing is weighted
    let mut cut = b.clone();
    cut.paths.iter_mut().for_each(|p| p.episode = false);
    let s = shape(
        &cut,
        ShapingRule::TailWeight {
            alpha: 0.5,
            weight: 4.0,
        },
        &mut ShapingState::default(),
        GAMMA,
        LAMBDA,
        &comm,
    )
    .expect("shapes");
    assert!(s.report.level.is_nan());
    assert_eq!(s.policy, cut);
}

#[test]
fn each_shaping_reduces_to_ppo_in_the_batch() {
    let b = batch();
    let comm = Comm::default();
    for rule in [
        ShapingRule::MeanVariance { lambda: 0.0 },
        ShapingRule::WorstEpisodes { alpha: 1.0 },
        ShapingRule::TailWeight {
            alpha: 0.5,
            weight: 1.0,
        },
    ] {
        let s =
            shape(&b, rule, &mut ShapingState::default(), GAMMA, LAMBDA, &comm).expect("shapes");
        assert_eq!(s.policy, b, "{rule:?}: the batch bit for bit");
        assert!(s.value.is_none(), "{rule:?}");
    }
    // return capping with the cap at +∞
    let mut state = ShapingState {
        cap: Some(f64::INFINITY),
    };
    let rule = ShapingRule::ReturnCap {
        alpha: 0.5,
        eta: 0.0,
        min_cap: f64::NEG_INFINITY,
    };
    let s = shape(&b, rule, &mut state, GAMMA, LAMBDA, &comm).expect("shapes");
    assert_eq!(s.policy, b);
}

/// A learner's parameters after one update on a batch from a seeded random rollout.
fn updated(config: AlgoConfig) -> (Vec<f64>, Vec<f64>) {
    let device = ndarray_f64();
    let cfg = MlpPolicyConfig {
        hidden: vec![8],
        ..MlpPolicyConfig::new(2, ActionKind::Continuous { dim: 1 })
    };
    let vcfg = ValueConfig {
        observation_dim: 2,
        hidden: vec![8],
    };
    let mut learner =
        Learner::<F64, _>::new(cfg.clone(), cfg.action, &vcfg, config, &device, 3).expect("valid");
    let theta = learner.policy_params();
    let mut rng = Rng::new(5);
    let mut buf = RolloutBuffer::new(LAYOUT, 0.99, 0.97, 60);
    for t in 0..60 {
        let obs = rng.normals(2, 1.0);
        let dist = ref_policy(&cfg, &theta, std::slice::from_ref(&obs));
        let action = sample_actions(&dist, &mut rng);
        let RefDist::Gaussian { mean, log_std } = &dist else {
            unreachable!("a Gaussian policy")
        };
        buf.store(
            &[obs[0] as f32, obs[1] as f32],
            &[action[0][0] as f32],
            dist.log_prob(&action)[0] as f32,
            &[mean[0][0] as f32, log_std[0][0] as f32],
            rng.normal() as f32,
            rng.normal() as f32,
        );
        if t % 15 == 14 {
            buf.finish_path(0.0);
        }
    }
    learner
        .update(&buf.take(), &mut StdRng::seed_from_u64(0))
        .expect("update");
    (learner.policy_params(), learner.value_params())
}

#[test]
fn mvpi_at_lambda_0_cvar_at_alpha_1_and_tailppo_at_w_1_update_as_ppo_bit_for_bit() {
    let ppo = PpoConfig::paper_defaults();
    let (policy_update, value_update) = (
        ProximalConfig {
            iters: 5,
            ..ppo.policy_update
        },
        ProximalConfig {
            iters: 5,
            ..ppo.value_update
        },
    );
    let want = updated(AlgoConfig::Ppo(PpoConfig {
        policy_update,
        value_update,
        ..ppo
    }));
    let mvpi = |mv_lambda: f64| {
        AlgoConfig::Mvpi(MvpiConfig {
            mv_lambda,
            policy_update,
            value_update,
            ..MvpiConfig::paper_defaults()
        })
    };
    let cvar = AlgoConfig::Cvar(CvarConfig {
        alpha: 1.0,
        policy_update,
        value_update,
        ..CvarConfig::paper_defaults()
    });
    let tailppo = |tail_weight: f64| {
        AlgoConfig::TailPpo(TailPpoConfig {
            tail_weight,
            policy_update,
            value_update,
            ..TailPpoConfig::paper_defaults()
        })
    };
    assert_eq!(updated(mvpi(0.0)), want, "mvpi, λ = 0");
    assert_eq!(updated(cvar), want, "cvar, α = 1");
    assert_eq!(updated(tailppo(1.0)), want, "tailppo, w = 1");
    // and a weight that is not 0 (mvpi) or 1 (tailppo) changes the update
    assert_ne!(updated(mvpi(0.5)), want);
    assert_ne!(updated(tailppo(4.0)), want);
}

#[test]
fn a_batch_without_rewards_and_paths_is_refused_naming_what_it_lacks() {
    let mut b = batch();
    b.paths.pop(); // the paths end at row 7 of 10
    let mut state = ShapingState { cap: Some(1.0) };
    let rule = ShapingRule::ReturnCap {
        alpha: 0.5,
        eta: 0.5,
        min_cap: f64::NEG_INFINITY,
    };
    let err = shape(&b, rule, &mut state, GAMMA, LAMBDA, &Comm::default()).expect_err("refused");
    assert_eq!(
        err,
        ShapingError::Unrecorded {
            rows: 10,
            rewards: 10,
            ends: "[3, 7]".to_string()
        }
    );
    assert!(err.to_string().contains("10 rows"), "{err}");
    assert_eq!(state.cap, Some(1.0), "nothing changed");
    let mut b = batch();
    b.reward.clear();
    assert!(shape(&b, rule, &mut state, GAMMA, LAMBDA, &Comm::default()).is_err());
    // a per-row field of another length is refused, not a panic
    let mut b = batch();
    b.value.pop();
    assert!(shape(&b, rule, &mut state, GAMMA, LAMBDA, &Comm::default()).is_err());
    assert_eq!(state.cap, Some(1.0), "nothing changed");
}

#[test]
fn non_finite_returns_and_caps_move_nothing() {
    // a NaN return ranks nothing: the quantile is over the finite ones (6 and 0.5)
    let mut b = batch();
    b.reward[0] = f32::NAN;
    let s = shape(
        &b,
        ShapingRule::WorstEpisodes { alpha: 0.5 },
        &mut ShapingState::default(),
        GAMMA,
        LAMBDA,
        &Comm::default(),
    )
    .expect("shapes");
    assert_eq!(s.report.level, 0.5, "B's return");
    // a cap set to +∞ by hand stays there (it would become NaN)
    let mut state = ShapingState {
        cap: Some(f64::INFINITY),
    };
    let rule = ShapingRule::ReturnCap {
        alpha: 0.5,
        eta: 0.5,
        min_cap: f64::NEG_INFINITY,
    };
    shape(&batch(), rule, &mut state, GAMMA, LAMBDA, &Comm::default()).expect("shapes");
    assert_eq!(state.cap, Some(f64::INFINITY));
}
