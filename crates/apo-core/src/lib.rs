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
//! * [`kernels`] — where the Fisher-vector products and the value fit run: Burn's graph, or
//!   fused host kernels;
//! * [`metrics`] — per-epoch statistics, the bound `J − k·Var` and its confidence;
//! * [`algorithm`] — one module per algorithm: its settings, defaults and policy step;
//! * [`collective`] — data-parallel updates: global means and summed gradients across ranks;
//! * [`learner`] — one object that updates a policy and a critic with any algorithm.

mod activation;
mod adam;
pub mod algorithm;
pub mod buffer;
pub mod collective;
pub mod distribution;
pub mod fisher;
pub mod flat;
mod host_net;
pub mod hvp;
pub mod inference;
pub mod kernels;
pub mod learner;
pub mod metrics;
pub mod mlp;
pub mod objective;
pub mod policy;
pub mod proximal;
pub mod tensor_batch;
pub mod trust_region;
mod validate;
pub mod value;
mod value_fit;

pub use algorithm::{
    AlgoConfig, Algorithm, AlgorithmConfig, ConfigError, HMaxMode, PolicyStep, Settings,
};
pub use buffer::{Batch, BufferLayout, RolloutBuffer};
pub use collective::{Collective, Comm, Solo};
pub use distribution::DistParams;
pub use fisher::FisherOperator;
pub use kernels::Kernels;
pub use learner::{Learner, UpdateReport};
pub use metrics::EpisodeStats;
pub use objective::{
    ApoParams, HMax, Multipliers, Objective, ObjectiveTerms, PenaltyUnits, Switch, VmpoParams,
};
pub use policy::{ActionKind, MlpPolicy, MlpPolicyConfig, Policy, PolicyError, PolicyFamily};
pub use proximal::{ProximalConfig, ProximalReport, ProximalStep};
pub use tensor_batch::TensorBatch;
pub use trust_region::{
    Acceptance, LineSearchOutcome, Rejections, TrustRegionConfig, TrustRegionReport,
};
pub use value::{ValueConfig, ValueNet};
