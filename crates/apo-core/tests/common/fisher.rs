//! Backend-generic checks of the Fisher-vector product (`apo_core::fisher`) and of the MLP
//! policy's forward-mode JVP (`Policy::distribution_jvp`), run on NdArray<f64> and wgpu
//! (`tests/core/fisher.rs`) and on NdArray<f32> (`tests/ndarray_f32.rs`). Every reference is
//! plain `f64` on the host, from the reference policy of `common/mod.rs`:
//!
//! * [`check_jvp`]: `J v` against central differences of the reference policy in direction v;
//! * [`check_fisher_vs_explicit`]: `F v` against an explicit `Jᵀ M J / N` ([`reference_fisher`])
//!   whose Jacobian comes from central differences of the reference policy.

use apo_core::distribution::DistParams;
use apo_core::fisher::FisherOperator;
use apo_core::flat::{from_host, unflatten};
use apo_core::policy::{MlpPolicy, MlpPolicyConfig, Policy, PolicyFamily};
use apo_core::Kernels;
use burn::module::Module;
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

use super::*;

// ---------------------------------------------------------------------------------------
// Cases
// ---------------------------------------------------------------------------------------

pub struct Case {
    pub name: String,
    pub cfg: MlpPolicyConfig,
    /// θ_j.
    pub theta: Vec<f64>,
    /// Collected by θ_j: `dist_old` is θ_j's.
    pub batch: RefBatch,
    /// Random unit vectors.
    pub vs: Vec<Vec<f64>>,
}

/// θ_j random, a 32-state batch collected by θ_j and three random unit vectors.
pub fn case(name: &str, cfg: MlpPolicyConfig, seed: u64) -> Case {
    let mut rng = Rng::new(seed);
    let theta = random_theta(&cfg, &mut rng);
    let batch = sample_batch(&cfg, &theta, 32, 0.0, &mut rng);
    let vs = (0..3).map(|_| unit_vector(theta.len(), &mut rng)).collect();
    Case {
        name: name.to_string(),
        cfg,
        theta,
        batch,
        vs,
    }
}

/// Gaussian (3 actions) and categorical (5 actions) MLP policies, 4 observations, hidden (5, 4).
pub fn cases() -> Vec<Case> {
    vec![
        case("gaussian (5, 4)", gaussian_cfg(4, &[5, 4], 3), 31),
        case("categorical (5, 4)", categorical_cfg(4, &[5, 4], 5), 32),
    ]
}

/// The library's `F v` on backend `B` (products on `kernels`) for each of `vs`, from one
/// operator (`None` when the family's policy has no JVP).
pub fn library_fisher<B: Backend, F: PolicyFamily>(
    family: &F,
    c: &Case,
    vs: &[Vec<f64>],
    device: &B::Device,
    kernels: Kernels,
) -> Option<Vec<Vec<f64>>> {
    let tb = c.batch.to_tensors::<B>(device);
    let op = FisherOperator::new(family, &c.theta, tb.obs, &tb.dist_old).with_kernels(kernels);
    assert_eq!(
        op.kernels(),
        kernels,
        "the operator did not take the kernels asked for"
    );
    vs.iter().map(|v| op.apply(v)).collect()
}

// ---------------------------------------------------------------------------------------
// The JVP of the distribution parameters
// ---------------------------------------------------------------------------------------

/// The distribution parameters of each state as one row: (means, log-stds) or logits.
pub fn dist_rows(d: &RefDist) -> Vec<Vec<f64>> {
    match d {
        RefDist::Gaussian { mean, log_std } => mean
            .iter()
            .zip(log_std)
            .map(|(m, s)| m.iter().chain(s).copied().collect())
            .collect(),
        RefDist::Categorical { logits } => logits.clone(),
    }
}

