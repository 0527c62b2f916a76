//! Policies: the trait a policy module implements to be trained, and the built-in MLP policies.
//!
//! A policy maps a batch of observations to the parameters of its action distribution.
//! The algorithms need the same policy on several backends (the plain backend for
//! evaluation, `Autodiff<B>` for gradients, `Autodiff<Autodiff<B>>` for Hessian-vector
//! products), so a policy is described by a [`PolicyFamily`]: a plain, serializable config
//! that builds the module on any backend. Parameters move between the copies as one flat
//! vector (see [`crate::flat`]).
//!
//! # Using your own policy
//!
//! Implement [`Policy`] for your module and [`PolicyFamily`] for its config: the
//! [crate docs](crate#your-own-policy) show a complete, tested policy built from
//! `burn::nn::Linear`, and `apo-train`'s `examples/custom_policy.rs` trains one.

use burn::module::{Module, Param};
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;
use serde::{Deserialize, Serialize};

use crate::distribution::DistParams;
use crate::mlp::Mlp;

/// A stochastic policy module: observations → action-distribution parameters.
///
/// Everything an algorithm in this crate needs from a policy. The policy's float
/// parameters (as visited by [`Module::visit`]) are the parameters θ that are optimized.
pub trait Policy<B: Backend>: Module<B> {
    /// `obs: [batch, observation_dim]` → the distribution of the action in each state:
    /// [`DistParams::Gaussian`] with means and log-stds `[batch, action_dim]` for a box
    /// action space, [`DistParams::Categorical`] with logits `[batch, n]` for `n` discrete
    /// actions.
    ///
    /// Any Burn operation will do, `burn::nn` layers included (`Linear`, convolutions, norms,
    /// embeddings): every algorithm needs only first derivatives — the trust-region step
    /// takes its Fisher-vector products from [`Policy::distribution_jvp`] or, without one,
    /// from a finite difference of this function ([`crate::fisher`]).
    fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B>;

    /// The Jacobian-vector product of [`Policy::distribution`] with respect to the
    /// parameters: `obs: [batch, observation_dim]` and `tangent`, a module of the same
    /// architecture whose parameters hold the direction `v` (for a flat `v: [num_params]`,
    /// [`crate::flat::unflatten`]`(self.clone(), v)` builds it), →
    /// `J v = d/dε distribution_{θ + εv}(obs)` at `ε = 0`, in the same layout as
    /// [`Policy::distribution`]'s output: the tangents of the means `[batch, action_dim]` and
    /// of the log standard deviations `[batch, action_dim]` for a Gaussian, of the logits
    /// `[batch, n]` for a categorical.
    ///
    /// Optional: it makes the trust-region step's Fisher-vector products exact and a little
    /// cheaper (see [`crate::fisher`]). The default, `None`, means "not available": the
    /// trust-region step then takes `J v` by a central finite difference of
    /// [`Policy::distribution`] (two forward passes, relative error about 1e-4 in `f32`).
    fn distribution_jvp(&self, _obs: Tensor<B, 2>, _tangent: &Self) -> Option<DistParams<B>> {
        None
    }

    /// The policy as a host MLP, for [`crate::Kernels::Host`]: `None` (the default) when it
    /// is not one, and Burn's graph is used.
    fn host_form(&self) -> Option<HostForm> {
        None
    }
}

/// A policy whose flat parameters are an MLP (the network that outputs the means or the
/// logits, tanh hidden layers) followed by state-independent log-stds.
#[derive(Debug, Clone, PartialEq)]
pub struct HostForm {
    /// Per layer, `(weight [input, output] row-major, bias [output])`.
    pub layers: Vec<(Vec<f32>, Vec<f32>)>,
    /// Number of log-std parameters after the network's (`None`: a categorical policy).
    pub log_std: Option<usize>,
}

/// A policy whose distributions do not fit the actions it is trained on (see
/// [`Policy::distribution`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("policy `{policy}`: {problem}")]
pub struct PolicyError {
    /// The policy's type.
    pub policy: String,
    /// What is wrong, and what to change.
    pub problem: String,
}

impl PolicyError {
    /// The error of policy type `P`.
    pub(crate) fn of<P: ?Sized>(problem: String) -> Self {
        Self {
            policy: std::any::type_name::<P>().to_string(),
            problem,
        }
    }
}

/// `Ok` when `dist`, policy `P`'s output on `rows` states, is a batch of `rows`
/// distributions of `action`'s family and width.
pub(crate) fn check_distribution<B: Backend, P: ?Sized>(
    dist: &DistParams<B>,
    rows: usize,
    action: ActionKind,
) -> Result<(), PolicyError> {
    let found = match dist {
        DistParams::Gaussian { mean, log_std } if mean.dims() == log_std.dims() => {
            let [r, dim] = mean.dims();
            (r, ActionKind::Continuous { dim })
        }
        DistParams::Gaussian { mean, log_std } => {
            return Err(PolicyError::of::<P>(format!(
                "its Gaussian's means {:?} and log-stds {:?} differ in shape (both must be [batch, action_dim]; expand a state-independent log-std to the batch)",
                mean.dims(),
                log_std.dims()
            )))
        }
        DistParams::Categorical { logits } => {
            let [r, n] = logits.dims();
            (r, ActionKind::Discrete { n })
        }
    };
    let expected = (rows, action);
    if found == expected {
        return Ok(());
    }
    let describe = |(rows, action): (usize, ActionKind)| match action {
        ActionKind::Continuous { dim } => format!("a Gaussian [{rows}, {dim}]"),
        ActionKind::Discrete { n } => format!("a categorical [{rows}, {n}]"),
    };
    Err(PolicyError::of::<P>(format!(
        "its distribution on {rows} states is {}, but the actions need {}",
        describe(found),
        describe(expected)
    )))
}

