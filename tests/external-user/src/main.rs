//! The three stories of a Burn user, written outside apo's workspace against the public API
//! only, each trained for a few epochs and checked:
//!
//! 1. a registered environment (Pendulum-v1) with the built-in MLP, APO;
//! 2. a policy of `burn::nn` layers (Linear, LayerNorm) on a registered environment
//!    (CartPole-v1), TRPO and APO, on NdArray and (with `--wgpu`) on wgpu;
//! 3. an environment of its own (`impl Env`, seeded through `apo_envs::rng`) with the
//!    built-in MLP and with the `burn::nn` policy, through `Trainer::from_envs`;
//! 4. a run in a directory (`apo_train::Run`): 3 epochs, a checkpoint, everything dropped,
//!    resumed from the directory alone, 3 more epochs — the networks, `progress.csv` and
//!    `episodes.csv` equal those of 6 epochs straight, with the built-in MLP and with the
//!    `burn::nn` policy.
//!
//! `cargo run --manifest-path tests/external-user/Cargo.toml [-- --wgpu]`; exits non-zero
//! with the failed check on stderr.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use anyhow_free::{ensure, Result};
use apo_core::{ActionKind, Algorithm, DistParams, Policy, PolicyFamily};
use apo_envs::rng::{reseed, EnvRng, Rng, SeedableRng};
use apo_envs::{Action, Env, Space, Transition, VecEnv};
use apo_train::{BurnActor, HostActor, Launch, ProgressRow, Run, RunConfig, TrainConfig, Trainer};
use burn::backend::{NdArray, Wgpu};
use burn::module::{AutodiffModule, Module};
use burn::nn::{LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

/// A tiny error type: no dependency beyond the three crates and Burn.
mod anyhow_free {
    pub type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

    macro_rules! ensure {
        ($cond:expr, $($msg:tt)+) => {
            if !$cond {
                return Err(format!($($msg)+).into());
            }
        };
    }
    pub(crate) use ensure;
}

// ---------------------------------------------------------------------------------------
// A policy of `burn::nn` layers, Gaussian or categorical by the action kind
// ---------------------------------------------------------------------------------------

/// Linear → LayerNorm → tanh → Linear: the means of a Gaussian (with state-independent
/// log-stds) or the logits of a categorical.
#[derive(Module, Debug)]
struct NnPolicy<B: Backend> {
    hidden: Linear<B>,
    norm: LayerNorm<B>,
    out: Linear<B>,
    /// `[action_dim]` for a Gaussian; absent for a categorical.
    log_std: Option<burn::module::Param<Tensor<B, 1>>>,
}

impl<B: Backend> Policy<B> for NnPolicy<B> {
    fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
        let h = self.norm.forward(self.hidden.forward(obs)).tanh();
        let out = self.out.forward(h);
        match &self.log_std {
            Some(log_std) => {
                let log_std = log_std.val().unsqueeze_dim::<2>(0).expand(out.dims());
                DistParams::Gaussian { mean: out, log_std }
            }
            None => DistParams::Categorical { logits: out },
        }
    }
}

#[derive(Debug, Clone)]
struct NnPolicyConfig {
    obs: usize,
    action: ActionKind,
}

impl PolicyFamily for NnPolicyConfig {
    type Policy<B: Backend> = NnPolicy<B>;

    fn init<B: Backend>(&self, device: &B::Device) -> NnPolicy<B> {
        let width = self.action.width();
        NnPolicy {
            hidden: LinearConfig::new(self.obs, 32).init(device),
            norm: LayerNormConfig::new(32).init(device),
            out: LinearConfig::new(32, width).init(device),
            log_std: match self.action {
                ActionKind::Continuous { dim } => Some(burn::module::Param::from_tensor(
                    Tensor::full([dim], -0.5, device),
                )),
                ActionKind::Discrete { .. } => None,
            },
        }
    }
}

fn nn_family(_: &TrainConfig, obs: usize, action: ActionKind) -> NnPolicyConfig {
    NnPolicyConfig { obs, action }
}

// ---------------------------------------------------------------------------------------
// An environment of our own
// ---------------------------------------------------------------------------------------

/// Steer a point on a line to 0: observe x, act a ∈ [-1, 1], x += 0.2·a, reward −x²; the
/// episode is cut after 20 steps.
struct Steer {
    obs_space: Space,
    action_space: Space,
    x: f32,
    t: usize,
    rng: EnvRng,
}

impl Steer {
    fn boxed() -> Box<dyn Env> {
        Box::new(Self {
            obs_space: Space::uniform_box(1, -5.0, 5.0),
            action_space: Space::uniform_box(1, -1.0, 1.0),
            x: 0.0,
            t: 0,
            rng: EnvRng::seed_from_u64(0),
        })
    }
}

