//! The learner: one update per algorithm on a tiny synthetic batch collected by its own
//! policy, with the reported numbers checked independently; config validation.

use crate::common;

use apo_core::algorithm::{AlgoConfig, Algorithm, AlgorithmConfig, ApoConfig, PapoConfig};
use apo_core::buffer::{Batch, BufferLayout, RolloutBuffer};
use apo_core::policy::{ActionKind, MlpPolicyConfig};
use apo_core::value::ValueConfig;
use apo_core::Learner;
use common::*;
use rand::rngs::StdRng;
use rand::SeedableRng;

const OBS: usize = 3;

/// Collects a 3-path, 40-step batch with the learner's current policy and critic
/// (evaluated here by the plain-Rust reference), random rewards, and the buffer's GAE.
fn collect(
    cfg: &MlpPolicyConfig,
    theta: &[f64],
    vtheta: &[f64],
    hidden: &[usize],
    rng: &mut Rng,
) -> Batch {
    let (width, dist_width) = match cfg.action {
        ActionKind::Continuous { dim } => (dim, 2 * dim),
        ActionKind::Discrete { n } => (n, n),
    };
    let layout = BufferLayout {
        observation_dim: OBS,
        action_width: width,
        dist_width,
    };
    let mut buf = RolloutBuffer::new(layout, 0.99, 0.97, 40);
    let vsizes: Vec<usize> = std::iter::once(OBS)
        .chain(hidden.iter().copied())
        .chain([1])
        .collect();
    for t in 0..40 {
        let obs = rng.normals(OBS, 1.0);
        let dist = ref_policy(cfg, theta, std::slice::from_ref(&obs));
        let action = sample_actions(&dist, rng);
        let logp = dist.log_prob(&action)[0];
        let params: Vec<f64> = match &dist {
            RefDist::Gaussian { mean, log_std } => {
                mean[0].iter().chain(&log_std[0]).copied().collect()
            }
            RefDist::Categorical { logits } => logits[0].clone(),
        };
        let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let value = ref_mlp(&vsizes, vtheta, &obs)[0];
        buf.store(
            &f32s(&obs),
            &f32s(&action[0]),
            logp as f32,
            &f32s(&params),
            value as f32,
            rng.normal() as f32,
        );
        match t {
            12 => buf.finish_path(0.0), // terminated
            25 => buf.finish_path(ref_mlp(&vsizes, vtheta, &rng.normals(OBS, 1.0))[0] as f32), // truncated
            39 => buf.finish_cut_path(0.3), // cut by the epoch
            _ => {}
        }
    }
    buf.take()
}

/// The host batch as a reference batch (f32 values widened to f64).
fn to_ref(batch: &Batch, cfg: &MlpPolicyConfig) -> RefBatch {
    let rows = |v: &[f32], w: usize| {
        v.chunks(w)
            .map(|r| r.iter().map(|&x| f64::from(x)).collect())
            .collect::<Vec<Vec<f64>>>()
    };
    let one = |v: &[f32]| v.iter().map(|&x| f64::from(x)).collect::<Vec<f64>>();
    let dist_old = match cfg.action {
        ActionKind::Continuous { dim } => {
            let d = rows(&batch.dist, 2 * dim);
            RefDist::Gaussian {
                mean: d.iter().map(|r| r[..dim].to_vec()).collect(),
                log_std: d.iter().map(|r| r[dim..].to_vec()).collect(),
            }
        }
        ActionKind::Discrete { n } => RefDist::Categorical {
            logits: rows(&batch.dist, n),
        },
    };
    RefBatch {
        obs: rows(&batch.obs, OBS),
        actions: rows(&batch.actions, cfg.action.width()),
        logp_old: one(&batch.logp),
        dist_old,
        value: one(&batch.value),
        delta: one(&batch.delta),
        adv: one(&batch.adv),
        ret: one(&batch.ret),
        adv_scale: batch.adv_scale,
    }
}

