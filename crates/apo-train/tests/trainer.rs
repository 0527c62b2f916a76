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

/// A run of `config` with the environments on `threads` threads, from epoch `from` of
/// `resume` (a trainer to copy the networks, optimizers and counters from) when given: every
/// epoch's row without its time columns, then the final policy and critic parameters.
fn run_from(
    config: TrainConfig,
    threads: usize,
    resume: Option<&Trainer<NdArray, MlpPolicyConfig, HostActor>>,
) -> (Vec<apo_train::ProgressRow>, Vec<f64>, Vec<f64>) {
    let mut trainer =
        Trainer::<NdArray, _, _>::mlp(config, &Default::default(), threads).expect("valid");
    if let Some(from) = resume {
        let (policy, value) = from.learner().networks();
        let (policy_optim, value_optim) = from.learner().optimizers();
        let learner = trainer.learner_mut();
        learner.restore(
            policy.clone(),
            value.clone(),
            policy_optim.clone(),
            value_optim.clone(),
        );
        if let Some(m) = from.learner().multipliers() {
            learner.restore_multipliers(*m);
        }
        trainer
            .restore(from.state().clone())
            .expect("within the run");
    }
    let stop = AtomicBool::new(false);
    let mut rows = Vec::new();
    while let Some(epoch) = trainer.epoch(&stop, &mut |_| {}).expect("finite") {
        rows.push(epoch.row.timeless());
    }
    let learner = trainer.learner();
    (rows, learner.policy_params(), learner.value_params())
}

/// The pipelined epoch (the value fit on another thread while the next rollout runs) gives
/// the sequential epoch's numbers bit for bit, for every algorithm, with normalized
/// observations, minibatches, evaluation, 1 to 3 threads, and when resumed after any epoch.
#[test]
fn the_pipelined_epoch_is_the_sequential_epoch_bit_for_bit() {
    use apo_core::AlgoConfig;
    for &algo in Algorithm::ALL {
        let env = if matches!(algo, Algorithm::Vmpo | Algorithm::Trpo | Algorithm::Espo) {
            "CartPole-v1"
        } else {
            "Pendulum-v1"
        };
        let mut config = small(algo, env, 4, 300);
        config.normalize_obs = true;
        config.eval_every = 2;
        config.eval_episodes = 2;
        config.eval_deterministic = false;
        // minibatches: the value fit draws from the update's random stream on its thread
        match &mut config.algo {
            AlgoConfig::Ppo(c) => {
                c.value_update.minibatch_size = Some(64);
                c.policy_update.minibatch_size = Some(64);
            }
            AlgoConfig::Apo(c) => c.value_update.minibatch_size = Some(100),
            _ => {}
        }
        config.pipeline = false;
        let sequential = run_from(config.clone(), 1, None);
        assert_eq!(sequential.0.len(), 4);
        config.pipeline = true;
        for threads in [1, 2, 3] {
            let pipelined = run_from(config.clone(), threads, None);
            assert!(
                pipelined == sequential,
                "{algo} on {env}, {threads} threads: the pipelined run differs"
            );
        }
    }
    // resumed after any epoch: the checkpoint's networks, counters and statistics are the
    // sequential run's, and the rollout collected ahead is not part of them
    let mut config = small(Algorithm::Papo, "Pendulum-v1", 4, 300);
    config.normalize_obs = true;
    let whole = run_from(config.clone(), 2, None);
    for done in 1..4 {
        // `done` epochs of the same run, whose next rollout has already been collected
        let mut first =
            Trainer::<NdArray, _, _>::mlp(config.clone(), &Default::default(), 2).expect("valid");
        let stop = AtomicBool::new(false);
        for _ in 0..done {
            first.epoch(&stop, &mut |_| {}).expect("finite");
        }
        let rest = run_from(config.clone(), 2, Some(&first));
        assert_eq!(rest.0[..], whole.0[done..], "resumed after epoch {done}");
        assert_eq!((&rest.1, &rest.2), (&whole.1, &whole.2));
    }
}