/// [`dist_rows`] of the library's distribution parameters.
pub fn params_rows<B: Backend>(d: DistParams<B>) -> Vec<Vec<f64>> {
    let to_rows = |t: Tensor<B, 2>| {
        let [n, m] = t.dims();
        let v = host(t);
        (0..n)
            .map(|i| v[i * m..(i + 1) * m].to_vec())
            .collect::<Vec<_>>()
    };
    match d {
        DistParams::Gaussian { mean, log_std } => to_rows(mean)
            .into_iter()
            .zip(to_rows(log_std))
            .map(|(m, s)| m.into_iter().chain(s).collect())
            .collect(),
        DistParams::Categorical { logits } => to_rows(logits),
    }
}

/// The MLP policy's `J v` on backend `B`, for Gaussian and categorical policies with hidden
/// sizes (), (6) and (5, 4), against float64 central differences (ε = 1e-5) of the reference
/// policy in direction v. Returns `(case, relative error)`.
pub fn check_jvp<B: Backend>(device: &B::Device, tol: f64) -> Vec<(String, f64)> {
    let cfgs = [
        ("gaussian ()", gaussian_cfg(4, &[], 3)),
        ("gaussian (6)", gaussian_cfg(4, &[6], 2)),
        ("gaussian (5, 4)", gaussian_cfg(4, &[5, 4], 3)),
        ("categorical ()", categorical_cfg(4, &[], 5)),
        ("categorical (6)", categorical_cfg(4, &[6], 3)),
        ("categorical (5, 4)", categorical_cfg(4, &[5, 4], 5)),
    ];
    let mut errors = Vec::new();
    for (seed, (name, cfg)) in cfgs.into_iter().enumerate() {
        let c = case(name, cfg, 40 + seed as u64);
        let policy = unflatten(c.cfg.init::<B>(device), from_host::<B>(&c.theta, device));
        let obs = t2::<B>(&c.batch.obs, device);
        for (i, v) in c.vs.iter().enumerate() {
            let tangent = unflatten(policy.clone(), from_host::<B>(v, device));
            let jv = params_rows(
                policy
                    .distribution_jvp(obs.clone(), &tangent)
                    .expect("the MLP policy has a JVP"),
            );
            let eps = 1e-5;
            let at = |s: f64| -> Vec<f64> {
                c.theta
                    .iter()
                    .zip(v)
                    .map(|(t, vi)| t + s * eps * vi)
                    .collect()
            };
            let (plus, minus) = (
                ref_policy(&c.cfg, &at(1.0), &c.batch.obs),
                ref_policy(&c.cfg, &at(-1.0), &c.batch.obs),
            );
            let reference: Vec<f64> = dist_rows(&plus)
                .iter()
                .flatten()
                .zip(dist_rows(&minus).iter().flatten())
                .map(|(p, m)| (p - m) / (2.0 * eps))
                .collect();
            let got: Vec<f64> = jv.into_iter().flatten().collect();
            let what = format!("{name}, v{i}: J v");
            let err = assert_vec_rel(&what, &got, &reference, tol);
            errors.push((what, err));
        }
    }
    errors
}

// ---------------------------------------------------------------------------------------
// F v against an explicit Jᵀ M J / N from a float64 finite-difference Jacobian
// ---------------------------------------------------------------------------------------