#[test]
fn one_update_per_algorithm_reports_consistent_finite_numbers() {
    let device = ndarray_f64();
    let hidden = [8, 8];
    let vcfg = ValueConfig {
        observation_dim: OBS,
        hidden: hidden.to_vec(),
    };
    for (pname, cfg) in [
        (
            "gaussian",
            MlpPolicyConfig {
                hidden: hidden.to_vec(),
                ..MlpPolicyConfig::new(OBS, ActionKind::Continuous { dim: 2 })
            },
        ),
        (
            "categorical",
            MlpPolicyConfig {
                hidden: hidden.to_vec(),
                ..MlpPolicyConfig::new(OBS, ActionKind::Discrete { n: 3 })
            },
        ),
    ] {
        for &algo in Algorithm::ALL {
            let what = format!("{pname}/{algo}");
            let mut config = AlgoConfig::paper_defaults(algo);
            shorten(&mut config);
            let mut learner =
                Learner::<F64, _>::new(cfg.clone(), cfg.action, &vcfg, config.clone(), &device, 7)
                    .expect("valid config");
            let theta_j = learner.policy_params();
            let vtheta = learner.value_params();
            assert_eq!(theta_j.len(), policy_params(&cfg));
            let batch = collect(&cfg, &theta_j, &vtheta, &hidden, &mut Rng::new(3));
            // MVPI, CVaR and return capping update on the shaped batch (tests/core/shaping.rs
            // checks the shaping against hand computations)
            let shaped = config.settings().shaping().map(|rule| {
                let common = config.common();
                apo_core::shaping::shape(
                    &batch,
                    rule,
                    &mut apo_core::ShapingState::default(),
                    common.gamma,
                    common.lambda,
                    &apo_core::Comm::default(),
                )
                .expect("a buffer's batch shapes")
            });
            let rb = to_ref(shaped.as_ref().map_or(&batch, |s| &s.policy), &cfg);
            let rb_value = to_ref(
                shaped
                    .as_ref()
                    .map_or(&batch, |s| s.value.as_ref().unwrap_or(&s.policy)),
                &cfg,
            );

            let report = learner
                .update(&batch, &mut StdRng::seed_from_u64(0))
                .expect("the built-in MLP fits its actions");
            let theta = learner.policy_params();
            for (name, v) in [
                ("loss_pi", report.loss_pi),
                ("mean_surr", report.mean_surr),
                ("kl", report.kl),
                ("entropy", report.entropy),
                ("loss_v", report.loss_v),
            ] {
                assert!(v.is_finite(), "{what}: {name} = {v}");
            }
            // the numbers at θ_j, recomputed here
            let r = ref_objective(&cfg, &config.objective(), &theta_j, &rb);
            assert_close(
                &format!("{what}: loss_pi"),
                report.loss_pi,
                -r.objective,
                1e-9,
                1.0,
            );
            assert_close(
                &format!("{what}: mean_surr"),
                report.mean_surr,
                r.mean_surr,
                1e-9,
                1.0,
            );
            if !matches!(algo, Algorithm::A2c | Algorithm::Vmpo) {
                // ratio 1 (up to the f32 storage of logp): mean_surr = mean(adv) ≈ 0 (normalized)
                assert_close(
                    &format!("{what}: mean_surr = mean(adv)"),
                    report.mean_surr,
                    mean(&rb.adv),
                    1e-6,
                    1.0,
                );
            }
            assert_eq!(
                report.mean_variance.is_some(),
                matches!(algo, Algorithm::Apo | Algorithm::Papo),
                "{what}"
            );
            assert_eq!(
                report.variance_mean.is_some(),
                matches!(algo, Algorithm::Apo | Algorithm::Papo),
                "{what}"
            );
            if let (Some(a), Some(e)) = (report.mean_variance, r.mean_variance) {
                assert_close(&format!("{what}: mv"), a, e, 1e-9, 1.0);
            }
            if let (Some(a), Some(e)) = (report.variance_mean, r.variance_mean) {
                assert_close(&format!("{what}: vm"), a, e, 1e-9, 1.0);
            }
            let entropy = mean(&ref_policy(&cfg, &theta_j, &rb.obs).entropy());
            assert_close(
                &format!("{what}: entropy"),
                report.entropy,
                entropy,
                1e-12,
                1.0,
            );
            let vsizes = [OBS, 8, 8, 1];
            let mse = mean(
                &rb_value
                    .obs
                    .iter()
                    .zip(&rb_value.ret)
                    .map(|(x, r)| (ref_mlp(&vsizes, &vtheta, x)[0] - r).powi(2))
                    .collect::<Vec<_>>(),
            );
            assert_close(&format!("{what}: loss_v"), report.loss_v, mse, 1e-9, 1.0);
            // KL(π_j ‖ π_{j+1}) of the stored (f32) distributions
            let kl = ref_mean_kl(&cfg, &theta, &rb);
            assert_close(&format!("{what}: kl"), report.kl, kl, 1e-6, 1e-6);
            // the value network was updated
            assert_ne!(
                learner.value_params(),
                vtheta,
                "{what}: value network unchanged"
            );

            match algo {
                Algorithm::Apo | Algorithm::Trpo => {
                    let outcome = report.line_search.expect("trust-region outcome");
                    assert!(report.proximal.is_none());
                    assert!(
                        report.kl <= max_kl(&config) * (1.0 + 1e-6),
                        "{what}: KL {}",
                        report.kl
                    );
                    eprintln!("{what}: {outcome:?}, KL {:.2e}", report.kl);
                }
                _ => {
                    let p = report.proximal.expect("proximal report");
                    assert!(report.line_search.is_none());
                    assert!(p.steps >= 1, "{what}: {p:?}");
                    // ESPO measures its ratio deviation; V-MPO learns η and α
                    assert_eq!(
                        p.ratio_deviation.is_some(),
                        algo == Algorithm::Espo,
                        "{what}"
                    );
                    if let Some(d) = p.ratio_deviation {
                        assert!(d.is_finite() && d >= 0.0, "{what}: {d}");
                    }
                    assert_eq!(report.multipliers.is_some(), algo == Algorithm::Vmpo);
                    if let Some(m) = report.multipliers {
                        assert!(m.eta != 1.0 && m.alpha != 5.0, "{what}: {m:?}");
                        assert_eq!(learner.multipliers(), Some(&m));
                    }
                    assert_ne!(theta, theta_j, "{what}: policy unchanged");
                    eprintln!("{what}: {p:?}, KL {:.2e}", report.kl);
                }
            }
        }
    }
}

