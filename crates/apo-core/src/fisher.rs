//! The Fisher matrix of the policy at θ_j, applied to a vector by first-order passes only.
//!
//! The trust-region step solves `(F + damping · I) x = g` by conjugate gradient, where
//! `F = ∇²_θ (1/N) Σ_s KL(π_j(·|s) ‖ π_θ(·|s))` at `θ = θ_j`. Write `d_θ(s)` for the
//! distribution parameters of state `s` (means and log-stds, or logits). At `θ = θ_j` the
//! KL's gradient in `d` vanishes (the KL is minimal, 0, there), so the term of the chain rule
//! with second derivatives of `d_θ` drops out and
//!
//! ```text
//! F = (1/N) Σ_s J_sᵀ M_s J_s,    J_s = ∂d_θ(s)/∂θ  [param_dim, num_params],
//!                                M_s = ∇²_d KL(π_j(·|s) ‖ π_d)|_{d = d_j(s)}  [param_dim, param_dim],
//! ```
//!
//! `M_s` being the Fisher information of the action distribution in its parameters:
//!
//! * diagonal Gaussian in `(mean, log_std)`: `M = diag(1/σ_i² for each mean, 2 for each log-std)`.
//!   From the analytic KL of [`DistParams::kl_from`],
//!   `Σ_i [s_i − s_j,i + (σ_j,i² + (μ_j,i − μ_i)²) e^{−2 s_i} / 2 − ½]` with `s = log σ`:
//!   `∂²/∂μ_i² = e^{−2 s_i} = 1/σ_i²`, `∂²/∂s_i² = 2 (σ_j,i² + (μ_j,i − μ_i)²) e^{−2 s_i} = 2` and
//!   `∂²/∂μ_i∂s_i = 2 (μ_j,i − μ_i) e^{−2 s_i} = 0` at `d = d_j`. (The textbook Fisher information
//!   of `N(μ, σ²)` in `(μ, σ)` is `diag(1/σ², 2/σ²)`; `dσ/ds = σ` turns `2/σ²` into 2.)
//! * categorical in logits `l`: `M = diag(p) − p pᵀ`. `KL = Σ_a p_j(a) ln p_j(a) − Σ_a p_j(a) l_a
//!   + ln Σ_a e^{l_a}`, whose Hessian in `l` is that of log-sum-exp, `diag(p) − p pᵀ`
//!   (Boyd & Vandenberghe, *Convex Optimization*, §3.1.5), at `p = p_j`.
//!
//! This is the Fisher-vector product of TRPO (Schulman et al., "Trust Region Policy
//! Optimization", ICML 2015, Appendix C: `A = Jᵀ M J` with `M` the Fisher information of the
//! distribution in its parameter vector), i.e. the generalized Gauss–Newton matrix of the KL
//! (Martens, "New insights and perspectives on the natural gradient method", JMLR 2020).
//! So `F v = (1/N) Jᵀ (M (J v))`, computed as
//!
//! 1. `J v` by forward-mode tangents, [`Policy::distribution_jvp`], on the plain backend —
//!    or, for a policy without one (any module built from `burn::nn` layers), by a central
//!    finite difference of the distribution parameters along `v` (see below);
//! 2. `u = M (J v)` elementwise, with π_j's `σ` or `p` (the batch's `dist_old`: at θ_j they
//!    are the current policy's);
//! 3. `Jᵀ u / N` as the gradient of `(1/N) Σ_s ⟨u_s, d_θ(s)⟩` with `u` a constant, by one
//!    first-order backward pass on `Autodiff<B>` ([`crate::hvp::gradient`]).
//!
//! No second derivative is taken: one product costs about a forward-mode pass and a
//! forward-backward pass, instead of the double backward through `Autodiff<Autodiff<B>>` of
//! [`crate::hvp::hessian_vector_product`], which stays as a reference. Burn's standard layers
//! (`nn::Linear`, convolutions, norms, embeddings) are differentiable once but not twice
//! (their backward passes are not recorded), so a double backward fails on nearly every real
//! model; these first-order passes work for any policy whose forward pass is differentiable.
//!
//! # The finite-difference JVP
//!
//! For a policy whose [`Policy::distribution_jvp`] is `None`,
//!
//! ```text
//! J v ≈ (d_{θ+εv}(s) − d_{θ−εv}(s)) / (2ε),   ε = ε_M^{1/3} · max(1, ‖θ‖_∞) / ‖v‖_∞,
//! ```
//!
//! two forward passes on the plain backend, where `ε_M` is the machine epsilon of the
//! tensors' float type (`f32`: 1.19e-7, so every parameter moves by at most 4.9e-3 of its scale;
//! `f64`: 2.2e-16). The central difference's truncation error is `O(ε²)` and its rounding error
//! `O(ε_M / ε)`; `ε ∝ ε_M^{1/3}` balances them (Nocedal & Wright, *Numerical Optimization*,
//! 2nd ed., §8.1), leaving a relative error of order `ε_M^{2/3}`: about 1e-5 to 1e-4 in `f32`
//! (measured on the built-in MLP in `tests/core/fisher.rs`), 1e-10 in `f64`. The conjugate-gradient
//! solve and the line search (which checks the exact KL of every try) absorb it.

