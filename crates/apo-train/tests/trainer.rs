//! The epoch loop: the checkpoint schedule, interrupts, restoring, and acting through the host
//! MLP and through any Burn policy module.

use std::sync::atomic::AtomicBool;

use apo_core::inference::ActBuffers;
use apo_core::{Algorithm, Learner, MlpPolicyConfig};
use apo_train::{
    Act, Actor, BurnActor, Checkpoint, HostActor, RunState, TrainConfig, TrainError, Trainer,
};
use burn::backend::NdArray;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

fn small(algo: Algorithm, env: &str, epochs: usize, steps: usize) -> TrainConfig {
    let mut config = TrainConfig::defaults(algo, env);
    config.epochs = epochs;
    config.steps_per_epoch = steps;
    config.num_envs = 2;
    config.hidden = vec![8];
    config
}

#[test]
fn checkpoints_are_due_every_n_epochs_kept_every_m_at_the_end_and_on_interrupt() {
    let mut config = small(Algorithm::Ppo, "CartPole-v1", 5, 32);
    config.checkpoint_every = 2;
    config.keep_checkpoint_every = 3;
    let mut trainer = Trainer::<NdArray, _, _>::mlp(config, &Default::default(), 1).expect("valid");
    let stop = AtomicBool::new(false);
    let mut due = Vec::new();
    let mut interrupted = Vec::new();
    while let Some(epoch) = trainer.epoch(&stop, &mut |_| {}).expect("finite") {
        assert_eq!(epoch.row.epoch, trainer.state().epoch);
        due.push(trainer.checkpoint_due(false));
        interrupted.push(trainer.checkpoint_due(true));
    }
    let plain = Some(Checkpoint { keep: false });
    let kept = Some(Checkpoint { keep: true });
    // epoch 1: nothing; 2: every 2; 3: kept (every 3); 4: every 2; 5: the last
    assert_eq!(due, vec![None, plain, kept, plain, plain]);
    assert!(interrupted.iter().all(Option::is_some));
    assert!(trainer.finished());
    assert_eq!(trainer.state().env_steps, 5 * 32);
}

#[test]
fn a_stop_during_the_rollout_drops_the_epoch_and_restore_checks_the_end() {
    let config = small(Algorithm::Trpo, "CartPole-v1", 2, 64);
    let mut trainer = Trainer::<NdArray, _, _>::mlp(config, &Default::default(), 1).expect("valid");
    let stopped = trainer
        .epoch(&AtomicBool::new(true), &mut |_| {})
        .expect("no error");
    assert!(stopped.is_none());
    assert_eq!(trainer.state().epoch, 0);
    assert_eq!(trainer.state().env_steps, 0);

    let past = RunState {
        epoch: 3,
        env_steps: 192,
        elapsed_s: 1.0,
        normalizer: None,
    };
    match trainer.restore(past) {
        Err(TrainError::PastTheEnd { done: 3, epochs: 2 }) => {}
        other => panic!("expected PastTheEnd, got {other:?}"),
    }
    let one = RunState {
        epoch: 1,
        env_steps: 64,
        elapsed_s: 1.0,
        normalizer: None,
    };
    trainer.restore(one).expect("within the run");
    let epoch = trainer
        .epoch(&AtomicBool::new(false), &mut |_| {})
        .expect("finite")
        .expect("an epoch");
    assert_eq!((epoch.row.epoch, epoch.row.env_steps), (2, 128));
    assert!(epoch.row.time_s >= 1.0, "elapsed time carries over");
}

#[test]
fn the_host_and_burn_actors_act_alike_on_the_built_in_mlp() {
    let (obs_dim, n) = (3, 5);
    for action in [
        apo_core::ActionKind::Continuous { dim: 2 },
        apo_core::ActionKind::Discrete { n: 4 },
    ] {
        let config = small(Algorithm::Apo, "x", 1, 10);
        let family = config.mlp_policy(obs_dim, action);
        let value = config.value(obs_dim);
        let learner = Learner::<NdArray, MlpPolicyConfig>::new(
            family,
            action,
            &value,
            config.algo.clone(),
            &Default::default(),
            3,
        )
        .expect("valid");
        let mut host = <HostActor as Actor<NdArray, _>>::from_learner(&learner, &value);
        let mut burn =
            <BurnActor<MlpPolicyConfig> as Actor<NdArray, _>>::from_learner(&learner, &value);
        let mut rng = StdRng::seed_from_u64(0);
        let obs: Vec<f32> = (0..n * obs_dim)
            .map(|_| rng.random_range(-2.0..2.0))
            .collect();
        let (mut a, mut b) = (ActBuffers::default(), ActBuffers::default());
        host.act(&obs, n, false, &mut StdRng::seed_from_u64(9), &mut a);
        burn.act(&obs, n, false, &mut StdRng::seed_from_u64(9), &mut b);
        let close = |x: &[f32], y: &[f32], what: &str| {
            assert_eq!(x.len(), y.len(), "{what}");
            for (i, (x, y)) in x.iter().zip(y).enumerate() {
                assert!((x - y).abs() < 1e-4, "{action:?} {what}[{i}]: {x} vs {y}");
            }
        };
        close(&a.dist, &b.dist, "dist");
        close(&a.actions, &b.actions, "actions");
        close(&a.env_actions, &b.env_actions, "env_actions");
        close(&a.logp, &b.logp, "logp");
        let host_v = host.values(&obs, n).to_vec();
        close(&host_v, burn.values(&obs, n), "values");
    }
}

