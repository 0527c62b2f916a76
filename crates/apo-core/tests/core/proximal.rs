//! The proximal step (Adam on the clipped objective with KL early stopping) and the value
//! update, with the objective, the approximate KL and the MSE computed independently.

use crate::common;

use apo_core::flat::{flatten, to_host};
use apo_core::objective::{ApoParams, HMax, Objective};
use apo_core::objective::{Multipliers, VmpoParams};
use apo_core::policy::{MlpPolicy, MlpPolicyConfig, PolicyFamily};
use apo_core::proximal::{
    proximal_update, value_update, ProximalConfig, ProximalReport, ProximalStep,
};
use apo_core::value::{ValueConfig, ValueNet};
use burn::backend::Autodiff;
use burn::optim::AdamConfig;
use common::*;
use rand::rngs::StdRng;
use rand::SeedableRng;

type Ad = Autodiff<F64>;

struct Setup {
    cfg: MlpPolicyConfig,
    theta_j: Vec<f64>,
    batch: RefBatch,
}

fn setup(seed: u64) -> Setup {
    let cfg = gaussian_cfg(4, &[8, 8], 2);
    let mut rng = Rng::new(seed);
    let theta_j = random_theta(&cfg, &mut rng);
    let batch = sample_batch(&cfg, &theta_j, 64, 0.0, &mut rng);
    Setup {
        cfg,
        theta_j,
        batch,
    }
}

/// Runs `proximal_update` from θ_j; returns the new parameters and the report.
fn run(s: &Setup, objective: &Objective, config: &ProximalConfig) -> (Vec<f64>, ProximalReport) {
    run_step(s, objective, ProximalStep::new(config), None)
}

/// [`run`] with ESPO's stop and V-MPO's multipliers.
fn run_step(
    s: &Setup,
    objective: &Objective,
    step: ProximalStep<'_>,
    multipliers: Option<&mut Multipliers>,
) -> (Vec<f64>, ProximalReport) {
    let device = ndarray_f64();
    let policy: MlpPolicy<Ad> =
        apo_core::flat::unflatten(s.cfg.init::<Ad>(&device), t1::<Ad>(&s.theta_j, &device));
    // Adam needs parameters that are leaves requiring gradients: rebuild them as such
    let policy = reparam(policy);
    let mut optim = AdamConfig::new().init::<Ad, MlpPolicy<Ad>>();
    let tb = s.batch.to_tensors::<Ad>(&device);
    let (policy, report) = proximal_update(
        policy,
        &mut optim,
        objective,
        &tb,
        step,
        multipliers,
        &mut StdRng::seed_from_u64(0),
    );
    (to_host(flatten(&policy)), report)
}

/// The same module with every float parameter a fresh leaf that requires gradients.
fn reparam(policy: MlpPolicy<Ad>) -> MlpPolicy<Ad> {
    use burn::module::{Module, ModuleMapper, Param};
    use burn::tensor::Tensor;
    struct Leaf;
    impl ModuleMapper<Ad> for Leaf {
        fn map_float<const D: usize>(
            &mut self,
            param: Param<Tensor<Ad, D>>,
        ) -> Param<Tensor<Ad, D>> {
            param.map(|t| t.detach().require_grad())
        }
    }
    policy.map(&mut Leaf)
}

fn approx_kl(s: &Setup, theta: &[f64]) -> f64 {
    let logp = ref_policy(&s.cfg, theta, &s.batch.obs).log_prob(&s.batch.actions);
    mean(
        &(0..s.batch.len())
            .map(|i| s.batch.logp_old[i] - logp[i])
            .collect::<Vec<_>>(),
    )
}

#[test]
fn ppo_update_increases_the_clipped_objective() {
    let s = setup(1);
    for (name, obj) in [
        ("ppo", Objective::Ppo { clip: 0.2 }),
        (
            "papo",
            Objective::Papo {
                params: ApoParams {
                    k: 7.0,
                    omega1: 0.005,
                    h_max: HMax::Fixed(0.005),
                    gamma: 0.99,
                    units: Default::default(),
                    switch: Default::default(),
                },
                clip: 0.2,
            },
        ),
        ("a2c", Objective::A2c),
    ] {
        let config = ProximalConfig {
            lr: 3e-3,
            iters: 20,
            target_kl: None,
            minibatch_size: None,
        };
        let (theta, report) = run(&s, &obj, &config);
        assert_eq!(report.steps, 20, "{name}: no early stop without a target");
        assert!(!report.stopped_early);
        let before = ref_objective(&s.cfg, &obj, &s.theta_j, &s.batch).objective;
        let after = ref_objective(&s.cfg, &obj, &theta, &s.batch).objective;
        eprintln!("{name}: objective {before:.6} → {after:.6}");
        assert!(
            after > before + 1e-3,
            "{name}: objective {before} → {after}"
        );
    }
}