/// `(1/N) Σ_s J_sᵀ M_s J_s` (`[num_params, num_params]`), J_s by central differences of the
/// reference policy, M_s from the batch's `dist_old`: `diag(1/σ², 2)` or `diag(p) − p pᵀ`.
pub fn reference_fisher(c: &Case) -> Vec<Vec<f64>> {
    let p = c.theta.len();
    let h = 1e-5;
    let mut x = c.theta.clone();
    // jac[i][s][k] = ∂ d(s)_k / ∂θ_i
    let jac: Vec<Vec<Vec<f64>>> = (0..p)
        .map(|i| {
            x[i] = c.theta[i] + h;
            let plus = dist_rows(&ref_policy(&c.cfg, &x, &c.batch.obs));
            x[i] = c.theta[i] - h;
            let minus = dist_rows(&ref_policy(&c.cfg, &x, &c.batch.obs));
            x[i] = c.theta[i];
            plus.iter()
                .zip(&minus)
                .map(|(a, b)| a.iter().zip(b).map(|(u, w)| (u - w) / (2.0 * h)).collect())
                .collect()
        })
        .collect();
    let metric: Vec<Vec<Vec<f64>>> = match &c.batch.dist_old {
        RefDist::Gaussian { log_std, .. } => log_std
            .iter()
            .map(|s| {
                let a = s.len();
                let mut m = vec![vec![0.0; 2 * a]; 2 * a];
                for k in 0..a {
                    m[k][k] = (-2.0 * s[k]).exp();
                    m[a + k][a + k] = 2.0;
                }
                m
            })
            .collect(),
        RefDist::Categorical { logits } => logits
            .iter()
            .map(|l| {
                let q = softmax(l);
                (0..q.len())
                    .map(|a| {
                        (0..q.len())
                            .map(|b| if a == b { q[a] } else { 0.0 } - q[a] * q[b])
                            .collect()
                    })
                    .collect()
            })
            .collect(),
    };
    let n = c.batch.len();
    let mut f = vec![vec![0.0; p]; p];
    for (s, m) in metric.iter().enumerate() {
        // M_s J_s, column j: Σ_l m[k][l] jac[j][s][l]
        let mj: Vec<Vec<f64>> = (0..p)
            .map(|j| m.iter().map(|row| dot(row, &jac[j][s])).collect())
            .collect();
        for i in 0..p {
            for j in 0..p {
                f[i][j] += dot(&jac[i][s], &mj[j]) / n as f64;
            }
        }
    }
    f
}

pub fn matvec(a: &[Vec<f64>], x: &[f64]) -> Vec<f64> {
    a.iter().map(|row| dot(row, x)).collect()
}

/// The built-in MLP policy without its JVP: the Fisher operator takes `J v` by a finite
/// difference of the distributions.
#[derive(Module, Debug)]
pub struct NoJvp<B: Backend> {
    pub inner: MlpPolicy<B>,
}

impl<B: Backend> Policy<B> for NoJvp<B> {
    fn distribution(&self, obs: Tensor<B, 2>) -> DistParams<B> {
        self.inner.distribution(obs)
    }
}

#[derive(Debug, Clone)]
pub struct NoJvpFamily(pub MlpPolicyConfig);

impl PolicyFamily for NoJvpFamily {
    type Policy<B: Backend> = NoJvp<B>;

    fn init<B: Backend>(&self, device: &B::Device) -> NoJvp<B> {
        NoJvp {
            inner: self.0.init(device),
        }
    }
}

/// How the library's `F v` gets `J v`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Jvp {
    /// The MLP policy's forward-mode JVP.
    Analytic,
    /// The finite difference of a policy without one ([`NoJvp`]).
    FiniteDifference,
}

/// The library's `F v` on backend `B` ([`cases`], each of their `vs`, `J v` by `jvp`) against
/// the explicit [`reference_fisher`]. Returns `(case, relative error)`.
pub fn check_fisher_vs_explicit<B: Backend>(
    device: &B::Device,
    kernels: Kernels,
    jvp: Jvp,
    tol: f64,
) -> Vec<(String, f64)> {
    let mut errors = Vec::new();
    for c in cases() {
        let f = reference_fisher(&c);
        let fvs = match jvp {
            Jvp::Analytic => library_fisher::<B, _>(&c.cfg, &c, &c.vs, device, kernels),
            Jvp::FiniteDifference => {
                library_fisher::<B, _>(&NoJvpFamily(c.cfg.clone()), &c, &c.vs, device, kernels)
            }
        }
        .expect("the policy's distributions are of the batch's family");
        for (i, (v, fv)) in c.vs.iter().zip(&fvs).enumerate() {
            let what = format!("{}, v{i}: F v vs Jᵀ M J v / N", c.name);
            let err = assert_vec_rel(&what, fv, &matvec(&f, v), tol);
            errors.push((what, err));
        }
    }
    errors
}