use std::cell::RefCell;

use burn::backend::Autodiff;
use burn::tensor::activation::softmax;
use burn::tensor::backend::Backend;
use burn::tensor::{DType, Tensor};

use crate::distribution::DistParams;
use crate::flat::{from_host, unflatten};
use crate::host_net::HostNet;
use crate::hvp::gradient;
use crate::kernels::Kernels;
use crate::policy::{HostForm, Policy, PolicyFamily};

/// What `M_s` needs of π_j, per state.
#[derive(Debug, Clone)]
enum Metric<B: Backend> {
    /// `1/σ²` of π_j, `[batch, action_dim]` (the log-std block of `M` is the constant 2).
    Gaussian { inv_var: Tensor<B, 2> },
    /// `p` of π_j, `[batch, n]`.
    Categorical { probs: Tensor<B, 2> },
}

impl<B: Backend> Metric<B> {
    fn new(dist: &DistParams<B>) -> Self {
        match dist {
            DistParams::Gaussian { log_std, .. } => Metric::Gaussian {
                inv_var: log_std.clone().mul_scalar(-2.0).exp(),
            },
            DistParams::Categorical { logits } => Metric::Categorical {
                probs: softmax(logits.clone(), 1),
            },
        }
    }

    /// `M_s t_s` for every state, for tangents `t` of the same family (`None` for the other).
    fn apply(&self, t: DistParams<B>) -> Option<DistParams<B>> {
        match (self, t) {
            (Metric::Gaussian { inv_var }, DistParams::Gaussian { mean, log_std }) => {
                Some(DistParams::Gaussian {
                    mean: mean * inv_var.clone(),
                    log_std: log_std.mul_scalar(2.0),
                })
            }
            (Metric::Categorical { probs }, DistParams::Categorical { logits }) => {
                // (diag(p) − p pᵀ) t = p ⊙ (t − pᵀt)
                let p_t = (probs.clone() * logits.clone()).sum_dim(1);
                Some(DistParams::Categorical {
                    logits: probs.clone() * (logits - p_t),
                })
            }
            _ => None,
        }
    }
}

/// `d` as constants of `Autodiff<B>` (no copy).
fn lift<B: Backend>(d: DistParams<B>) -> DistParams<Autodiff<B>> {
    match d {
        DistParams::Gaussian { mean, log_std } => DistParams::Gaussian {
            mean: Tensor::from_inner(mean),
            log_std: Tensor::from_inner(log_std),
        },
        DistParams::Categorical { logits } => DistParams::Categorical {
            logits: Tensor::from_inner(logits),
        },
    }
}