#[test]
fn tiny_target_kl_stops_early() {
    let s = setup(2);
    let obj = Objective::Ppo { clip: 0.2 };
    let config = ProximalConfig {
        lr: 3e-3,
        iters: 80,
        target_kl: Some(1e-9),
        minibatch_size: None,
    };
    let (theta, report) = run(&s, &obj, &config);
    assert!(report.stopped_early, "{report:?}");
    // before the first step the policy is π_j (approx KL 0 ≤ target), so at least one
    // step; the sample estimate mean(logp_old − logp) can be ≤ 0 after a step, so maybe
    // a second one, but no more on this data
    assert!(report.steps >= 1 && report.steps <= 3, "{report:?}");
    assert!(report.approx_kl > 1e-9);
    // the reported approx KL is the one of the returned policy, computed here independently
    assert_close(
        "approx_kl",
        report.approx_kl,
        approx_kl(&s, &theta),
        1e-8,
        1e-10,
    );

    // a moderate target stops later, and the returned policy is the first one over it
    let config = ProximalConfig {
        target_kl: Some(0.01),
        ..config
    };
    let (theta, report) = run(&s, &obj, &config);
    assert!(
        report.stopped_early && report.steps > 1 && report.steps < 80,
        "{report:?}"
    );
    assert!(approx_kl(&s, &theta) > 0.01);

    // a huge target never stops
    let config = ProximalConfig {
        target_kl: Some(1e6),
        iters: 10,
        ..config
    };
    let (_, report) = run(&s, &obj, &config);
    assert_eq!((report.steps, report.stopped_early), (10, false));
}

/// `mean(|ratio − 1|)` of the policy `theta` on the batch, computed here.
fn ratio_deviation(s: &Setup, theta: &[f64]) -> f64 {
    let logp = ref_policy(&s.cfg, theta, &s.batch.obs).log_prob(&s.batch.actions);
    mean(
        &(0..s.batch.len())
            .map(|i| ((logp[i] - s.batch.logp_old[i]).exp() - 1.0).abs())
            .collect::<Vec<_>>(),
    )
}

#[test]
fn espo_stops_once_the_ratio_deviation_exceeds_delta() {
    let s = setup(5);
    let config = ProximalConfig {
        lr: 3e-3,
        iters: 80,
        target_kl: None,
        minibatch_size: None,
    };
    let espo = |delta: f64, config: &ProximalConfig| {
        let step = ProximalStep {
            update: config,
            max_ratio_deviation: Some(delta),
        };
        run_step(&s, &Objective::Trpo, step, None)
    };
    let (theta, report) = espo(0.05, &config);
    assert!(
        report.stopped_early && report.steps > 1 && report.steps < 80,
        "{report:?}"
    );
    // the reported deviation is the returned policy's, which is the first one over δ
    let deviation = report.ratio_deviation.expect("measured");
    assert_close(
        "ratio deviation",
        deviation,
        ratio_deviation(&s, &theta),
        1e-8,
        1e-10,
    );
    assert!(deviation > 0.05, "{deviation}");
    assert_eq!(report.approx_kl, 0.0, "no KL stop configured");
    // one step fewer stays within δ
    let fewer = ProximalConfig {
        iters: report.steps - 1,
        ..config
    };
    let (theta, report) = espo(0.05, &fewer);
    assert!(!report.stopped_early, "{report:?}");
    assert!(ratio_deviation(&s, &theta) <= 0.05);
    // a huge δ never stops
    let ten = ProximalConfig {
        iters: 10,
        ..config
    };
    let (_, report) = espo(1e6, &ten);
    assert_eq!((report.steps, report.stopped_early), (10, false));
}

