//! The backend-generic objective, gradient, HVP, JVP and Fisher-vector-product checks on
//! NdArray<f32>.
//!
//! This is a binary of its own on purpose: Burn 0.21 records the default float dtype per
//! device *type*, process-wide, and NdArray<f32> and NdArray<f64> share `NdArrayDevice`.
//! Whichever runs first in a process decides the dtype of both, so mixing them in one
//! test binary would make the float64 references silently run in float32 (or these
//! tests in float64). Here nothing touches NdArray<f64>: every reference is plain Rust
//! f64 (the HVP reference is the mixed finite difference of the reference value; the JVP and
//! Fisher references are central differences of the reference policy, `common/fisher.rs`).

mod common;

use burn::backend::ndarray::NdArrayDevice;
use burn::backend::NdArray;
use burn::tensor::DType;
use common::backend::*;
use common::fisher::{check_fisher_vs_explicit, check_jvp, Jvp};

type F32 = NdArray<f32>;

fn device() -> NdArrayDevice {
    let device = NdArrayDevice::default();
    common::assert_float_dtype::<F32>(&device, DType::F32, "NdArray<f32>");
    device
}

#[test]
fn terms_by_hand_ndarray_f32() {
    check_terms::<F32>(&device(), 1e-5);
}

#[test]
fn evaluate_every_objective_ndarray_f32() {
    check_evaluate::<F32>(&device(), 1e-5);
}

#[test]
fn terms_at_theta_j_ndarray_f32() {
    check_at_theta_j::<F32>(&device(), 1e-5);
}

#[test]
fn gradients_match_finite_differences_ndarray_f32() {
    let errors = check_gradients::<F32>(&device(), 1e-4);
    print_errors("gradient relative error, NdArray<f32> vs f64 FD", &errors);
}

#[test]
fn hvp_matches_finite_differences_ndarray_f32() {
    let cases = hvp_cases();
    let refs: Vec<Vec<f64>> = cases.iter().map(|c| c.reference_fd_of_value()).collect();
    let errors = check_hvp::<F32>(&device(), 1e-4, &cases, &refs);
    print_errors(
        "HVP relative error, NdArray<f32> vs f64 mixed FD of the value",
        &errors,
    );
}

#[test]
fn jvp_matches_finite_differences_ndarray_f32() {
    let errors = check_jvp::<F32>(&device(), 1e-4);
    print_errors("J v relative error, NdArray<f32> vs f64 FD", &errors);
}

#[test]
fn fisher_product_matches_explicit_fisher_ndarray_f32() {
    let errors =
        check_fisher_vs_explicit::<F32>(&device(), apo_core::Kernels::Backend, Jvp::Analytic, 1e-4);
    print_errors(
        "F v relative error, NdArray<f32> vs explicit Jᵀ M J / N (f64 FD Jacobian)",
        &errors,
    );
}

/// `J v` by a central finite difference in f32 (a policy without a JVP): the error is of order
/// ε_M^{2/3} ≈ 2.4e-5 (`apo_core::fisher`), against 1e-7 for the forward-mode JVP.
#[test]
fn finite_difference_fisher_matches_explicit_fisher_ndarray_f32() {
    let errors = check_fisher_vs_explicit::<F32>(
        &device(),
        apo_core::Kernels::Backend,
        Jvp::FiniteDifference,
        1e-3,
    );
    print_errors(
        "F v relative error, J v by f32 finite differences, NdArray<f32> vs explicit Jᵀ M J / N",
        &errors,
    );
}

#[test]
fn fisher_product_on_host_kernels_matches_explicit_fisher() {
    let errors =
        check_fisher_vs_explicit::<F32>(&device(), apo_core::Kernels::Host, Jvp::Analytic, 1e-5);
    print_errors(
        "F v relative error, host kernels (f32) vs explicit Jᵀ M J / N (f64 FD Jacobian)",
        &errors,
    );
}