/// A stop raised while the next epoch's rollout runs ahead drops that rollout only: the
/// epoch in progress completes, and the run resumes from it as if never stopped.
#[test]
fn a_stop_during_the_rollout_ahead_keeps_the_epoch() {
    use std::sync::atomic::Ordering;
    let mut config = small(Algorithm::Ppo, "Pendulum-v1", 3, 300);
    config.normalize_obs = true;
    let whole = run_from(config.clone(), 1, None);
    let mut trainer =
        Trainer::<NdArray, _, _>::mlp(config.clone(), &Default::default(), 1).expect("valid");
    let stop = AtomicBool::new(false);
    let first = trainer
        .epoch(&stop, &mut |_| {})
        .expect("finite")
        .expect("epoch 1");
    assert_eq!(first.row.timeless(), whole.0[0]);
    // epoch 2's steps were collected during epoch 1: raise the stop during epoch 3's
    let mut calls = 0;
    let second = trainer
        .epoch(&stop, &mut |_| {
            calls += 1;
            stop.store(true, Ordering::Relaxed);
        })
        .expect("finite")
        .expect("epoch 2 completes");
    assert!(calls > 0, "the rollout ahead reports its progress");
    assert_eq!(second.row.timeless(), whole.0[1]);
    assert_eq!(trainer.state().epoch, 2);
    let rest = run_from(config, 1, Some(&trainer));
    assert_eq!(rest.0[..], whole.0[2..]);
    assert_eq!((&rest.1, &rest.2), (&whole.1, &whole.2));
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

/// `from_envs` steps the environments as given: each config key that `Trainer::new` applies by
/// wrapping them is refused by name unless it is a no-op; with the wrapper applied by hand
/// (here `RescaleAction` around Pendulum's torque box of [-2, 2]) the trainer is built.
#[test]
fn from_envs_refuses_the_keys_it_cannot_apply_by_name() {
    let bare = || {
        let envs = (0..2)
            .map(|_| apo_envs::registry::make_with("Pendulum-v1", &unwrapped()).expect("Pendulum"))
            .collect();
        apo_envs::VecEnv::new(envs).expect("envs")
    };
    let build = |config: TrainConfig, envs| {
        Trainer::<NdArray, _>::from_envs(config, envs, &Default::default(), |c, o, a| {
            c.mlp_policy(o, a)
        })
        .err()
        .map(|e| e.to_string())
    };
    let base = small(Algorithm::Trpo, "Pendulum-v1", 1, 32);
    let mut cases: Vec<(&str, TrainConfig)> = Vec::new();
    let mut c = base.clone();
    c.max_episode_steps = 100;
    cases.push(("max_episode_steps", c));
    let mut c = base.clone();
    c.episode_reset = apo_train::EpisodeReset::RunSeed;
    cases.push(("episode_reset", c));
    let mut c = base.clone();
    c.physics = apo_envs::mujoco::Physics::Mujoco3;
    cases.push(("physics", c));
    // Pendulum's torque box is [-2, 2]: `actions = rescale` needs the wrapper
    cases.push(("actions", base.clone()));
    for (key, config) in cases {
        let error = build(config, bare()).expect("refused");
        assert!(
            error.contains(&format!("`{key}`")) && error.contains("from_envs"),
            "{key}: {error}"
        );
    }
    let mut raw = base.clone();
    raw.actions = apo_train::ActionMapping::Raw;
    assert_eq!(build(raw, bare()), None, "actions = raw on the bare box");
    let wrapped = (0..2)
        .map(|_| {
            let env = apo_envs::registry::make_with("Pendulum-v1", &unwrapped()).expect("Pendulum");
            Box::new(apo_envs::RescaleAction::new(env).expect("a box")) as Box<dyn apo_envs::Env>
        })
        .collect();
    let wrapped = apo_envs::VecEnv::new(wrapped).expect("envs");
    assert_eq!(build(base, wrapped), None, "rescaled by hand");
}

/// Pendulum as it is registered, without `RescaleAction`.
fn unwrapped() -> apo_envs::MakeOptions {
    apo_envs::MakeOptions {
        rescale_actions: false,
        ..Default::default()
    }
}

// ---------------------------------------------------------------------------------------
// Policies built from `burn::nn` layers train with the trust-region algorithms
// ---------------------------------------------------------------------------------------

/// `burn::nn` layers are differentiable once but not twice: the trust-region step must take
/// its Fisher-vector products by first-order passes (the finite-difference JVP of
/// `apo_core::fisher`). Each policy below has no `distribution_jvp`.
mod nn_policies {
    use std::sync::atomic::AtomicBool;

    use apo_core::{ActionKind, Algorithm, DistParams, Policy, PolicyFamily, PolicyStep};
    use apo_envs::rng::{reseed, EnvRng, Rng, SeedableRng};
    use apo_envs::{Action, Env, RescaleAction, Space, Transition, VecEnv};
    use apo_train::{ProgressRow, TrainConfig, Trainer};
    use burn::backend::{Autodiff, NdArray, Wgpu};
    use burn::module::{AutodiffModule, Module, Param};
    use burn::nn::conv::{Conv1d, Conv1dConfig};
    use burn::nn::{Embedding, EmbeddingConfig, LayerNorm, LayerNormConfig, Linear, LinearConfig};
    use burn::tensor::backend::Backend;
    use burn::tensor::Tensor;

    /// A one-step task: observe `s ~ U(-1, 1)^4`, act `a ∈ R²`, reward `−‖a − A s‖²`.
    struct Regress {
        obs_space: Space,
        action_space: Space,
        state: [f32; 4],
        rng: EnvRng,
    }

    impl Env for Regress {
        fn observation_space(&self) -> &Space {
            &self.obs_space
        }
        fn action_space(&self) -> &Space {
            &self.action_space
        }
        fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
            reseed(&mut self.rng, seed);
            self.state = std::array::from_fn(|_| self.rng.random_range(-1.0..1.0));
            obs.copy_from_slice(&self.state);
        }
        fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
            let s = self.state;
            let a = match action {
                Action::Continuous(a) => [a[0], a[1]],
                Action::Discrete(_) => [0.0; 2],
            };
            let target = [
                0.8 * s[0] - 0.5 * s[1] + 0.3 * s[2],
                0.3 * s[1] + 0.9 * s[3],
            ];
            let reward: f32 = a.iter().zip(target).map(|(a, t)| -(a - t).powi(2)).sum();
            obs.copy_from_slice(&s);
            Transition {
                reward: f64::from(reward),
                terminated: true,
                ..Default::default()
            }
        }
    }

    /// A one-step task: observe a token `k ∈ {0, …, 3}` (as a float), reward 1 for action
    /// `k mod 3` of 3.
    struct Lookup {
        obs_space: Space,
        action_space: Space,
        token: usize,
        rng: EnvRng,
    }

    impl Env for Lookup {
        fn observation_space(&self) -> &Space {
            &self.obs_space
        }
        fn action_space(&self) -> &Space {
            &self.action_space
        }
        fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
            reseed(&mut self.rng, seed);
            self.token = self.rng.random_range(0..4);
            obs[0] = self.token as f32;
        }
        fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
            let right = matches!(action, Action::Discrete(a) if a == self.token % 3);
            obs[0] = self.token as f32;
            Transition {
                reward: if right { 1.0 } else { 0.0 },
                terminated: true,
                ..Default::default()
            }
        }
    }

    fn regress() -> VecEnv {
        let envs = (0..4)
            .map(|_| {
                let env = Regress {
                    obs_space: Space::uniform_box(4, -1.0, 1.0),
                    action_space: Space::uniform_box(2, -2.0, 2.0),
                    state: [0.0; 4],
                    rng: EnvRng::seed_from_u64(0),
                };
                // the policy acts in [-1, 1]²: mapped to the box [-2, 2]²
                Box::new(RescaleAction::new(env).expect("a box")) as Box<dyn Env>
            })
            .collect();
        VecEnv::new(envs).expect("four environments")
    }

    fn lookup() -> VecEnv {
        let envs = (0..4)
            .map(|_| {
                Box::new(Lookup {
                    obs_space: Space::uniform_box(1, 0.0, 3.0),
                    action_space: Space::Discrete { n: 3 },
                    token: 0,
                    rng: EnvRng::seed_from_u64(0),
                }) as Box<dyn Env>
            })
            .collect();
        VecEnv::new(envs).expect("four environments")
    }

    fn log_std<B: Backend>(dim: usize, device: &B::Device) -> Param<Tensor<B, 1>> {
        Param::from_tensor(Tensor::full([dim], -0.5, device))
    }

    fn gaussian<B: Backend>(mean: Tensor<B, 2>, log_std: &Param<Tensor<B, 1>>) -> DistParams<B> {
        let log_std = log_std.val().unsqueeze_dim::<2>(0).expand(mean.dims());
        DistParams::Gaussian { mean, log_std }
    }

    /// Linear → tanh → Linear, Gaussian.
    #[derive(Module, Debug)]
    pub struct Mlp<B: Backend> {
        hidden: Linear<B>,
        out: Linear<B>,
        log_std: Param<Tensor<B, 1>>,
    }

    impl<B: Backend> Policy<B> for Mlp<B> {
        fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
            let h = self.hidden.forward(obs).tanh();
            gaussian(self.out.forward(h), &self.log_std)
        }
    }

    /// Conv1d over the observation as a 1-channel signal → tanh → Linear, Gaussian.
    #[derive(Module, Debug)]
    pub struct Conv<B: Backend> {
        conv: Conv1d<B>,
        out: Linear<B>,
        log_std: Param<Tensor<B, 1>>,
    }

    impl<B: Backend> Policy<B> for Conv<B> {
        fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
            let [n, _] = obs.dims();
            let h = self.conv.forward(obs.unsqueeze_dim::<3>(1)).tanh();
            let [_, channels, width] = h.dims();
            gaussian(
                self.out.forward(h.reshape([n, channels * width])),
                &self.log_std,
            )
        }
    }

    /// Linear → LayerNorm → tanh → Linear, Gaussian.
    #[derive(Module, Debug)]
    pub struct Normed<B: Backend> {
        hidden: Linear<B>,
        norm: LayerNorm<B>,
        out: Linear<B>,
        log_std: Param<Tensor<B, 1>>,
    }

    impl<B: Backend> Policy<B> for Normed<B> {
        fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
            let h = self.norm.forward(self.hidden.forward(obs)).tanh();
            gaussian(self.out.forward(h), &self.log_std)
        }
    }

    /// The observed token's row of an embedding table as the logits: a categorical.
    #[derive(Module, Debug)]
    pub struct Table<B: Backend> {
        table: Embedding<B>,
    }

    impl<B: Backend> Policy<B> for Table<B> {
        fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
            let [n, _] = obs.dims();
            let logits = self.table.forward(obs.int());
            let [_, _, actions] = logits.dims();
            DistParams::Categorical {
                logits: logits.reshape([n, actions]),
            }
        }
    }

    /// The four policies, each sized by the environment.
    #[derive(Debug, Clone, Copy)]
    pub struct Sizes {
        obs: usize,
        act: usize,
    }

    macro_rules! family {
        ($family:ident, $policy:ident, |$s:ident, $device:ident| $init:expr) => {
            #[derive(Debug, Clone, Copy)]
            pub struct $family(Sizes);
            impl PolicyFamily for $family {
                type Policy<B: Backend> = $policy<B>;
                fn init<B: Backend>(&self, $device: &B::Device) -> $policy<B> {
                    let $s = self.0;
                    $init
                }
            }
        };
    }

    family!(MlpFamily, Mlp, |s, device| Mlp {
        hidden: LinearConfig::new(s.obs, 16).init(device),
        out: LinearConfig::new(16, s.act).init(device),
        log_std: log_std(s.act, device),
    });
    family!(ConvFamily, Conv, |s, device| Conv {
        conv: Conv1dConfig::new(1, 3, 2).init(device),
        out: LinearConfig::new(3 * (s.obs - 1), s.act).init(device),
        log_std: log_std(s.act, device),
    });
    family!(NormedFamily, Normed, |s, device| Normed {
        hidden: LinearConfig::new(s.obs, 16).init(device),
        norm: LayerNormConfig::new(16).init(device),
        out: LinearConfig::new(16, s.act).init(device),
        log_std: log_std(s.act, device),
    });
    family!(TableFamily, Table, |s, device| Table {
        table: EmbeddingConfig::new(4, s.act).init(device),
    });

    /// `epochs` epochs of 256 steps of `algo` with the policy that `family` builds: every row,
    /// and the trust region's radius δ.
    fn train<B: Backend, F: PolicyFamily>(
        algo: Algorithm,
        epochs: usize,
        envs: VecEnv,
        device: &B::Device,
        family: fn(Sizes) -> F,
    ) -> (Vec<ProgressRow>, f64)
    where
        F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
    {
        let mut config = TrainConfig::defaults(algo, "nn-policy");
        config.epochs = epochs;
        config.steps_per_epoch = 256;
        config.num_envs = 4;
        config.hidden = vec![8];
        let PolicyStep::TrustRegion(region) = config.algo.settings().policy_step() else {
            panic!("{algo:?} is not a trust-region algorithm");
        };
        let max_kl = region.max_kl;
        // the actor defaults to BurnActor<F>, which runs any policy module
        let mut trainer =
            Trainer::<B, F>::from_envs(config, envs, device, |_, obs, action: ActionKind| {
                family(Sizes {
                    obs,
                    act: action.width(),
                })
            })
            .expect("valid settings");
        let stop = AtomicBool::new(false);
        let mut rows = Vec::new();
        while let Some(epoch) = trainer.epoch(&stop, &mut |_| {}).expect("a finite update") {
            rows.push(epoch.row);
        }
        (rows, max_kl)
    }

    /// Every update accepted a step inside the trust region, and the mean return of the
    /// last third of the epochs beats that of the first third.
    fn check<B: Backend, F: PolicyFamily>(
        name: &str,
        epochs: usize,
        envs: fn() -> VecEnv,
        device: &B::Device,
        family: fn(Sizes) -> F,
    ) where
        F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
    {
        for algo in [Algorithm::Trpo, Algorithm::Apo] {
            let (rows, delta) = train::<B, F>(algo, epochs, envs(), device, family);
            let accepted = rows
                .iter()
                .filter(|r| {
                    r.line_search
                        .as_deref()
                        .is_some_and(|l| l.starts_with("accepted"))
                })
                .count();
            let mean = |rows: &[ProgressRow]| {
                rows.iter()
                    .map(|r| r.ep_ret_mean.unwrap_or(f64::NAN))
                    .sum::<f64>()
                    / rows.len() as f64
            };
            let third = rows.len() / 3;
            let (first, last) = (mean(&rows[..third]), mean(&rows[rows.len() - third..]));
            let max_kl = rows.iter().map(|r| r.kl).fold(0.0, f64::max);
            eprintln!(
                "{name}, {algo:?}: {accepted}/{} steps accepted, return {first:.3} -> {last:.3}, max KL {max_kl:.4}",
                rows.len()
            );
            assert!(
                accepted * 4 >= rows.len() * 3,
                "{name}, {algo:?}: {accepted}/{} accepted",
                rows.len()
            );
            assert!(
                max_kl > 0.0 && max_kl <= delta,
                "{name}, {algo:?}: max KL {max_kl} (δ {delta})"
            );
            assert!(last > first, "{name}, {algo:?}: return {first} -> {last}");
        }
    }

    fn check_all<B: Backend>(epochs: usize, device: &B::Device) {
        check::<B, _>("Linear", epochs, regress, device, MlpFamily);
        check::<B, _>("Conv1d + Linear", epochs, regress, device, ConvFamily);
        check::<B, _>("LayerNorm", epochs, regress, device, NormedFamily);
        check::<B, _>(
            "Embedding (categorical)",
            epochs,
            lookup,
            device,
            TableFamily,
        );
    }

    #[test]
    fn burn_nn_policies_train_with_trpo_and_apo_on_ndarray() {
        check_all::<NdArray>(12, &Default::default());
    }

    /// Fewer epochs: each of wgpu's small kernels is a dispatch (slow on a software device).
    #[test]
    fn burn_nn_policies_train_with_trpo_and_apo_on_wgpu() {
        check_all::<Wgpu>(6, &Default::default());
    }
}