#[test]
fn vmpo_update_learns_its_multipliers() {
    let s = setup(6);
    let config = ProximalConfig {
        lr: 1e-2,
        iters: 5,
        target_kl: None,
        minibatch_size: None,
    };
    let params = VmpoParams {
        eps_eta: 0.008,
        eps_alpha: 0.05,
        eta: 1.0,
        alpha: 5.0,
    };
    let mut m = Multipliers::new(1.0, 5.0);
    let (theta, report) = run_step(
        &s,
        &Objective::Vmpo(params),
        ProximalStep::new(&config),
        Some(&mut m),
    );
    assert_eq!(report.steps, 5);
    // at θ_j the KL is 0 < ε_α: ∂loss/∂α = ε_α − KL > 0 while the policy stays close, so
    // Adam lowers α by about lr per step; the temperature's gradient
    // ε_η + log mean exp(a/η) − Σψa/η is negative for spread-out advantages at η = 1, so η rises
    assert!(m.alpha < 5.0 && m.alpha > 5.0 - 5.5 * 1e-2, "{m:?}");
    assert!(m.eta > 1.0 && m.eta < 1.0 + 5.5 * 1e-2, "{m:?}");
    // the policy moved toward the top half's actions: their weighted log-likelihood rose
    let weighted = |theta: &[f64]| {
        let logp = ref_policy(&s.cfg, theta, &s.batch.obs).log_prob(&s.batch.actions);
        -ref_vmpo(&params, &logp, 0.0, &s.batch.adv).0
    };
    assert!(
        weighted(&theta) > weighted(&s.theta_j),
        "weighted log-likelihood fell"
    );
    // without multipliers the objective's η and α stay constants
    let (theta_fixed, _) = run_step(
        &s,
        &Objective::Vmpo(params),
        ProximalStep::new(&config),
        None,
    );
    assert_ne!(
        theta_fixed, theta,
        "learned multipliers change the policy's steps"
    );
}

#[test]
fn minibatches_take_one_step_each() {
    let s = setup(3);
    let config = ProximalConfig {
        lr: 1e-3,
        iters: 3,
        target_kl: None,
        minibatch_size: Some(16),
    };
    let (_, report) = run(&s, &Objective::Ppo { clip: 0.2 }, &config);
    assert_eq!(
        report.steps,
        3 * 4,
        "64 rows in minibatches of 16, 3 passes"
    );
}

#[test]
fn value_update_reduces_the_mse() {
    let device = ndarray_f64();
    let vcfg = ValueConfig {
        observation_dim: 4,
        hidden: vec![8, 8],
    };
    let mut rng = Rng::new(4);
    let pcfg = gaussian_cfg(4, &[4], 1);
    let theta = random_theta(&pcfg, &mut rng);
    let mut batch = sample_batch(&pcfg, &theta, 64, 0.0, &mut rng);
    // targets: a smooth function of the observation
    batch.ret = batch
        .obs
        .iter()
        .map(|x| x[0] - 0.5 * x[1] * x[2] + 0.3)
        .collect();
    let value: ValueNet<Ad> = vcfg.init::<Ad>(&device);
    let mse = |theta: &[f64]| {
        let sizes = [4, 8, 8, 1];
        mean(
            &batch
                .obs
                .iter()
                .zip(&batch.ret)
                .map(|(x, r)| (ref_mlp(&sizes, theta, x)[0] - r).powi(2))
                .collect::<Vec<_>>(),
        )
    };
    let before = mse(&to_host(flatten(&value)));
    let mut optim = AdamConfig::new().init::<Ad, ValueNet<Ad>>();
    let config = ProximalConfig {
        lr: 1e-2,
        iters: 80,
        target_kl: None,
        minibatch_size: None,
    };
    let tb = batch.to_tensors::<Ad>(&device);
    let (value, report) = value_update(
        value,
        &mut optim,
        &tb,
        &config,
        &mut StdRng::seed_from_u64(0),
    );
    let after = mse(&to_host(flatten(&value)));
    eprintln!("value MSE {before:.4} → {after:.4}");
    assert_close("loss_before", report.loss_before, before, 1e-12, 1.0);
    assert!(after < 0.5 * before, "MSE {before} → {after}");
    assert!(report.loss_after < report.loss_before);
}
