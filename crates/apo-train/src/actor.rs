//! How the rollout acts.
//!
//! The [`Collector`](crate::Collector) calls an [`Act`] once per vector step with the
//! observations of every environment (`[n, observation_dim]`, one batched call), and once per
//! cut path for its bootstrap value. An [`Actor`] is an [`Act`] built from a learner's current
//! networks; the [`Trainer`](crate::Trainer) rebuilds it after every update.
//!
//! Two actors come with the crate:
//! * [`HostActor`] — the built-in MLP policy and critic as plain `f32` arrays: a few
//!   microseconds per call, no allocation per step (the default, and what the CLI uses);
//! * [`BurnActor`] — any [`Policy`] module of any [`PolicyFamily`], run on Burn's NdArray
//!   backend (custom policies; slower per call, identical semantics).
//!
//! Both sample from the distribution parameters with [`ActBuffers::sample`], so for the built-in
//! MLP they draw the same random numbers in the same order.

use apo_core::inference::{ActBuffers, HostPolicy, HostValue};
use apo_core::{ActionKind, DistParams, Learner, MlpPolicyConfig, Policy, PolicyFamily};
use apo_core::{ValueConfig, ValueNet};
use burn::backend::{Autodiff, NdArray};
use burn::module::AutodiffModule;
use burn::tensor::backend::Backend;
use burn::tensor::{Tensor, TensorData};
use rand::rngs::StdRng;

/// Acts in a batch of states.
pub trait Act {
    /// Samples one action for each of the `n` states `obs: [n, observation_dim]` (already
    /// normalized), filling `out`: actions `[n, action_width]`, environment actions
    /// `[n, env_width]`, log-probabilities `[n]` and distribution parameters `[n, dist_width]`.
    /// With `deterministic`, takes the most likely action instead (a Gaussian's mean, a
    /// categorical's arg max; evaluation), drawing nothing from `rng`.
    fn act(
        &mut self,
        obs: &[f32],
        n: usize,
        deterministic: bool,
        rng: &mut StdRng,
        out: &mut ActBuffers,
    );

    /// The critic's values `V(s)` of `obs: [n, observation_dim]` → `[n]`.
    fn values(&mut self, obs: &[f32], n: usize) -> &[f32];
}

/// An [`Act`] made from a learner's current networks.
pub trait Actor<B: Backend, F: PolicyFamily>: Act + Sized
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    /// Copies `learner`'s current policy and critic (whose sizes are `value`).
    fn from_learner(learner: &Learner<B, F>, value: &ValueConfig) -> Self;
}

/// The built-in MLP policy and critic as host `f32` arrays.
#[derive(Debug, Clone)]
pub struct HostActor {
    /// The policy.
    pub policy: HostPolicy,
    /// The critic.
    pub value: HostValue,
}

impl Act for HostActor {
    fn act(
        &mut self,
        obs: &[f32],
        n: usize,
        deterministic: bool,
        rng: &mut StdRng,
        out: &mut ActBuffers,
    ) {
        self.policy.act(obs, n, deterministic, rng, out);
    }

    fn values(&mut self, obs: &[f32], n: usize) -> &[f32] {
        self.value.values(obs, n)
    }
}

impl<B: Backend> Actor<B, MlpPolicyConfig> for HostActor {
    fn from_learner(learner: &Learner<B, MlpPolicyConfig>, value: &ValueConfig) -> Self {
        let device = Default::default();
        Self {
            policy: HostPolicy::new(&learner.policy_on::<NdArray>(&device), learner.action()),
            value: HostValue::new(&learner.value_on::<NdArray>(value, &device)),
        }
    }
}

/// Any [`Policy`] module of family `F`, with the critic, run on Burn's NdArray backend.
#[derive(Debug)]
pub struct BurnActor<F: PolicyFamily> {
    policy: F::Policy<NdArray>,
    value: ValueNet<NdArray>,
    action: ActionKind,
    values: Vec<f32>,
}

impl<F: PolicyFamily> BurnActor<F> {
    fn tensor(obs: &[f32], n: usize) -> Tensor<NdArray, 2> {
        let width = obs.len() / n.max(1);
        Tensor::from_data(
            TensorData::new(obs.to_vec(), [n, width]),
            &Default::default(),
        )
    }
}

/// The rows of `[n, w]` tensors side by side: `[n, Σ w]`, on the host.
fn host_rows(parts: Vec<Tensor<NdArray, 2>>, out: &mut Vec<f32>) {
    let tensor = Tensor::cat(parts, 1);
    out.clear();
    out.extend(tensor.into_data().iter::<f32>());
}

impl<F: PolicyFamily> Act for BurnActor<F> {
    fn act(
        &mut self,
        obs: &[f32],
        n: usize,
        deterministic: bool,
        rng: &mut StdRng,
        out: &mut ActBuffers,
    ) {
        match self.policy.distribution(Self::tensor(obs, n)) {
            DistParams::Gaussian { mean, log_std } => host_rows(vec![mean, log_std], &mut out.dist),
            DistParams::Categorical { logits } => host_rows(vec![logits], &mut out.dist),
        }
        out.sample(self.action, n, deterministic, rng);
    }

    fn values(&mut self, obs: &[f32], n: usize) -> &[f32] {
        let v = self.value.forward(Self::tensor(obs, n));
        self.values.clear();
        self.values.extend(v.into_data().iter::<f32>());
        &self.values
    }
}

impl<B: Backend, F: PolicyFamily> Actor<B, F> for BurnActor<F>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    fn from_learner(learner: &Learner<B, F>, value: &ValueConfig) -> Self {
        let device = Default::default();
        Self {
            policy: learner.policy_on::<NdArray>(&device),
            value: learner.value_on::<NdArray>(value, &device),
            action: learner.action(),
            values: Vec::new(),
        }
    }
}