impl Env for Steer {
    fn observation_space(&self) -> &Space {
        &self.obs_space
    }
    fn action_space(&self) -> &Space {
        &self.action_space
    }
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        reseed(&mut self.rng, seed);
        self.x = self.rng.random_range(-1.0..1.0);
        self.t = 0;
        obs[0] = self.x;
    }
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let a = match action {
            Action::Continuous(a) => a[0].clamp(-1.0, 1.0),
            Action::Discrete(_) => 0.0,
        };
        self.x += 0.2 * a;
        self.t += 1;
        obs[0] = self.x;
        Transition {
            reward: -f64::from(self.x * self.x),
            truncated: self.t >= 20,
            ..Default::default()
        }
    }
}

// ---------------------------------------------------------------------------------------
// The stories
// ---------------------------------------------------------------------------------------

fn config(algo: Algorithm, env: &str, epochs: usize, steps: usize) -> TrainConfig {
    let mut config = TrainConfig::defaults(algo, env);
    config.epochs = epochs;
    config.steps_per_epoch = steps;
    config.num_envs = 2;
    config
}

/// Every epoch of `trainer`, with its rows checked finite.
fn run<B: Backend, F: PolicyFamily, A: apo_train::Actor<B, F>>(
    what: &str,
    mut trainer: Trainer<B, F, A>,
) -> Result<Vec<ProgressRow>>
where
    F::Policy<burn::backend::Autodiff<B>>: AutodiffModule<burn::backend::Autodiff<B>>,
{
    let before = trainer.learner().policy_params();
    let stop = AtomicBool::new(false);
    let mut rows = Vec::new();
    while let Some(epoch) = trainer.epoch(&stop, &mut |_| {})? {
        ensure!(epoch.row.kl.is_finite(), "{what}: KL {}", epoch.row.kl);
        rows.push(epoch.row);
    }
    ensure!(
        trainer.learner().policy_params() != before,
        "{what}: the policy did not move"
    );
    let first = rows.first().and_then(|r| r.ep_ret_mean).unwrap_or(f64::NAN);
    let last = rows.last().and_then(|r| r.ep_ret_mean).unwrap_or(f64::NAN);
    println!(
        "{what}: {} epochs, mean return {first:.3} -> {last:.3}",
        rows.len()
    );
    Ok(rows)
}

/// Story 2 on backend `B`: the `burn::nn` policy on CartPole with TRPO and APO; every trust
/// region step accepted inside δ.
fn nn_policy_on_cartpole<B: Backend>(device: &B::Device, backend: &str) -> Result<()> {
    for algo in [Algorithm::Trpo, Algorithm::Apo] {
        let trainer =
            Trainer::<B, _>::new(config(algo, "CartPole-v1", 3, 256), device, 1, nn_family)?;
        let rows = run(
            &format!("2. nn policy, CartPole-v1, {algo:?}, {backend}"),
            trainer,
        )?;
        for row in &rows {
            let accepted = row
                .line_search
                .as_deref()
                .is_some_and(|l| l.starts_with("accepted"));
            ensure!(
                accepted,
                "{algo:?} on {backend}: line search {:?}",
                row.line_search
            );
        }
    }
    Ok(())
}

/// Trains `run` to its end, or for `epochs` epochs.
fn epochs_of<F: PolicyFamily, A: apo_train::Actor<NdArray, F>>(
    run: &mut Run<NdArray, F, A>,
    epochs: Option<usize>,
) -> Result<usize>
where
    F::Policy<burn::backend::Autodiff<NdArray>>: AutodiffModule<burn::backend::Autodiff<NdArray>>,
{
    let stop = AtomicBool::new(false);
    let mut done = 0;
    while epochs.is_none_or(|n| done < n) && run.epoch(&stop, &mut |_| {})?.is_some() {
        done += 1;
    }
    Ok(done)
}

/// What a run leaves that must not depend on where it stopped: its networks, its
/// `progress.csv` without the wall-clock columns, its `episodes.csv`.
type Outcome = (Vec<f64>, Vec<f64>, Vec<ProgressRow>, Vec<u8>);

fn outcome<F: PolicyFamily, A: apo_train::Actor<NdArray, F>>(
    run: &Run<NdArray, F, A>,
) -> Result<Outcome>
where
    F::Policy<burn::backend::Autodiff<NdArray>>: AutodiffModule<burn::backend::Autodiff<NdArray>>,
{
    let rows = apo_train::progress_csv::read(&run.dir().join("progress.csv"))?;
    Ok((
        run.trainer().learner().policy_params(),
        run.trainer().learner().value_params(),
        rows.into_iter().map(ProgressRow::timeless).collect(),
        std::fs::read(run.dir().join("episodes.csv"))?,
    ))
}