/// `Σ_s ⟨u_s, d_s⟩` → `[1]`; `Err` with a zero that depends on `d` when the families differ.
fn pairing<B: Backend>(d: DistParams<B>, u: DistParams<B>) -> Result<Tensor<B, 1>, Tensor<B, 1>> {
    match (d, u) {
        (
            DistParams::Gaussian { mean, log_std },
            DistParams::Gaussian {
                mean: u_mean,
                log_std: u_log_std,
            },
        ) => Ok((mean * u_mean).sum() + (log_std * u_log_std).sum()),
        (DistParams::Categorical { logits }, DistParams::Categorical { logits: u_logits }) => {
            Ok((logits * u_logits).sum())
        }
        (DistParams::Gaussian { mean: d, .. } | DistParams::Categorical { logits: d }, _) => {
            Err(d.sum().mul_scalar(0.0))
        }
    }
}

/// The Fisher matrix `F = (1/N) Σ_s J_sᵀ M_s J_s` of a policy of family `F` at θ_j on a
/// batch of `N` states, as a linear operator on host vectors (see the [module](self) docs).
///
/// Built once per trust-region step: everything that does not change between the
/// conjugate-gradient iterations (π_j's module, the observations on both backends, `M`) is
/// prepared here, and [`FisherOperator::apply`] runs only the JVP, `M`'s elementwise
/// product and one backward pass.
pub struct FisherOperator<B: Backend, F: PolicyFamily> {
    /// π_j on `B`: the point of the JVP and the template of the tangent modules.
    policy: F::Policy<B>,
    /// A module of the family on `Autodiff<B>` (its values are replaced by θ_j).
    template_ad: F::Policy<Autodiff<B>>,
    /// θ_j, `[num_params]`.
    theta: Vec<f64>,
    /// Observations, `[N, observation_dim]`.
    obs: Tensor<B, 2>,
    /// The same observations as constants of `Autodiff<B>`.
    obs_ad: Tensor<Autodiff<B>, 2>,
    /// `M_s` of each state.
    metric: Metric<B>,
    /// The same operator on the host kernels, when chosen and the policy has a host form.
    host: Option<RefCell<HostFisher>>,
}

impl<B: Backend, F: PolicyFamily> FisherOperator<B, F> {
    /// The Fisher matrix at `theta` (θ_j, `[num_params]`) over the states `obs`
    /// (`[N, observation_dim]`), whose distributions under θ_j are `dist_old` (`[N, ·]`, the
    /// batch's; `M` is taken from its `σ` or `p`).
    pub fn new(family: &F, theta: &[f64], obs: Tensor<B, 2>, dist_old: &DistParams<B>) -> Self {
        let device = obs.device();
        Self {
            policy: unflatten(family.init::<B>(&device), from_host::<B>(theta, &device)),
            template_ad: family.init::<Autodiff<B>>(&device),
            theta: theta.to_vec(),
            obs_ad: Tensor::from_inner(obs.clone()),
            obs,
            metric: Metric::new(dist_old),
            host: None,
        }
    }

    /// The operator with its products on `kernels`: with [`Kernels::Host`], on the host
    /// kernels when the policy has a host form ([`Policy::host_form`]) of `dist_old`'s
    /// family, else (and with [`Kernels::Backend`]) on Burn's graph.
    pub fn with_kernels(mut self, kernels: Kernels) -> Self {
        self.host = match kernels {
            Kernels::Host => {
                HostFisher::new(&self.policy, &self.obs, &self.metric).map(RefCell::new)
            }
            Kernels::Backend => None,
        };
        self
    }

    /// Where the products run: [`Kernels::Host`] only when it was asked for and the policy
    /// has a host form of `dist_old`'s family.
    pub fn kernels(&self) -> Kernels {
        if self.host.is_some() {
            Kernels::Host
        } else {
            Kernels::Backend
        }
    }

