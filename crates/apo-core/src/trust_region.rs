//! The trust-region step of TRPO and APO.
//!
//! At θ_j, with `g = ∇ objective(θ_j)` and `F = ∇² mean KL(π_j ‖ π_θ)|θ_j` (plus
//! `damping · I`), applied to vectors as `(1/N) Jᵀ M J v` by first-order passes
//! ([`crate::fisher`]: the policy's JVP, [`Policy::distribution_jvp`], or a finite difference
//! of its distributions when it has none — no second derivative, so any policy whose forward
//! pass is differentiable works, `burn::nn` layers included):
//!
//! 1. `x ≈ F⁻¹ g` by conjugate gradient;
//! 2. the full step `Δ = sqrt(2δ / (xᵀFx + step_epsilon)) · x` — the maximizer of the linearized objective
//!    inside the quadratic trust region `½ ΔᵀFΔ ≤ δ`;
//! 3. backtracking: try `θ_j + ξ^i Δ` for `i = 0, 1, …` (ξ = 0.8, up to 100 tries) and accept
//!    the first with mean KL ≤ δ and objective ≥ objective(θ_j) (the paper's
//!    [`Acceptance::Improvement`]), or, with [`Acceptance::Ratio`], an actual improvement of
//!    at least `accept_ratio` times the linear model's `ξ^i gᵀΔ` (the original TRPO's test);
//!    if none, keep θ_j.
//!
//! With several ranks ([`crate::collective`]) the gradient and every product `F v` are summed
//! over the ranks' shares, and the line search's KL and objective are means over every rank's
//! batch: conjugate gradient and the line search run in lockstep, on bitwise equal vectors.
//!
//! With [`Kernels::Host`] and a policy with a host form, the network's passes of the products,
//! of the gradient and of every line-search try run on apo-core's `f32` host kernels
//! ([`crate::fisher`], `crate::host_head`); the objective and the KL stay Burn's, evaluated on
//! the network's output.

use burn::backend::Autodiff;
use burn::tensor::backend::Backend;
use serde::{Deserialize, Serialize};

use crate::distribution::DistParams;
use crate::fisher::FisherOperator;
use crate::flat::{from_host, to_host, unflatten};
use crate::host_head::HostHead;
use crate::hvp::gradient;
use crate::kernels::Kernels;
use crate::objective::Objective;
use crate::policy::{Policy, PolicyFamily};
use crate::tensor_batch::TensorBatch;
use crate::validate::{check, ConfigError};

/// Which tries of the backtracking line search are accepted (inside the KL radius).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Acceptance {
    /// `objective(θ) ≥ objective(θ_j)` (the paper's Algorithm 1 and its code).
    #[default]
    Improvement,
    /// `objective(θ) − objective(θ_j) > 0` and at least `accept_ratio` times the improvement
    /// `ξ^i · gᵀΔ` the linearized objective predicts for the try (Schulman et al. 2015's
    /// line search, ratio 0.1).
    Ratio,
}

/// The improvement ratio of [`Acceptance::Ratio`] by default (Schulman et al.'s 0.1).
pub const DEFAULT_ACCEPT_RATIO: f64 = 0.1;

fn default_accept_ratio() -> f64 {
    DEFAULT_ACCEPT_RATIO
}

/// Settings of the trust-region step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrustRegionConfig {
    /// KL radius δ of the trust region (paper: 0.02).
    pub max_kl: f64,
    /// Maximum conjugate-gradient iterations.
    pub cg_iters: usize,
    /// Damping added to the Fisher matrix: `(F + damping · I) x = g`.
    pub cg_damping: f64,
    /// CG stops when the squared residual norm falls below this.
    pub cg_residual_tol: f64,
    /// Backtracking coefficient ξ (paper: 0.8).
    pub backtrack_coeff: f64,
    /// Maximum backtracking tries (paper: 100).
    pub backtrack_iters: usize,
    /// Added to `xᵀFx` in the step length `sqrt(2δ / (xᵀFx + step_epsilon))` (the paper's
    /// code: 1e-8; default 0).
    #[serde(default)]
    pub step_epsilon: f64,
    /// Which tries the line search accepts (default: the paper's).
    #[serde(default)]
    pub acceptance: Acceptance,
    /// The smallest actual / predicted improvement [`Acceptance::Ratio`] accepts, in (0, 1].
    #[serde(default = "default_accept_ratio")]
    pub accept_ratio: f64,
}

