//! Training your own Burn policy module with APO.
//!
//! The task is a one-step problem: observe `s ~ U(-1, 1)²`, act `a ∈ R²`, receive
//! `r = −‖a − A s‖²` for a fixed matrix `A`, and the episode ends. The policy is a custom
//! module — a linear Gaussian with a learned log-std — that implements [`Policy`]; its config
//! implements [`PolicyFamily`], which is all [`Learner`] needs to run APO (or PAPO, TRPO,
//! PPO, A2C) on it. Implementing the optional [`Policy::distribution_jvp`] as well (forward-mode
//! tangents of the distribution parameters) would let the trust-region step of APO and TRPO use
//! the cheaper Fisher-vector product instead of double-backward Hessian-vector products.
//!
//! Run with `cargo run --release -p apo-core --example custom_policy`.

use apo_core::flat::to_host;
use apo_core::{
    ActionKind, AlgoConfig, Algorithm, BufferLayout, DistParams, Learner, Policy, PolicyFamily,
    RolloutBuffer, ValueConfig,
};
use burn::backend::NdArray;
use burn::module::{Module, Param};
use burn::tensor::backend::Backend;
use burn::tensor::{Distribution, Tensor, TensorData};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

/// `a ~ N(s·W + b, exp(log_std)²)`.
#[derive(Module, Debug)]
struct LinearGaussian<B: Backend> {
    weight: Param<Tensor<B, 2>>,
    bias: Param<Tensor<B, 1>>,
    log_std: Param<Tensor<B, 1>>,
}

impl<B: Backend> Policy<B> for LinearGaussian<B> {
    fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
        let mean = obs.matmul(self.weight.val()) + self.bias.val().unsqueeze_dim(0);
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
            weight: Param::from_tensor(Tensor::random(
                [self.obs, self.act],
                Distribution::Normal(0.0, 0.1),
                device,
            )),
            bias: Param::from_tensor(Tensor::zeros([self.act], device)),
            log_std: Param::from_tensor(Tensor::full([self.act], -0.5, device)),
        }
    }
}

const TARGET: [[f32; 2]; 2] = [[0.8, -0.5], [0.3, 0.9]];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    type B = NdArray;
    let device = Default::default();
    let (obs_dim, act_dim, batch) = (2, 2, 1024);
    let family = LinearGaussianConfig {
        obs: obs_dim,
        act: act_dim,
    };
    let action = ActionKind::Continuous { dim: act_dim };
    let value = ValueConfig {
        observation_dim: obs_dim,
        hidden: vec![16],
    };
    let mut config = AlgoConfig::paper_defaults(Algorithm::Apo);
    config.omega1 = 1e-3;
    let mut learner = Learner::<B, _>::new(family, action, &value, config, &device, 0)?;
    let layout = BufferLayout {
        observation_dim: obs_dim,
        action_width: act_dim,
        dist_width: 2 * act_dim,
    };
    let mut buffer = RolloutBuffer::new(layout, 0.99, 0.97, batch);
    let mut rng = StdRng::seed_from_u64(0);

    for epoch in 1..=40 {
        // act with a copy of the current policy on the plain backend
        let policy = learner.policy_on::<B>(&device);
        let critic = learner.value_on::<B>(&value, &device);
        let obs: Vec<f32> = (0..batch * obs_dim)
            .map(|_| rng.random_range(-1.0..1.0))
            .collect();
        let obs_t =
            Tensor::<B, 2>::from_data(TensorData::new(obs.clone(), [batch, obs_dim]), &device);
        let DistParams::Gaussian { mean, log_std } = policy.distribution(obs_t.clone()) else {
            unreachable!("a Gaussian policy")
        };
        let (mean_h, log_std_h) = (to_host(mean.clone()), to_host(log_std.clone()));
        let actions: Vec<f32> = mean_h
            .iter()
            .zip(&log_std_h)
            .map(|(m, s)| (m + s.exp() * rng.sample::<f64, _>(StandardNormal)) as f32)
            .collect();
        let act_t =
            Tensor::<B, 2>::from_data(TensorData::new(actions.clone(), [batch, act_dim]), &device);
        let dist = DistParams::Gaussian { mean, log_std };
        let logp = to_host(dist.log_prob(act_t));
        let values = to_host(critic.forward(obs_t));

        let mut total = 0.0;
        for i in 0..batch {
            let (s, a) = (
                &obs[i * obs_dim..(i + 1) * obs_dim],
                &actions[i * act_dim..(i + 1) * act_dim],
            );
            let reward: f32 = (0..act_dim)
                .map(|j| {
                    let target = TARGET[j][0] * s[0] + TARGET[j][1] * s[1];
                    -(a[j] - target).powi(2)
                })
                .sum();
            total += reward;
            let dist_row: Vec<f32> = (0..act_dim)
                .map(|j| mean_h[i * act_dim + j] as f32)
                .chain((0..act_dim).map(|j| log_std_h[i * act_dim + j] as f32))
                .collect();
            buffer.store(s, a, logp[i] as f32, &dist_row, values[i] as f32, reward);
            buffer.finish_path(0.0); // one-step episodes end by termination
        }
        let report = learner.update(&buffer.take(), &mut rng);
        if epoch % 5 == 0 {
            println!(
                "epoch {epoch:2}: mean reward {:+.4}  kl {:.4}  line search {:?}",
                total / batch as f32,
                report.kl,
                report.line_search
            );
        }
    }
    Ok(())
}