/// A description of a policy that can build the same architecture on any backend.
pub trait PolicyFamily: Clone + Send + Sync + std::fmt::Debug + 'static {
    /// The policy module on backend `B`.
    type Policy<B: Backend>: Policy<B>;

    /// A freshly initialized policy on `device`.
    fn init<B: Backend>(&self, device: &B::Device) -> Self::Policy<B>;
}

/// The kind of action a built-in policy produces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ActionKind {
    /// A real vector of `dim` components (diagonal Gaussian policy).
    Continuous {
        /// Action dimension.
        dim: usize,
    },
    /// One of `n` actions (categorical policy).
    Discrete {
        /// Number of actions.
        n: usize,
    },
}

impl ActionKind {
    /// Width of the action as stored in a batch: `dim`, or `n` for a one-hot row.
    pub fn width(&self) -> usize {
        match *self {
            ActionKind::Continuous { dim } => dim,
            ActionKind::Discrete { n } => n,
        }
    }

    /// Width of one state's distribution parameters: a Gaussian's means and log-stds
    /// (`2 · dim`), a categorical's logits (`n`).
    pub fn dist_width(&self) -> usize {
        match *self {
            ActionKind::Continuous { dim } => 2 * dim,
            ActionKind::Discrete { n } => n,
        }
    }

    /// Width of one environment action: `dim` floats, or one index.
    pub fn env_width(&self) -> usize {
        match *self {
            ActionKind::Continuous { dim } => dim,
            ActionKind::Discrete { .. } => 1,
        }
    }
}

/// Config of the built-in MLP policy (the paper's: tanh, (64, 64), state-independent log-std).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MlpPolicyConfig {
    /// Observation dimension.
    pub observation_dim: usize,
    /// Action space.
    pub action: ActionKind,
    /// Hidden layer sizes.
    pub hidden: Vec<usize>,
    /// Initial log standard deviation of a Gaussian policy (SpinningUp's −0.5).
    pub init_log_std: f64,
}

impl MlpPolicyConfig {
    /// The paper's architecture for the given sizes.
    pub fn new(observation_dim: usize, action: ActionKind) -> Self {
        Self {
            observation_dim,
            action,
            hidden: vec![64, 64],
            init_log_std: -0.5,
        }
    }
}

/// The built-in MLP policy: a diagonal Gaussian with a state-independent log-std, or a categorical.
#[derive(Module, Debug)]
pub struct MlpPolicy<B: Backend> {
    /// The network producing the means (Gaussian) or the logits (categorical).
    pub net: Mlp<B>,
    /// State-independent log standard deviations `[action_dim]` (Gaussian only).
    pub log_std: Option<Param<Tensor<B, 1>>>,
}

impl<B: Backend> Policy<B> for MlpPolicy<B> {
    fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
        let out = self.net.forward(obs);
        match &self.log_std {
            Some(log_std) => {
                let dims = out.dims();
                let log_std = log_std.val().unsqueeze_dim::<2>(0).expand(dims);
                DistParams::Gaussian { mean: out, log_std }
            }
            None => DistParams::Categorical { logits: out },
        }
    }

    /// Forward-mode tangents through the MLP ([`Mlp::jvp`]); the log-std tangent is the
    /// tangent's log-std `[action_dim]` expanded to the batch (it does not depend on the state).
    fn distribution_jvp(&self, obs: Tensor<B, 2>, tangent: &Self) -> Option<DistParams<B>> {
        let out = self.net.jvp(obs, &tangent.net);
        match (&self.log_std, &tangent.log_std) {
            (Some(_), Some(d_log_std)) => {
                let dims = out.dims();
                let log_std = d_log_std.val().unsqueeze_dim::<2>(0).expand(dims);
                Some(DistParams::Gaussian { mean: out, log_std })
            }
            (None, None) => Some(DistParams::Categorical { logits: out }),
            // a tangent of the other family: not a direction in this policy's parameters
            _ => None,
        }
    }

    fn host_form(&self) -> Option<HostForm> {
        Some(HostForm {
            layers: self.net.host_layers(),
            log_std: self.log_std.as_ref().map(|p| p.val().dims()[0]),
        })
    }
}

impl PolicyFamily for MlpPolicyConfig {
    type Policy<B: Backend> = MlpPolicy<B>;

    fn init<B: Backend>(&self, device: &B::Device) -> MlpPolicy<B> {
        let out = self.action.width();
        let net = Mlp::new(self.observation_dim, &self.hidden, out, device);
        let log_std = match self.action {
            ActionKind::Continuous { dim } => Some(Param::from_tensor(Tensor::full(
                [dim],
                self.init_log_std,
                device,
            ))),
            ActionKind::Discrete { .. } => None,
        };
        MlpPolicy { net, log_std }
    }
}
