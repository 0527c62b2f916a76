//! Training your own Burn policy module with APO, through the same loop as `apo train`.
//!
//! The task is a one-step problem written here as an [`Env`]: observe `s ~ U(-1, 1)²`, act
//! `a ∈ [-1, 1]²`, receive `r = −‖a − A s‖²` for a fixed matrix `A`, and the episode ends. The
//! policy is a custom module — a `burn::nn::Linear` layer for the means and a learned log-std —
//! that implements [`Policy`]; its config implements [`PolicyFamily`]. `BurnActor` (the trainer's default actor) runs it in
//! the rollout on Burn's NdArray backend, and [`Trainer`] does the rest. Any `burn::nn` layer
//! works: the trust-region step needs first derivatives only. Implementing the optional
//! [`Policy::distribution_jvp`] as well (forward-mode tangents of the distribution parameters)
//! would replace the finite-difference Jacobian-vector product of its Fisher-vector products
//! by an exact one.
//!
//! Run with `cargo run --release -p apo-train --example custom_policy -- [EPOCHS]`.

use std::sync::atomic::AtomicBool;

use apo_core::{AlgoConfig, Algorithm, DistParams, Policy, PolicyFamily};
use apo_envs::rng::{reseed, EnvRng, Rng, SeedableRng};
use apo_envs::{Action, Env, Space, Transition, VecEnv};
use apo_train::{TrainConfig, Trainer};
use burn::backend::NdArray;
use burn::module::{Module, Param};
use burn::nn::{Linear, LinearConfig};
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

/// `a ~ N(s·W + b, exp(log_std)²)`.
#[derive(Module, Debug)]
struct LinearGaussian<B: Backend> {
    layer: Linear<B>,
    log_std: Param<Tensor<B, 1>>,
}

impl<B: Backend> Policy<B> for LinearGaussian<B> {
    fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
        let mean = self.layer.forward(obs);
        let log_std = self.log_std.val().unsqueeze_dim::<2>(0).expand(mean.dims());
        DistParams::Gaussian { mean, log_std }
    }
}

/// Sizes of a [`LinearGaussian`]; builds it on any backend.
#[derive(Debug, Clone)]
struct LinearGaussianConfig {
    obs: usize,
    act: usize,
}

impl PolicyFamily for LinearGaussianConfig {
    type Policy<B: Backend> = LinearGaussian<B>;

    fn init<B: Backend>(&self, device: &B::Device) -> LinearGaussian<B> {
        LinearGaussian {
            layer: LinearConfig::new(self.obs, self.act).init(device),
            log_std: Param::from_tensor(Tensor::full([self.act], -0.5, device)),
        }
    }
}

const TARGET: [[f32; 2]; 2] = [[0.8, -0.5], [0.3, 0.9]];

/// The one-step task.
struct Match {
    space: Space,
    state: [f32; 2],
    rng: EnvRng,
}

impl Env for Match {
    fn observation_space(&self) -> &Space {
        &self.space
    }
    fn action_space(&self) -> &Space {
        &self.space
    }
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        reseed(&mut self.rng, seed);
        self.state = [
            self.rng.random_range(-1.0..1.0),
            self.rng.random_range(-1.0..1.0),
        ];
        obs.copy_from_slice(&self.state);
    }
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let Action::Continuous(a) = action else {
            unreachable!("a box action space")
        };
        let s = self.state;
        let reward: f32 = (0..2)
            .map(|j| -(a[j] - (TARGET[j][0] * s[0] + TARGET[j][1] * s[1])).powi(2))
            .sum();
        obs.copy_from_slice(&s);
        Transition {
            reward: f64::from(reward),
            terminated: true,
            ..Default::default()
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let epochs = std::env::args().nth(1).map_or(Ok(40), |a| a.parse())?;
    let envs = (0..8)
        .map(|_| {
            Box::new(Match {
                space: Space::uniform_box(2, -1.0, 1.0),
                state: [0.0; 2],
                rng: EnvRng::seed_from_u64(0),
            }) as Box<dyn Env>
        })
        .collect();
    let mut config = TrainConfig::defaults(Algorithm::Apo, "match");
    config.epochs = epochs;
    config.steps_per_epoch = 1024;
    config.hidden = vec![16]; // the critic's
    if let AlgoConfig::Apo(apo) = &mut config.algo {
        apo.omega1 = 1e-3;
    }
    let mut trainer = Trainer::<NdArray, _>::from_envs(
        config,
        VecEnv::new(envs)?,
        &Default::default(),
        |_, obs, action| LinearGaussianConfig {
            obs,
            act: action.width(),
        },
    )?;
    while let Some(epoch) = trainer.epoch(&AtomicBool::new(false), &mut |_| {})? {
        if epoch.row.epoch % 5 == 0 {
            println!(
                "epoch {:2}: mean reward {:+.4}  kl {:.4}  line search {}",
                epoch.row.epoch,
                epoch.row.ep_ret_mean.unwrap_or(f64::NAN),
                epoch.row.kl,
                epoch.row.line_search.as_deref().unwrap_or("-")
            );
        }
    }
    Ok(())
}