/// Pendulum whose observation turns NaN at step `at` without the step being flagged unstable,
/// as a custom environment (or a sensor) can.
struct NanAt {
    inner: Box<dyn apo_envs::Env>,
    at: usize,
    steps: usize,
}

impl apo_envs::Env for NanAt {
    fn observation_space(&self) -> &apo_envs::Space {
        self.inner.observation_space()
    }
    fn action_space(&self) -> &apo_envs::Space {
        self.inner.action_space()
    }
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.inner.reset(seed, obs);
    }
    fn step(&mut self, action: apo_envs::Action<'_>, obs: &mut [f32]) -> apo_envs::Transition {
        let transition = self.inner.step(action, obs);
        self.steps += 1;
        if self.steps == self.at {
            obs[0] = f32::NAN;
        }
        transition
    }
}

/// A non-finite observation from the environment stops the run with an error that says so and
/// describes the batch (the update only met the NaN), before the epoch counts.
#[test]
fn a_non_finite_observation_from_the_environment_is_named_in_the_error() {
    let mut config = small(Algorithm::Trpo, "Pendulum-v1", 2, 64);
    config.actions = apo_train::ActionMapping::Raw;
    let envs = (0..2)
        .map(|i| {
            let inner =
                apo_envs::registry::make_with("Pendulum-v1", &unwrapped()).expect("Pendulum");
            let at = if i == 0 { 10 } else { usize::MAX };
            Box::new(NanAt {
                inner,
                at,
                steps: 0,
            }) as Box<dyn apo_envs::Env>
        })
        .collect();
    let envs = apo_envs::VecEnv::new(envs).expect("envs");
    let mut trainer =
        Trainer::<NdArray, _>::from_envs(config, envs, &Default::default(), |c, o, a| {
            c.mlp_policy(o, a)
        })
        .expect("trainer");
    let error = trainer
        .epoch(&AtomicBool::new(false), &mut |_| {})
        .map(|report| report.is_some())
        .expect_err("a NaN observation cannot train");
    let TrainError::NonFinite { epoch, ref what } = error else {
        panic!("expected NonFinite, got {error}");
    };
    assert_eq!(epoch, 1);
    assert!(
        what.contains("the epoch's batch: 64 transitions")
            && what.contains("max |obs| ")
            && what.contains(" non-finite")
            && what.contains("the environment returned non-finite observations or rewards"),
        "{what}"
    );
    assert_eq!(trainer.state().epoch, 0, "the failed epoch does not count");
}