/// Story 4: a run stopped after 3 epochs and resumed from its directory equals 6 straight.
fn resume_from_the_directory(root: &Path) -> Result<()> {
    let device = Default::default();
    let launch = Launch::new(1);
    let mut config = RunConfig::defaults(Algorithm::Apo, "CartPole-v1");
    config.train.epochs = 6;
    config.train.steps_per_epoch = 256;
    config.train.num_envs = 2;

    // the built-in MLP
    let mut straight =
        Run::<NdArray>::create(&root.join("mlp-6"), config.clone(), &launch, &device, false)?;
    epochs_of(&mut straight, None)?;
    let six = outcome(&straight)?;
    drop(straight);
    let split = root.join("mlp-3+3");
    let mut run = Run::<NdArray>::create(&split, config.clone(), &launch, &device, false)?;
    ensure!(epochs_of(&mut run, Some(3))? == 3, "4. MLP: 3 epochs");
    run.checkpoint()?;
    drop(run);
    let mut run = Run::<NdArray>::resume(&split, &launch, &device, None)?;
    ensure!(
        epochs_of(&mut run, None)? == 3 && run.finished(),
        "4. MLP: 3 more epochs"
    );
    ensure!(
        outcome(&run)? == six,
        "4. MLP: 3 + 3 epochs differ from 6 straight"
    );
    println!(
        "4. built-in MLP, CartPole-v1, APO: 3 + 3 epochs resumed from the directory = 6 straight"
    );

    // our own burn::nn policy
    type NnRun = Run<NdArray, NnPolicyConfig, BurnActor<NnPolicyConfig>>;
    let make = |config, threads| Trainer::new(config, &device, threads, nn_family);
    let mut straight = NnRun::create_with(
        &root.join("nn-6"),
        config.clone(),
        &launch,
        &device,
        false,
        make,
    )?;
    epochs_of(&mut straight, None)?;
    let six = outcome(&straight)?;
    drop(straight);
    let split = root.join("nn-3+3");
    let mut run = NnRun::create_with(&split, config, &launch, &device, false, make)?;
    ensure!(epochs_of(&mut run, Some(3))? == 3, "4. nn: 3 epochs");
    run.checkpoint()?;
    drop(run);
    let mut run = NnRun::resume_with(&split, &launch, &device, None, make)?;
    ensure!(
        epochs_of(&mut run, None)? == 3 && run.finished(),
        "4. nn: 3 more epochs"
    );
    ensure!(
        outcome(&run)? == six,
        "4. nn: 3 + 3 epochs differ from 6 straight"
    );
    println!(
        "4. nn policy, CartPole-v1, APO: 3 + 3 epochs resumed from the directory = 6 straight"
    );
    Ok(())
}

fn main() -> Result<()> {
    let wgpu = std::env::args().any(|a| a == "--wgpu");
    let device = Default::default();

    // 1. a registered environment, the built-in MLP
    let trainer =
        Trainer::<NdArray, _, _>::mlp(config(Algorithm::Apo, "Pendulum-v1", 2, 400), &device, 1)?;
    let rows = run("1. built-in MLP, Pendulum-v1, APO", trainer)?;
    ensure!(
        rows.len() == 2 && rows[1].env_steps == 800,
        "1: {} rows",
        rows.len()
    );

    // 2. our own burn::nn policy on a registered environment
    nn_policy_on_cartpole::<NdArray>(&device, "NdArray")?;
    if wgpu {
        nn_policy_on_cartpole::<Wgpu>(&Default::default(), "wgpu")?;
    }

    // 3. our own environment: with the built-in MLP, then with the burn::nn policy
    let envs = || VecEnv::new(vec![Steer::boxed(), Steer::boxed()]);
    let trainer = Trainer::<NdArray, _, HostActor>::from_envs(
        config(Algorithm::Trpo, "steer", 3, 400),
        envs()?,
        &device,
        |config, obs, action| config.mlp_policy(obs, action),
    )?;
    run("3. built-in MLP, own Env, TRPO", trainer)?;
    let trainer = Trainer::<NdArray, _>::from_envs(
        config(Algorithm::Apo, "steer", 3, 400),
        envs()?,
        &device,
        nn_family,
    )?;
    run("3. nn policy, own Env, APO", trainer)?;

    // a key from_envs cannot apply is refused by name, not ignored
    let mut limited = config(Algorithm::Trpo, "steer", 1, 400);
    limited.max_episode_steps = 10;
    let refused = Trainer::<NdArray, _>::from_envs(limited, envs()?, &device, nn_family);
    match refused {
        Err(e) => ensure!(e.to_string().contains("max_episode_steps"), "refusal: {e}"),
        Ok(_) => return Err("from_envs accepted max_episode_steps".into()),
    }
    // 4. a run in a directory, stopped, dropped and resumed
    let root = std::env::temp_dir().join(format!("apo-external-user-{}", std::process::id()));
    let resumed = resume_from_the_directory(&root);
    std::fs::remove_dir_all(&root)?;
    resumed?;
    println!("external user: every story trained");
    Ok(())
}