impl Default for TrustRegionConfig {
    fn default() -> Self {
        Self {
            max_kl: 0.02,
            cg_iters: 10,
            cg_damping: 0.1,
            cg_residual_tol: 1e-10,
            backtrack_coeff: 0.8,
            backtrack_iters: 100,
            step_epsilon: 0.0,
            acceptance: Acceptance::Improvement,
            accept_ratio: DEFAULT_ACCEPT_RATIO,
        }
    }
}

impl TrustRegionConfig {
    /// Checks every field's range; errors name the field as `trust_region.<field>`.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let finite_nonneg = crate::validate::finite_nonneg;
        check(
            self.max_kl > 0.0 && self.max_kl <= 10.0,
            "trust_region.max_kl",
            self.max_kl,
            "must be in (0, 10]",
        )?;
        check(
            (1..=1000).contains(&self.cg_iters),
            "trust_region.cg_iters",
            self.cg_iters,
            "must be in 1..=1000",
        )?;
        check(
            finite_nonneg(self.cg_damping) && self.cg_damping <= 1e6,
            "trust_region.cg_damping",
            self.cg_damping,
            "must be in [0, 1e6]",
        )?;
        check(
            finite_nonneg(self.cg_residual_tol) && self.cg_residual_tol <= 1.0,
            "trust_region.cg_residual_tol",
            self.cg_residual_tol,
            "must be in [0, 1]",
        )?;
        check(
            self.backtrack_coeff > 0.0 && self.backtrack_coeff < 1.0,
            "trust_region.backtrack_coeff",
            self.backtrack_coeff,
            "must be in (0, 1)",
        )?;
        check(
            (1..=1000).contains(&self.backtrack_iters),
            "trust_region.backtrack_iters",
            self.backtrack_iters,
            "must be in 1..=1000",
        )?;
        check(
            finite_nonneg(self.step_epsilon) && self.step_epsilon <= 1.0,
            "trust_region.step_epsilon",
            self.step_epsilon,
            "must be in [0, 1]",
        )?;
        check(
            self.accept_ratio > 0.0 && self.accept_ratio <= 1.0,
            "trust_region.accept_ratio",
            self.accept_ratio,
            "must be in (0, 1]",
        )
    }

    /// Documentation of the keys, `trust_region.<field>`.
    pub fn key_docs() -> Vec<(String, &'static str)> {
        [
            ("trust_region", "the trust-region step"),
            ("trust_region.max_kl", "KL radius δ (paper: 0.02); (0, 10]"),
            (
                "trust_region.cg_iters",
                "conjugate-gradient iterations; 1..=1000",
            ),
            (
                "trust_region.cg_damping",
                "damping added to the Fisher matrix, (F + damping·I)x = g; [0, 1e6]",
            ),
            (
                "trust_region.cg_residual_tol",
                "CG stops when the squared residual falls below this; [0, 1]",
            ),
            (
                "trust_region.backtrack_coeff",
                "backtracking coefficient ξ (paper: 0.8); (0, 1)",
            ),
            (
                "trust_region.backtrack_iters",
                "backtracking tries (paper: 100); 1..=1000",
            ),
            (
                "trust_region.step_epsilon",
                "added to xᵀFx in the step length sqrt(2δ / (xᵀFx + ε)) (the paper's code: 1e-8); [0, 1]",
            ),
            (
                "trust_region.acceptance",
                "which line-search tries are accepted inside the KL radius: \"improvement\" (objective ≥ objective(θ_j), the paper) or \"ratio\" (actual / predicted improvement ≥ accept_ratio, the original TRPO)",
            ),
            (
                "trust_region.accept_ratio",
                "the smallest actual / predicted improvement with acceptance = \"ratio\" (TRPO: 0.1); (0, 1]",
            ),
        ]
        .map(|(k, d)| (k.to_string(), d))
        .into()
    }
}

/// What conjugate gradient returned.
#[derive(Debug, Clone, PartialEq)]
pub struct CgSolution {
    /// The approximate solution `x` of `A x = b`.
    pub x: Vec<f64>,
    /// Iterations run.
    pub iterations: usize,
    /// Squared norm of the final residual `b − A x`.
    pub residual_sq: f64,
}