/// Reward 1 per step; episodes last 20 steps (truncated), except every third episode the
/// environment plays, which a simulated simulator failure ends after 2 steps (return 2).
struct FailsOnPurpose {
    space: apo_envs::Space,
    episode: usize,
    t: usize,
}

impl FailsOnPurpose {
    fn boxed() -> Box<dyn apo_envs::Env> {
        Box::new(Self {
            space: apo_envs::Space::uniform_box(1, -1.0, 1.0),
            episode: 0,
            t: 0,
        })
    }
}

impl apo_envs::Env for FailsOnPurpose {
    fn observation_space(&self) -> &apo_envs::Space {
        &self.space
    }
    fn action_space(&self) -> &apo_envs::Space {
        &self.space
    }
    fn reset(&mut self, _seed: Option<u64>, obs: &mut [f32]) {
        self.episode += 1;
        self.t = 0;
        obs[0] = 0.0;
    }
    fn step(&mut self, _action: apo_envs::Action<'_>, obs: &mut [f32]) -> apo_envs::Transition {
        self.t += 1;
        obs[0] = self.t as f32 / 20.0;
        let mut step = apo_envs::Transition {
            reward: 1.0,
            ..Default::default()
        };
        if self.episode % 3 == 1 && self.t == 2 {
            step.terminated = true;
            step.info.unstable = true;
        } else if self.t == 20 {
            step.truncated = true;
        }
        step
    }
}