/// A random batch of `n` transitions (Gaussian policy, `obs_dim` observations, 2 actions);
/// the rewards-to-go are a smooth function of the observation plus noise, so the critic
/// has something to fit.
fn random_batch(n: usize, obs_dim: usize, seed: u64) -> apo_core::Batch {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut draw = |len: usize, scale: f32| -> Vec<f32> {
        (0..len).map(|_| rng.random_range(-scale..scale)).collect()
    };
    let obs = draw(n * obs_dim, 2.0);
    let noise = draw(n, 0.1);
    let ret = obs
        .chunks(obs_dim)
        .zip(&noise)
        .map(|(o, e)| 3.0 * o[0].sin() - o[1] + e)
        .collect();
    apo_core::Batch {
        len: n,
        actions: draw(n * 2, 1.0),
        logp: draw(n, 1.0).iter().map(|v| v - 2.0).collect(),
        dist: draw(n * 4, 0.5),
        value: draw(n, 1.0),
        delta: draw(n, 1.0),
        adv: draw(n, 1.0),
        obs,
        ret,
        adv_scale: 1.0,
        ..apo_core::Batch::default()
    }
}

/// Two learners from one seed, one updated with `fits[i]` in update `i` and the other always
/// through Burn; the largest difference of their critics' parameters after each update, and
/// of their policies' (which must be equal: the value fit draws the same minibatches).
fn value_fit_divergence(fits: &[apo_core::Kernels], minibatch: Option<usize>) -> Vec<f64> {
    use apo_core::algorithm::{AlgoConfig, AlgorithmConfig, PapoConfig};
    use apo_core::{Kernels, Learner, MlpPolicyConfig, ValueConfig};
    use rand::SeedableRng;
    let (obs_dim, hidden) = (5, vec![16, 16]);
    let mut config = PapoConfig::paper_defaults();
    config.value_update.iters = 20;
    config.value_update.minibatch_size = minibatch;
    config.policy_update.iters = 3;
    config.policy_update.minibatch_size = minibatch;
    let action = apo_core::ActionKind::Continuous { dim: 2 };
    let make = || {
        Learner::<F32, _>::new(
            MlpPolicyConfig {
                observation_dim: obs_dim,
                hidden: hidden.clone(),
                action,
                init_log_std: -0.5,
            },
            action,
            &ValueConfig {
                observation_dim: obs_dim,
                hidden: hidden.clone(),
            },
            AlgoConfig::Papo(config.clone()),
            &device(),
            11,
        )
        .expect("valid config")
    };
    let (mut a, mut b) = (make(), make());
    assert_eq!(a.value_params(), b.value_params());
    let (mut rng_a, mut rng_b) = (
        rand::rngs::StdRng::seed_from_u64(5),
        rand::rngs::StdRng::seed_from_u64(5),
    );
    let mut out = Vec::new();
    for (epoch, &fit) in fits.iter().enumerate() {
        let batch = random_batch(256, obs_dim, epoch as u64);
        a.set_kernels(fit);
        b.set_kernels(Kernels::Backend);
        let (ra, rb) = (
            a.update(&batch, &mut rng_a)
                .expect("the MLP fits its actions"),
            b.update(&batch, &mut rng_b)
                .expect("the MLP fits its actions"),
        );
        assert!((ra.loss_v - rb.loss_v).abs() <= 1e-4 * rb.loss_v.max(1.0));
        let max_diff = |x: Vec<f64>, y: Vec<f64>| {
            x.iter()
                .zip(&y)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max)
        };
        assert!(
            max_diff(a.policy_params(), b.policy_params()) <= 1e-5,
            "the policies differ: the value fits consumed the random stream differently"
        );
        out.push(max_diff(a.value_params(), b.value_params()));
    }
    out
}

