#![warn(missing_docs)]
//! # apo-core
//!
//! Absolute Policy Optimization (APO), Proximal APO (PAPO) and the baselines TRPO, PPO, A2C,
//! ESPO, AlphaPPO and V-MPO, written as Burn tensor graphs and generic over the Burn backend.
//!
//! * [`policy`], [`value`], [`distribution`] — the networks and their distributions;
//! * [`buffer`] — the rollout buffer with one-step advantages, GAE and rewards-to-go;
//! * [`objective`] — every objective, term by term, with the paper's names;
//! * [`trust_region`] — conjugate gradient on Fisher-vector products, step scaling, line search;
//! * [`fisher`] — the trust region's Fisher-vector product `Jᵀ M J v / N` by a JVP (the
//!   policy's forward-mode one, or a finite difference) and one backward pass: first
//!   derivatives only, so `burn::nn` policies work;
//! * [`proximal`] — Adam with early stopping (KL or ratio deviation), and the value update;
//! * [`kernels`] — where the Fisher-vector products, the proximal policy steps and the value fit run: Burn's graph, or
//!   fused host kernels;
//! * [`metrics`] — per-epoch statistics, the bound `J − k·Var` and its confidence;
//! * [`algorithm`] — one module per algorithm: its settings, defaults and policy step;
//! * [`collective`] — data-parallel updates: global means and summed gradients across ranks;
//! * [`learner`] — one object that updates a policy and a critic with any algorithm.
//!
//! apo-core knows no environment: it updates networks from batches ([`Batch`], filled by a
//! [`RolloutBuffer`]). The training loop with environments, rollouts and metrics is the
//! `apo-train` crate; the environments are `apo-envs`.
//!
//! # Backends
//!
//! Everything is generic over a plain Burn backend `B` — `NdArray` on the CPU, `Wgpu` on a
//! GPU (or Mesa's software Vulkan device). Pass the plain backend, not `Autodiff<B>`: the
//! [`Learner`] keeps its networks on `Autodiff<B>` itself and evaluates on `B`.
//!
//! # Your own policy
//!
//! A policy is a Burn module that implements [`Policy`] (observations `[batch, obs_dim]` →
//! the parameters of its action distributions, [`DistParams`]), described by a
//! [`PolicyFamily`]: a plain config that builds the same module on any backend. Any
//! `burn::nn` layer will do — every algorithm needs first derivatives only.
//!
//! ```
//! use apo_core::{
//!     ActionKind, AlgoConfig, Algorithm, DistParams, Learner, Policy, PolicyFamily, ValueConfig,
//! };
//! use burn::backend::NdArray;
//! use burn::module::{Module, Param};
//! use burn::nn::{Linear, LinearConfig};
//! use burn::tensor::backend::Backend;
//! use burn::tensor::Tensor;
//!
//! /// A Gaussian policy: means from two `nn::Linear` layers, a learned log-std per action.
//! #[derive(Module, Debug)]
//! struct Gaussian<B: Backend> {
//!     hidden: Linear<B>,
//!     mean: Linear<B>,
//!     log_std: Param<Tensor<B, 1>>,
//! }
//!
//! impl<B: Backend> Policy<B> for Gaussian<B> {
//!     fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
//!         let mean = self.mean.forward(self.hidden.forward(obs).tanh()); // [batch, act]
//!         let log_std = self.log_std.val().unsqueeze_dim::<2>(0).expand(mean.dims());
//!         DistParams::Gaussian { mean, log_std }
//!     }
//! }
//!
//! /// The sizes; builds the policy on any backend.
//! #[derive(Debug, Clone)]
//! struct GaussianConfig {
//!     obs: usize,
//!     act: usize,
//! }
//!
//! impl PolicyFamily for GaussianConfig {
//!     type Policy<B: Backend> = Gaussian<B>;
//!     fn init<B: Backend>(&self, device: &B::Device) -> Gaussian<B> {
//!         Gaussian {
//!             hidden: LinearConfig::new(self.obs, 32).init(device),
//!             mean: LinearConfig::new(32, self.act).init(device),
//!             log_std: Param::from_tensor(Tensor::full([self.act], -0.5, device)),
//!         }
//!     }
//! }
//!
//! let (obs, act) = (3, 1);
//! let device = Default::default();
//! let learner = Learner::<NdArray, _>::new(
//!     GaussianConfig { obs, act },
//!     ActionKind::Continuous { dim: act },
//!     &ValueConfig { observation_dim: obs, hidden: vec![32] },
//!     AlgoConfig::paper_defaults(Algorithm::Apo),
//!     &device,
//!     0,
//! )?;
//! // a copy of the current policy on the backend of the rollout
//! let policy = learner.policy_on::<NdArray>(&device);
//! let DistParams::Gaussian { mean, .. } = policy.distribution(Tensor::zeros([5, obs], &device))
//! else {
//!     unreachable!("a Gaussian policy")
//! };
//! assert_eq!(mean.dims(), [5, act]);
//! # Ok::<(), apo_core::ConfigError>(())
//! ```
//!
//! [`Learner::update`] then takes a [`Batch`] per epoch. `apo_train::Trainer` collects those
//! batches from environments and runs the epochs; its crate docs show the whole loop.

mod activation;
mod adam;
pub mod algorithm;
pub mod buffer;
pub mod collective;
pub mod distribution;
pub mod fisher;
pub mod flat;
mod host_head;
mod host_net;
mod host_proximal;
pub mod hvp;
pub mod inference;
pub mod kernels;
pub mod learner;
pub mod metrics;
pub mod mlp;
pub mod objective;
pub mod policy;
pub mod proximal;
pub mod shaping;
pub mod tensor_batch;
pub mod trust_region;
mod validate;
pub mod value;
mod value_fit;

pub use algorithm::{
    AlgoConfig, Algorithm, AlgorithmConfig, ConfigError, HMaxMode, PolicyStep, Settings,
};
pub use buffer::{Batch, BufferLayout, PathEnd, RolloutBuffer};
pub use collective::{Collective, Comm, Solo};
pub use distribution::DistParams;
pub use fisher::FisherOperator;
pub use kernels::Kernels;
pub use learner::{Learner, UpdateError, UpdateReport};
pub use metrics::EpisodeStats;
pub use objective::{
    ApoParams, HMax, Multipliers, Objective, ObjectiveTerms, PenaltyUnits, Switch, VmpoParams,
};
pub use policy::{ActionKind, MlpPolicy, MlpPolicyConfig, Policy, PolicyError, PolicyFamily};
pub use proximal::{ProximalConfig, ProximalReport, ProximalStep};
pub use shaping::{Shaped, ShapingError, ShapingReport, ShapingRule, ShapingState};
pub use tensor_batch::TensorBatch;
pub use trust_region::{
    Acceptance, LineSearchOutcome, Rejections, TrustRegionConfig, TrustRegionReport,
};
pub use validate::shown;
pub use value::{ValueConfig, ValueNet};