/// Every episode counts: an episode a simulator failure ends enters the return statistics of
/// training and of evaluation with the return it reached, and is counted and flagged, so a
/// policy cannot raise its worst return by failing.
#[test]
fn an_environment_that_fails_on_purpose_cannot_raise_the_worst_return() {
    let mut config = small(Algorithm::Trpo, "FailsOnPurpose", 2, 200);
    config.eval_episodes = 6;
    let envs = apo_envs::VecEnv::new(vec![FailsOnPurpose::boxed(), FailsOnPurpose::boxed()])
        .expect("envs");
    let mut trainer =
        Trainer::<NdArray, _>::from_envs(config.clone(), envs, &Default::default(), |c, o, a| {
            c.mlp_policy(o, a)
        })
        .expect("trainer");
    let report = trainer
        .epoch(&AtomicBool::new(false), &mut |_| {})
        .expect("finite")
        .expect("not stopped");
    let (row, episodes) = (&report.row, &report.episodes);
    let failed: Vec<_> = episodes.iter().filter(|e| e.unstable).collect();
    assert!(!failed.is_empty(), "{episodes:?}");
    assert!(failed.iter().all(|e| e.ret == 2.0 && e.length == 2));
    assert!(episodes
        .iter()
        .filter(|e| !e.unstable)
        .all(|e| e.ret == 20.0));
    assert!(episodes
        .iter()
        .all(|e| e.phase == apo_train::Phase::Train && e.epoch == 1));
    // the failed episodes are in every statistic, counted and flagged
    assert_eq!(row.episodes, episodes.len());
    assert_eq!(row.unstable_episodes, failed.len());
    assert_eq!(
        row.ep_ret_min,
        Some(2.0),
        "the worst return is the failed episodes'"
    );
    let mean = episodes.iter().map(|e| e.ret).sum::<f64>() / episodes.len() as f64;
    assert!((row.ep_ret_mean.expect("episodes") - mean).abs() < 1e-12);
    assert!(row.ep_ret_mean < Some(20.0) && row.ep_ret_cvar10 == Some(2.0));
    // each environment's stream: seeded at the epoch's start, its episodes numbered in order
    for env in 0..2 {
        let stream: Vec<_> = episodes.iter().filter(|e| e.env == env).collect();
        assert!(stream
            .windows(2)
            .all(|w| w[0].seed == w[1].seed && w[1].nth == w[0].nth + 1));
    }
    assert_ne!(
        episodes[0].seed, episodes[1].seed,
        "two environments, two seeds"
    );

    // the evaluation counts the same way
    let mut evaluator = apo_train::Evaluator::with_env(FailsOnPurpose::boxed(), &config);
    let mut actor = <HostActor as Actor<NdArray, MlpPolicyConfig>>::from_learner(
        trainer.learner(),
        trainer.value_config(),
    );
    let evaluation = evaluator.evaluate(&mut actor, None, 7.0);
    let stats = evaluation.stats.expect("six episodes");
    assert_eq!((stats.count, evaluation.unstable), (6, 2));
    assert_eq!(stats.ret_min, 2.0);
    assert_eq!(stats.ret_mean, (4.0 * 20.0 + 2.0 * 2.0) / 6.0);
    assert_eq!(evaluation.episodes.iter().filter(|e| e.unstable).count(), 2);
}