#[test]
fn host_value_fit_matches_burn_full_batch_and_minibatches() {
    use apo_core::Kernels::{Backend, Host};
    for minibatch in [None, Some(48)] {
        // host then Burn: the second update starts from the Adam state the host wrote back
        let diffs = value_fit_divergence(&[Host, Backend, Host], minibatch);
        for d in &diffs {
            assert!(
                *d <= 1e-6,
                "{minibatch:?}: host vs Burn critics differ by {diffs:?}"
            );
        }
    }
}

/// A random batch of `n` transitions for `action` (one-hot actions and logits for a
/// categorical), `obs_dim` observations.
fn random_batch_for(
    action: apo_core::ActionKind,
    n: usize,
    obs_dim: usize,
    seed: u64,
) -> apo_core::Batch {
    use rand::{Rng, SeedableRng};
    let mut batch = random_batch(n, obs_dim, seed);
    if let apo_core::ActionKind::Discrete { n: k } = action {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 100);
        batch.actions = (0..n)
            .flat_map(|_| {
                let a = rng.random_range(0..k);
                (0..k).map(move |i| if i == a { 1.0 } else { 0.0 })
            })
            .collect();
        batch.dist = vec![0.0; n * k];
    }
    batch
}

/// `batch` as collected by `learner`'s current policy π_j: its distributions and the
/// log-probabilities of the batch's actions under them.
fn on_policy(
    batch: &mut apo_core::Batch,
    learner: &apo_core::Learner<F32, apo_core::MlpPolicyConfig>,
    action: apo_core::ActionKind,
) {
    use apo_core::{DistParams, Policy, TensorBatch};
    let tb = TensorBatch::<F32>::new(batch, action, &device());
    let dist = learner
        .policy_on::<F32>(&device())
        .distribution(tb.obs.clone());
    let host =
        |t: burn::tensor::Tensor<F32, 2>| -> Vec<f32> { t.into_data().iter::<f32>().collect() };
    batch.logp = dist
        .log_prob(tb.actions.clone())
        .into_data()
        .iter::<f32>()
        .collect();
    batch.dist = match dist {
        DistParams::Gaussian { mean, log_std } => {
            host(burn::tensor::Tensor::cat(vec![mean, log_std], 1))
        }
        DistParams::Categorical { logits } => host(logits),
    };
}

/// The policy's Adam update of `config`.
fn policy_update(config: &mut apo_core::AlgoConfig) -> &mut apo_core::ProximalConfig {
    use apo_core::AlgoConfig::*;
    match config {
        Papo(c) => &mut c.policy_update,
        Ppo(c) => &mut c.policy_update,
        A2c(c) => &mut c.policy_update,
        Espo(c) => &mut c.policy_update,
        AlphaPpo(c) => &mut c.policy_update,
        Vmpo(c) => &mut c.policy_update,
        Mvpi(c) => &mut c.policy_update,
        Cvar(c) => &mut c.policy_update,
        Retcap(c) => &mut c.policy_update,
        TailPpo(c) => &mut c.policy_update,
        Apo(_) | Trpo(_) => unreachable!("trust-region algorithms have no Adam update"),
    }
}