    /// `F v` for `v: [num_params]` → `[num_params]`, by first-order passes: `J v` by the
    /// policy's [`Policy::distribution_jvp`], or by a finite difference when it has none
    /// (see the [module](self) docs).
    ///
    /// `None` when the policy's distributions (or its JVP) are not of `dist_old`'s family.
    ///
    /// # Panics
    /// If `v` does not have exactly as many elements as the policy has parameters.
    pub fn apply(&self, v: &[f64]) -> Option<Vec<f64>> {
        if let Some(host) = &self.host {
            return Some(host.borrow_mut().apply(v));
        }
        let device = self.obs.device();
        let tangent = unflatten(self.policy.clone(), from_host::<B>(v, &device));
        let jv = match self.policy.distribution_jvp(self.obs.clone(), &tangent) {
            Some(jv) => jv,
            None => self.finite_difference_jvp(v)?,
        };
        let u = lift(self.metric.apply(jv)?);
        let n = self.obs.dims()[0] as f64;
        let mut families_match = true;
        let (_, fv) = gradient(&self.template_ad, &self.theta, &device, |p| {
            let d = p.distribution(self.obs_ad.clone());
            pairing(d, u)
                .unwrap_or_else(|zero| {
                    families_match = false;
                    zero
                })
                .div_scalar(n)
        });
        families_match.then_some(fv)
    }

    /// `J v ≈ (d_{θ+εv} − d_{θ−εv}) / (2ε)` over the batch, `[N, ·]` in
    /// [`Policy::distribution`]'s layout; `None` when the two are not of one family.
    fn finite_difference_jvp(&self, v: &[f64]) -> Option<DistParams<B>> {
        let max_abs = |x: &[f64]| x.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let v_max = max_abs(v);
        // v = 0: both points are θ_j and the difference is the zero tangent
        let eps = if v_max > 0.0 {
            finite_difference_scale(self.obs.dtype()) * max_abs(&self.theta).max(1.0) / v_max
        } else {
            1.0
        };
        let device = self.obs.device();
        let at = |sign: f64| {
            let point: Vec<f64> = self
                .theta
                .iter()
                .zip(v)
                .map(|(t, v)| t + sign * eps * v)
                .collect();
            unflatten(self.policy.clone(), from_host::<B>(&point, &device))
                .distribution(self.obs.clone())
        };
        let scale = 0.5 / eps;
        match (at(1.0), at(-1.0)) {
            (
                DistParams::Gaussian { mean, log_std },
                DistParams::Gaussian {
                    mean: mean_minus,
                    log_std: log_std_minus,
                },
            ) => Some(DistParams::Gaussian {
                mean: (mean - mean_minus).mul_scalar(scale),
                log_std: (log_std - log_std_minus).mul_scalar(scale),
            }),
            (
                DistParams::Categorical { logits },
                DistParams::Categorical {
                    logits: logits_minus,
                },
            ) => Some(DistParams::Categorical {
                logits: (logits - logits_minus).mul_scalar(scale),
            }),
            _ => None,
        }
    }
}

/// `ε_M^{1/3}` of the float type `dtype` (the tensors' own: Burn chooses it per device at run
/// time): the finite-difference step per unit of parameter scale.
fn finite_difference_scale(dtype: DType) -> f64 {
    let machine_epsilon = match dtype {
        DType::F64 => f64::EPSILON,
        DType::F16 => 2f64.powi(-10),
        DType::BF16 => 2f64.powi(-7),
        // f32, and anything narrower taken as f32
        _ => f64::from(f32::EPSILON),
    };
    machine_epsilon.cbrt()
}

/// `M_s` on the host, per state.
#[derive(Debug, Clone)]
enum HostMetric {
    /// `1/σ²` of π_j, `[N, action_dim]` (the log-std block of `M` is `2·I`).
    Gaussian { inv_var: Vec<f32> },
    /// `p` of π_j, `[N, n]`.
    Categorical { probs: Vec<f32> },
}

/// [`FisherOperator`] on the host kernels: the policy's network at θ_j as a [`HostNet`]
/// whose forward pass over the batch is done once; each product is a tangent pass, `M`'s
/// elementwise product and a reverse pass.
#[derive(Debug)]
struct HostFisher {
    net: HostNet,
    /// Observations, `[N, observation_dim]`.
    obs: Vec<f32>,
    metric: HostMetric,
    /// The network's part of `v`, `[num_net_params]`.
    tangent: Vec<f32>,
}