/// Solves `A x = b` for a symmetric positive-definite `A` given only as the product
/// `avp(v) = A v`, starting from `x = 0`; stops after `max_iters` or when the squared
/// residual norm is below `residual_tol`.
pub fn conjugate_gradient(
    mut avp: impl FnMut(&[f64]) -> Vec<f64>,
    b: &[f64],
    max_iters: usize,
    residual_tol: f64,
) -> CgSolution {
    let mut x = vec![0.0; b.len()];
    let mut r = b.to_vec();
    let mut p = b.to_vec();
    let mut r_dot = dot(&r, &r);
    let mut iterations = 0;
    while iterations < max_iters && r_dot >= residual_tol {
        let ap = avp(&p);
        let p_ap = dot(&p, &ap);
        if p_ap <= 0.0 || !p_ap.is_finite() {
            break;
        }
        let alpha = r_dot / p_ap;
        axpy(alpha, &p, &mut x);
        axpy(-alpha, &ap, &mut r);
        let new_r_dot = dot(&r, &r);
        let beta = new_r_dot / r_dot;
        for (pi, ri) in p.iter_mut().zip(&r) {
            *pi = ri + beta * *pi;
        }
        r_dot = new_r_dot;
        iterations += 1;
    }
    CgSolution {
        x,
        iterations,
        residual_sq: r_dot,
    }
}

/// `x · y`.
pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a * b).sum()
}

/// `y += a · x`.
fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += a * xi;
    }
}

/// How the backtracking line search ended.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum LineSearchOutcome {
    /// The step `ξ^try · Δ` was accepted (`try` counts from 0).
    Accepted {
        /// Index of the accepted try.
        r#try: usize,
    },
    /// No try satisfied both conditions; θ_j was kept.
    Rejected,
    /// The gradient or the step was zero or not finite; θ_j was kept.
    NoStep,
}

/// What one trust-region step did.
#[derive(Debug, Clone, PartialEq)]
pub struct TrustRegionReport {
    /// The new parameters (θ_j when the search failed).
    pub theta: Vec<f64>,
    /// The full step Δ before backtracking (zeros for [`LineSearchOutcome::NoStep`]).
    pub full_step: Vec<f64>,
    /// Line-search outcome.
    pub outcome: LineSearchOutcome,
    /// Objective at θ_j.
    pub objective_before: f64,
    /// Objective at the returned parameters.
    pub objective_after: f64,
    /// Mean KL(π_j ‖ π_new) at the returned parameters.
    pub kl: f64,
    /// CG iterations run.
    pub cg_iterations: usize,
    /// CG's final squared residual.
    pub cg_residual_sq: f64,
    /// Why the tries before the returned one were rejected.
    pub rejections: Rejections,
}

/// The line search's rejected tries, by the first condition each failed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Rejections {
    /// Tries whose mean KL exceeded δ.
    pub kl: usize,
    /// Tries inside the KL radius whose objective was below objective(θ_j) (with
    /// [`Acceptance::Ratio`]: whose improvement fell short of the ratio).
    pub objective: usize,
}

/// Mean KL(π_j ‖ π_θ) and the objective at `theta`, without gradients.
pub fn evaluate<B, F>(
    family: &F,
    objective: &Objective,
    theta: &[f64],
    batch: &TensorBatch<B>,
) -> (f64, f64)
where
    B: Backend,
    F: PolicyFamily,
{
    let device = batch.adv.device();
    let policy = unflatten(family.init::<B>(&device), from_host::<B>(theta, &device));
    kl_and_objective(objective, &policy.distribution(batch.obs.clone()), batch)
}

/// Mean KL(π_j ‖ π) and the objective of the distributions `dist` over `batch`'s states.
fn kl_and_objective<B: Backend>(
    objective: &Objective,
    dist: &DistParams<B>,
    batch: &TensorBatch<B>,
) -> (f64, f64) {
    let kl = batch.comm.mean(dist.kl_from(&batch.dist_old));
    let obj = objective.evaluate(dist, batch).objective;
    (to_host(kl)[0], to_host(obj)[0])
}