/// Every proximal algorithm's policy update on the host kernels against Burn's graph: two
/// learners from one seed, one updated on the host in the epochs marked `Host` in `fits` (and
/// through Burn in the others), the other always through Burn, on Gaussian and categorical
/// policies, full-batch and with minibatches. After each epoch the policies must agree to f32
/// rounding, the reports must have taken the same steps and stops, and V-MPO's multipliers
/// must agree.
#[test]
fn host_proximal_updates_match_burn_for_every_algorithm() {
    use apo_core::Kernels::{Backend, Host};
    use apo_core::{ActionKind, AlgoConfig, Algorithm, Learner, MlpPolicyConfig, ValueConfig};
    use rand::SeedableRng;
    let (obs_dim, hidden) = (5, vec![16, 16]);
    let fits = [Host, Host, Backend, Host];
    let mut worst = 0.0f64;
    // MVPI, CVaR, return capping and tail-weighted PPO update as PPO on their shaped batch (this
    // batch records no rewards or paths to shape): PPO's row covers their policy step
    for algo in Algorithm::ALL.iter().copied().filter(|a| {
        !matches!(
            a,
            Algorithm::Apo
                | Algorithm::Trpo
                | Algorithm::Mvpi
                | Algorithm::Cvar
                | Algorithm::Retcap
                | Algorithm::TailPpo
        )
    }) {
        for action in [
            ActionKind::Continuous { dim: 2 },
            ActionKind::Discrete { n: 3 },
        ] {
            for minibatch in [None, Some(96)] {
                let mut config = AlgoConfig::paper_defaults(algo);
                let update = policy_update(&mut config);
                update.iters = 6;
                update.minibatch_size = minibatch;
                let make = || {
                    Learner::<F32, _>::new(
                        MlpPolicyConfig {
                            observation_dim: obs_dim,
                            hidden: hidden.clone(),
                            action,
                            init_log_std: -0.5,
                        },
                        action,
                        &ValueConfig {
                            observation_dim: obs_dim,
                            hidden: hidden.clone(),
                        },
                        config.clone(),
                        &device(),
                        11,
                    )
                    .expect("valid config")
                };
                let (mut a, mut b) = (make(), make());
                let (mut rng_a, mut rng_b) = (
                    rand::rngs::StdRng::seed_from_u64(5),
                    rand::rngs::StdRng::seed_from_u64(5),
                );
                let case = format!("{algo} {action:?} minibatch {minibatch:?}");
                let mut moved = 0.0f64;
                let start = b.policy_params();
                for (epoch, &fit) in fits.iter().enumerate() {
                    let mut batch = random_batch_for(action, 256, obs_dim, epoch as u64);
                    on_policy(&mut batch, &b, action);
                    a.set_kernels(fit);
                    b.set_kernels(Backend);
                    let ra = a.update(&batch, &mut rng_a).expect("the MLP fits");
                    let rb = b.update(&batch, &mut rng_b).expect("the MLP fits");
                    let (pa, pb) = (
                        ra.proximal.expect("proximal"),
                        rb.proximal.expect("proximal"),
                    );
                    assert_eq!(
                        (pa.steps, pa.stopped_early),
                        (pb.steps, pb.stopped_early),
                        "{case}, epoch {epoch}: the updates took different steps"
                    );
                    assert!(
                        (pa.approx_kl - pb.approx_kl).abs() <= 1e-5,
                        "{case}: {pa:?} vs {pb:?}"
                    );
                    let diff = a
                        .policy_params()
                        .iter()
                        .zip(b.policy_params())
                        .map(|(p, q)| (p - q).abs())
                        .fold(0.0, f64::max);
                    assert!(
                        diff <= 1e-6,
                        "{case}, epoch {epoch}: policies differ by {diff}"
                    );
                    worst = worst.max(diff);
                    if let (Some(ma), Some(mb)) = (ra.multipliers, rb.multipliers) {
                        assert!(
                            (ma.eta - mb.eta).abs() <= 1e-5 && (ma.alpha - mb.alpha).abs() <= 1e-5,
                            "{case}: multipliers {ma:?} vs {mb:?}"
                        );
                    }
                }
                moved = b
                    .policy_params()
                    .iter()
                    .zip(&start)
                    .map(|(p, q)| (p - q).abs())
                    .fold(moved, f64::max);
                // the comparison means something only if the updates moved the policy
                assert!(
                    moved > 100.0 * worst.max(1e-7),
                    "{case}: the policy moved by {moved} only"
                );
            }
        }
    }
    println!("largest host vs Burn policy difference: {worst:.2e}");
}