#[test]
fn config_validation_names_the_bad_field() {
    for &algo in Algorithm::ALL {
        AlgoConfig::paper_defaults(algo)
            .validate()
            .expect("the paper's defaults are valid");
    }
    let apo = |f: &dyn Fn(&mut ApoConfig)| {
        let mut c = ApoConfig::paper_defaults();
        f(&mut c);
        AlgoConfig::Apo(c)
    };
    let papo = |f: &dyn Fn(&mut PapoConfig)| {
        let mut c = PapoConfig::paper_defaults();
        f(&mut c);
        AlgoConfig::Papo(c)
    };
    let defaults = |algo| AlgoConfig::paper_defaults(algo);
    let with = |algo, f: &dyn Fn(&mut AlgoConfig)| {
        let mut c = defaults(algo);
        f(&mut c);
        c
    };
    let cases = vec![
        (
            "delta",
            with(Algorithm::Espo, &|c| {
                if let AlgoConfig::Espo(e) = c {
                    e.delta = 0.0
                }
            }),
        ),
        (
            "alpha",
            with(Algorithm::AlphaPpo, &|c| {
                if let AlgoConfig::AlphaPpo(a) = c {
                    a.alpha = 1.0
                }
            }),
        ),
        (
            "beta",
            with(Algorithm::AlphaPpo, &|c| {
                if let AlgoConfig::AlphaPpo(a) = c {
                    a.beta = 1.5
                }
            }),
        ),
        (
            "eta_init",
            with(Algorithm::Vmpo, &|c| {
                if let AlgoConfig::Vmpo(v) = c {
                    v.eta_init = 0.0
                }
            }),
        ),
        (
            "eps_alpha",
            with(Algorithm::Vmpo, &|c| {
                if let AlgoConfig::Vmpo(v) = c {
                    v.eps_alpha = -1.0
                }
            }),
        ),
        ("gamma", apo(&|c| c.gamma = 1.0)),
        ("k", apo(&|c| c.k = -1.0)),
        ("k", apo(&|c| c.k = 1e308)),
        ("omega2", papo(&|c| c.omega2 = 1e9)),
        ("trust_region.max_kl", apo(&|c| c.trust_region.max_kl = 0.0)),
        ("clip", papo(&|c| c.clip = 1.5)),
        ("lambda", papo(&|c| c.lambda = 1.5)),
        ("omega1", apo(&|c| c.omega1 = f64::NAN)),
        ("policy_update.lr", papo(&|c| c.policy_update.lr = 0.0)),
        ("value_update.iters", apo(&|c| c.value_update.iters = 0)),
    ];
    for (field, c) in cases {
        let err = c.validate().expect_err(field);
        assert_eq!(err.field, field);
        let msg = err.to_string();
        assert!(
            msg.contains(&format!("`{field}`")),
            "message `{msg}` does not name `{field}`"
        );
        // and the learner refuses it
        let cfg = MlpPolicyConfig::new(OBS, ActionKind::Discrete { n: 2 });
        let vcfg = ValueConfig {
            observation_dim: OBS,
            hidden: vec![4],
        };
        let res = Learner::<F64, _>::new(cfg.clone(), cfg.action, &vcfg, c, &ndarray_f64(), 0);
        assert_eq!(res.err().map(|e| e.field), Some(field.to_string()));
    }
}

/// Ten policy and value iterations instead of the paper's 80.
fn shorten(config: &mut AlgoConfig) {
    match config {
        AlgoConfig::Apo(c) => c.value_update.iters = 10,
        AlgoConfig::Trpo(c) => c.value_update.iters = 10,
        AlgoConfig::Papo(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
        AlgoConfig::Ppo(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
        AlgoConfig::A2c(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
        AlgoConfig::Espo(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
        AlgoConfig::AlphaPpo(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
        AlgoConfig::Mvpi(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
        AlgoConfig::Cvar(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
        AlgoConfig::Retcap(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
        AlgoConfig::Vmpo(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
        AlgoConfig::TailPpo(c) => {
            c.policy_update.iters = 10;
            c.value_update.iters = 10;
        }
    }
}

/// The trust region's δ (∞ for proximal algorithms).
fn max_kl(config: &AlgoConfig) -> f64 {
    match config.settings().policy_step() {
        apo_core::PolicyStep::TrustRegion(t) => t.max_kl,
        apo_core::PolicyStep::Proximal(_) => f64::INFINITY,
    }
}