/// One trust-region step from `theta` (θ_j, whose distributions are `batch.dist_old`), with
/// the Fisher-vector products on `kernels`.
pub fn trust_region_step<B, F>(
    family: &F,
    objective: &Objective,
    theta: &[f64],
    batch: &TensorBatch<B>,
    config: &TrustRegionConfig,
    kernels: Kernels,
) -> TrustRegionReport
where
    B: Backend,
    F: PolicyFamily,
{
    let device = batch.adv.device();
    let batch1 = batch.lift::<Autodiff<B>>();
    // the network's passes on the host: the policy at θ_j and the batch's states `[N, ·]`
    let mut host = match kernels {
        Kernels::Host => {
            let policy = unflatten(family.init::<B>(&device), from_host::<B>(theta, &device));
            HostHead::of(&policy).map(|head| {
                let obs: Vec<f32> = batch.obs.clone().into_data().iter::<f32>().collect();
                (head, obs)
            })
        }
        Kernels::Backend => None,
    };
    let (objective_before, mut g) = match &mut host {
        Some((head, obs)) => {
            let (dist, leaves) = head.distribution::<Autodiff<B>>(obs, &device);
            let value = objective.evaluate(&dist, &batch1).objective;
            let grads = value.backward();
            let g = head.gradient(obs, leaves, &grads);
            (to_host(value)[0], g.iter().map(|&x| f64::from(x)).collect())
        }
        None => gradient(&family.init::<Autodiff<B>>(&device), theta, &device, |p| {
            objective
                .evaluate(&p.distribution(batch1.obs.clone()), &batch1)
                .objective
        }),
    };
    let comm = &batch.comm;
    comm.sum(&mut g);
    // the Fisher operator averages over this rank's rows: its share of the global mean
    let share = batch.len() as f64 / comm.total(batch.len()).max(1) as f64;

    // θ_j is fixed during the whole solve: both operators are prepared once
    let fisher = FisherOperator::new(family, theta, batch.obs.clone(), &batch.dist_old)
        .with_kernels(kernels);
    // set when the policy's distributions are not of the batch's family (no Fisher product)
    let mismatch = std::cell::Cell::new(false);
    let fvp = |v: &[f64]| -> Vec<f64> {
        let mut fv = match fisher.apply(v) {
            Some(fv) if comm.is_distributed() => fv.into_iter().map(|x| x * share).collect(),
            Some(fv) => fv,
            None => {
                mismatch.set(true);
                vec![0.0; v.len()]
            }
        };
        comm.sum(&mut fv);
        axpy(config.cg_damping, v, &mut fv);
        fv
    };
    let cg = conjugate_gradient(&fvp, &g, config.cg_iters, config.cg_residual_tol);
    let x_fx = dot(&cg.x, &fvp(&cg.x));
    let no_step = |full_step: Vec<f64>, outcome, rejections| TrustRegionReport {
        theta: theta.to_vec(),
        full_step,
        outcome,
        objective_before,
        objective_after: objective_before,
        kl: 0.0,
        cg_iterations: cg.iterations,
        cg_residual_sq: cg.residual_sq,
        rejections,
    };
    let denominator = x_fx + config.step_epsilon;
    if mismatch.get() || !(denominator > 0.0 && denominator.is_finite()) {
        return no_step(
            vec![0.0; theta.len()],
            LineSearchOutcome::NoStep,
            Rejections::default(),
        );
    }
    let scale = (2.0 * config.max_kl / denominator).sqrt();
    let full_step: Vec<f64> = cg.x.iter().map(|xi| scale * xi).collect();
    // the linearized objective's improvement for the full step, gᵀΔ
    let predicted = dot(&g, &full_step);

    let mut fraction = 1.0;
    let mut rejections = Rejections::default();
    for r#try in 0..config.backtrack_iters {
        let candidate: Vec<f64> = theta
            .iter()
            .zip(&full_step)
            .map(|(t, s)| t + fraction * s)
            .collect();
        let (kl, objective_after) = match &mut host {
            Some((head, obs)) => {
                head.set_params(&candidate);
                kl_and_objective(objective, &head.distribution::<B>(obs, &device).0, batch)
            }
            None => evaluate(family, objective, &candidate, batch),
        };
        let improved = match config.acceptance {
            Acceptance::Improvement => objective_after >= objective_before,
            Acceptance::Ratio => {
                let actual = objective_after - objective_before;
                actual > 0.0 && actual >= config.accept_ratio * fraction * predicted
            }
        };
        if kl <= config.max_kl && improved {
            return TrustRegionReport {
                theta: candidate,
                full_step,
                outcome: LineSearchOutcome::Accepted { r#try },
                objective_before,
                objective_after,
                kl,
                cg_iterations: cg.iterations,
                cg_residual_sq: cg.residual_sq,
                rejections,
            };
        }
        if kl > config.max_kl {
            rejections.kl += 1;
        } else {
            rejections.objective += 1;
        }
        fraction *= config.backtrack_coeff;
    }
    no_step(full_step, LineSearchOutcome::Rejected, rejections)
}