/// PAPO without its penalty — `k = 0`, the same code path — is PPO bit for bit: every column
/// but the bound's (which is computed with `k`) agrees, so comparing PAPO with PPO on the same
/// seeds isolates the penalty. Setting ω1 = ω2 = 0 instead does not remove it: VarianceMean
/// keeps `−min_J_sq`, and PAPO with it learns differently from PPO.
#[test]
fn papo_without_its_penalty_is_ppo_bit_for_bit() {
    use apo_core::AlgoConfig;
    let rows = |algo: Algorithm, edit: &dyn Fn(&mut apo_core::algorithm::PapoConfig)| {
        // positive returns: min_J_sq's switch is on (with Pendulum's negative values it is off
        // and ω = 0 alone would make PAPO PPO too)
        let mut config = small(algo, "CartPole-v1", 3, 400);
        if let AlgoConfig::Papo(c) = &mut config.algo {
            edit(c);
        }
        let mut trainer =
            Trainer::<NdArray, _, _>::mlp(config, &Default::default(), 1).expect("valid");
        let mut rows = Vec::new();
        while let Some(report) = trainer
            .epoch(&AtomicBool::new(false), &mut |_| {})
            .expect("finite")
        {
            rows.push(apo_train::ProgressRow {
                bound: None,
                confidence: None,
                ..report.row.timeless()
            });
        }
        rows
    };
    let ppo = rows(Algorithm::Ppo, &|_| {});
    assert_eq!(rows(Algorithm::Papo, &|c| c.k = 0.0), ppo);
    let omega_zero = rows(Algorithm::Papo, &|c| {
        c.omega1 = 0.0;
        c.omega2 = 0.0;
    });
    assert_ne!(
        omega_zero.iter().map(|r| r.kl).collect::<Vec<_>>(),
        ppo.iter().map(|r| r.kl).collect::<Vec<_>>()
    );
}