impl HostFisher {
    /// `None` when the policy has no host form or it does not match `metric`'s family.
    fn new<B: Backend, P: Policy<B>>(
        policy: &P,
        obs: &Tensor<B, 2>,
        metric: &Metric<B>,
    ) -> Option<Self> {
        let HostForm { layers, log_std } = policy.host_form()?;
        let mut net = HostNet::new(&layers)?;
        let host = |t: &Tensor<B, 2>| -> Vec<f32> { t.clone().into_data().iter::<f32>().collect() };
        let metric = match (metric, log_std) {
            (Metric::Gaussian { inv_var }, Some(_)) => HostMetric::Gaussian {
                inv_var: host(inv_var),
            },
            (Metric::Categorical { probs }, None) => HostMetric::Categorical { probs: host(probs) },
            _ => return None,
        };
        let [n, width] = obs.dims();
        if width != net.input() {
            return None;
        }
        let obs = host(obs);
        if obs.len() != n * width {
            return None;
        }
        // θ_j is fixed: the parts keep this forward pass for every product
        net.run(&obs, |w, part, _, x_rows| w.forward(part, x_rows));
        Some(Self {
            net,
            obs,
            metric,
            tangent: Vec::new(),
        })
    }

    /// `F v`, `v: [num_params]` (the network's parameters, then the log-stds) → `[num_params]`.
    fn apply(&mut self, v: &[f64]) -> Vec<f64> {
        let width = self.net.output();
        let rows = self.obs.len() / self.net.input();
        let inv_n = 1.0 / rows.max(1) as f32;
        let (v_net, v_log_std) = v.split_at(self.net.num_params().min(v.len()));
        self.tangent.clear();
        self.tangent.extend(v_net.iter().map(|&x| x as f32));
        let (tangent, metric) = (&self.tangent, &self.metric);
        self.net.run(&self.obs, |w, part, rows, x_rows| {
            w.jvp(part, x_rows, tangent);
            let (_, u) = part.output_and_head();
            let per_row = rows.start * width..rows.end * width;
            // u = M J v / N, in place
            match metric {
                HostMetric::Gaussian { inv_var } => {
                    for (t, w) in u.iter_mut().zip(&inv_var[per_row]) {
                        *t *= w * inv_n;
                    }
                }
                HostMetric::Categorical { probs } => {
                    // (diag(p) − p pᵀ) t = p ⊙ (t − pᵀt)
                    for (t, p) in u
                        .chunks_exact_mut(width)
                        .zip(probs[per_row].chunks_exact(width))
                    {
                        let p_t: f32 = t.iter().zip(p).map(|(t, p)| t * p).sum();
                        for (t, p) in t.iter_mut().zip(p) {
                            *t = p * (*t - p_t) * inv_n;
                        }
                    }
                }
            }
            w.backward(part, x_rows);
        });
        self.net.sum_grads();
        let mut fv: Vec<f64> = self.net.grads.iter().map(|&g| f64::from(g)).collect();
        // the log-std block: (1/N) Σ_s 2 v = 2 v
        fv.extend(v_log_std.iter().map(|&x| 2.0 * x));
        fv
    }
}

/// `F v` at `theta` (θ_j, `[num_params]`) over the states `obs` (`[N, observation_dim]`)
/// with π_j's distributions `dist_old`, for one `v: [num_params]` → `[num_params]`:
/// [`FisherOperator::new`] then [`FisherOperator::apply`] (build the operator once to apply
/// it to several vectors). `None` when the policy's distributions are not of `dist_old`'s family.
pub fn fisher_vector_product<B: Backend, F: PolicyFamily>(
    family: &F,
    theta: &[f64],
    obs: Tensor<B, 2>,
    dist_old: &DistParams<B>,
    v: &[f64],
) -> Option<Vec<f64>> {
    FisherOperator::new(family, theta, obs, dist_old).apply(v)
}