/// APO's and TRPO's whole policy update on the host kernels (the objective's gradient, the
/// Fisher products, every line-search try and the diagnostics before and after) against
/// Burn's graph in f64, from one state: for three seeds, two learners made alike, one on f32
/// updated on the host, the other on f64 through Burn, on one batch. The line searches must
/// accept the same try; the diagnostics before the update (entropy, the objective) must agree
/// to f32 rounding; the steps must agree up to f32 rounding amplified by the
/// conjugate-gradient solve (bound 2e−2 of the step; 9.4e−3 measured at worst, 8.3e−3 with
/// the objective's gradient on Burn's graph, so the f32 Fisher products dominate it), and the
/// KL after the step to twice that (it is quadratic in the step).
#[test]
fn host_trust_region_updates_match_burn_for_apo_and_trpo() {
    use apo_core::Kernels::{Backend, Host};
    use apo_core::{ActionKind, AlgoConfig, Algorithm, Learner, MlpPolicyConfig, ValueConfig};
    use rand::SeedableRng;
    let (obs_dim, hidden) = (5, vec![16, 16]);
    let (mut worst_step, mut worst_kl) = (0.0f64, 0.0f64);
    for algo in [Algorithm::Apo, Algorithm::Trpo] {
        for action in [
            ActionKind::Continuous { dim: 2 },
            ActionKind::Discrete { n: 3 },
        ] {
            for seed in 0..3u64 {
                let policy = MlpPolicyConfig {
                    observation_dim: obs_dim,
                    hidden: hidden.clone(),
                    action,
                    init_log_std: -0.5,
                };
                let value = ValueConfig {
                    observation_dim: obs_dim,
                    hidden: hidden.clone(),
                };
                let config = AlgoConfig::paper_defaults(algo);
                let learner_seed = 11 + seed;
                let mut a = Learner::<F32, _>::new(
                    policy.clone(),
                    action,
                    &value,
                    config.clone(),
                    &device(),
                    learner_seed,
                )
                .expect("valid config");
                let mut b = Learner::<NdArray<f64>, _>::new(
                    policy,
                    action,
                    &value,
                    config,
                    &device(),
                    learner_seed,
                )
                .expect("valid config");
                a.set_kernels(Host);
                b.set_kernels(Backend);
                let mut batch = random_batch_for(action, 256, obs_dim, seed);
                on_policy(&mut batch, &a, action);
                let start = b.policy_params();
                let rng = || rand::rngs::StdRng::seed_from_u64(5);
                let ra = a.update(&batch, &mut rng()).expect("the MLP fits");
                let rb = b.update(&batch, &mut rng()).expect("the MLP fits");
                let case = format!("{algo} {action:?} seed {seed}");
                assert_eq!(ra.line_search, rb.line_search, "{case}");
                let rel = |x: f64, y: f64| (x - y).abs() / y.abs().max(1e-2);
                for (what, x, y) in [
                    ("entropy", ra.entropy, rb.entropy),
                    ("mean_surr", ra.mean_surr, rb.mean_surr),
                    ("loss_pi", ra.loss_pi, rb.loss_pi),
                ] {
                    assert!(rel(x, y) <= 1e-5, "{case}: {what} {x} vs {y}");
                }
                let max_abs = |v: Vec<f64>| v.into_iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let (pa, pb) = (a.policy_params(), b.policy_params());
                let moved = max_abs(pb.iter().zip(&start).map(|(p, q)| p - q).collect());
                let diff = max_abs(pa.iter().zip(&pb).map(|(p, q)| p - q).collect());
                // the comparison means something only if the update moved the policy
                assert!(moved > 1e-4, "{case}: moved by {moved} only");
                assert!(
                    diff <= 2e-2 * moved,
                    "{case}: policies differ by {diff}, moved by {moved}"
                );
                assert!(
                    rel(ra.kl, rb.kl) <= 4e-2,
                    "{case}: kl {} vs {}",
                    ra.kl,
                    rb.kl
                );
                worst_step = worst_step.max(diff / moved);
                worst_kl = worst_kl.max(rel(ra.kl, rb.kl));
            }
        }
    }
    println!(
        "largest host vs Burn (f64) difference: policy {worst_step:.2e} of the step, KL {worst_kl:.2e}"
    );
}