#[test]
fn any_policy_family_trains_through_the_loop_with_the_burn_actor() {
    let config = small(Algorithm::Papo, "Pendulum-v1", 2, 100);
    let mut trainer = Trainer::<NdArray, MlpPolicyConfig, BurnActor<_>>::new(
        config,
        &Default::default(),
        1,
        |config, obs, action| config.mlp_policy(obs, action),
    )
    .expect("valid");
    let before = trainer.learner().policy_params();
    let stop = AtomicBool::new(false);
    let mut steps = Vec::new();
    while let Some(epoch) = trainer.epoch(&stop, &mut |_| {}).expect("finite") {
        assert!(epoch.row.kl.is_finite() && epoch.update.proximal.is_some());
        steps.push(epoch.row.env_steps);
    }
    assert_eq!(steps, vec![100, 200]);
    assert_ne!(
        trainer.learner().policy_params(),
        before,
        "the policy learned"
    );
}

#[test]
fn espo_alphappo_and_vmpo_train_on_cartpole_and_pendulum_without_nan() {
    let stop = AtomicBool::new(false);
    for algo in [Algorithm::Espo, Algorithm::AlphaPpo, Algorithm::Vmpo] {
        for env in ["CartPole-v1", "Pendulum-v1"] {
            let what = format!("{algo} on {env}");
            let config = small(algo, env, 3, 400);
            let mut trainer =
                Trainer::<NdArray, _, _>::mlp(config, &Default::default(), 1).expect("valid");
            let mut epochs = 0;
            while let Some(epoch) = trainer.epoch(&stop, &mut |_| {}).expect("finite") {
                epochs += 1;
                let row = &epoch.row;
                for (name, v) in [
                    ("kl", row.kl),
                    ("loss_pi", row.loss_pi),
                    ("mean_surr", row.mean_surr),
                    ("entropy", row.entropy),
                    ("loss_v", row.loss_v),
                ] {
                    assert!(v.is_finite(), "{what}, epoch {epochs}: {name} = {v}");
                }
                assert!(row.pi_steps >= Some(1), "{what}: {row:?}");
                assert!(row.episodes > 0, "{what}: no episode ended");
                assert_eq!(row.ratio_deviation.is_some(), algo == Algorithm::Espo);
                assert_eq!(row.eta.is_some(), algo == Algorithm::Vmpo);
                for m in [row.eta, row.alpha].into_iter().flatten() {
                    assert!(m.is_finite() && m >= 1e-8, "{what}: multiplier {m}");
                }
            }
            assert_eq!(epochs, 3, "{what}");
        }
    }
}

/// Every epoch's rows of a run of `config`.
fn rows(config: TrainConfig) -> Vec<apo_train::ProgressRow> {
    let mut trainer = Trainer::<NdArray, _, _>::mlp(config, &Default::default(), 1).expect("valid");
    let stop = AtomicBool::new(false);
    let mut rows = Vec::new();
    while let Some(epoch) = trainer.epoch(&stop, &mut |_| {}).expect("finite") {
        rows.push(epoch.row.timeless());
    }
    rows
}

#[test]
fn evaluation_changes_no_training_number_and_is_reproducible() {
    // normalized observations: the evaluation reads the statistics and must not update them
    let mut config = small(Algorithm::Apo, "Pendulum-v1", 4, 400);
    config.normalize_obs = true;
    let plain = rows(config.clone());
    config.eval_every = 2;
    config.eval_episodes = 3;
    config.eval_deterministic = false;
    let evaluated = rows(config.clone());
    assert_eq!(evaluated.len(), 4);
    for (e, p) in evaluated.iter().zip(&plain) {
        assert_eq!(&e.clone().without_evaluation(), p, "epoch {}", p.epoch);
    }
    // epochs 2 and 4 evaluate 3 Pendulum episodes of 200 steps
    for row in &evaluated {
        let evaluates = row.epoch % 2 == 0;
        assert_eq!(
            row.eval_ret_mean.is_some(),
            evaluates,
            "epoch {}",
            row.epoch
        );
        if evaluates {
            assert_eq!(row.eval_len_mean, Some(200.0));
            assert_eq!(row.eval_unstable_episodes, Some(0));
            let (mean, min) = (row.eval_ret_mean.unwrap(), row.eval_ret_min.unwrap());
            assert!(min <= mean && mean < 0.0, "{row:?}");
            // three episodes: CVaR 10 % is the worst one
            assert_eq!(row.eval_ret_cvar10, Some(min));
        }
    }
    assert_eq!(
        rows(config.clone()),
        evaluated,
        "same seed, same evaluation"
    );
    // the deterministic evaluation acts differently from the sampled one
    config.eval_deterministic = true;
    let deterministic = rows(config);
    assert_ne!(deterministic[1].eval_ret_mean, evaluated[1].eval_ret_mean);
    assert_eq!(
        deterministic[1].clone().without_evaluation(),
        evaluated[1].clone().without_evaluation()
    );
}

#[test]
fn evaluation_needs_a_registered_environment() {
    let mut config = small(Algorithm::Ppo, "CartPole-v1", 1, 32);
    config.eval_every = 1;
    let envs = apo_envs::VecEnv::make("CartPole-v1", 2).expect("envs");
    let error = Trainer::<NdArray, _, HostActor>::from_envs(
        config.clone(),
        envs,
        &Default::default(),
        |c, o, a| c.mlp_policy(o, a),
    )
    .err()
    .expect("refused");
    assert!(error.to_string().contains("eval_every"), "{error}");
    config.eval_episodes = 0;
    let error = Trainer::<NdArray, _, _>::mlp(config, &Default::default(), 1)
        .err()
        .expect("refused");
    assert!(error.to_string().contains("eval_episodes"), "{error}");
}
