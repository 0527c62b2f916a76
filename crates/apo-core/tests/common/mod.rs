//! Shared helpers of the integration tests.
//!
//! * devices, with guards: `ndarray_f64()` checks that the NdArray<f64> backend really
//!   computes in float64, `wgpu()` fails loudly when no adapter can be found;
//! * a small deterministic random generator;
//! * **reference implementations in plain `f64`**, written from the formulas of
//!   `docs/algorithms.md` (the APO objective, term by term) without calling the library:
//!   distributions, the MLP forward pass (from a flat parameter vector), every objective;
//! * finite differences of those references;
//! * [`backend`]: the backend-generic check bodies (objective terms, gradients, HVPs),
//!   written once and called for NdArray<f64>, wgpu and NdArray<f32>;
//! * [`fisher`]: the same for the MLP policy's JVP and the Fisher-vector product.
#![allow(dead_code)]

pub mod backend;
pub mod fisher;

use std::sync::OnceLock;

use apo_core::distribution::DistParams;
use apo_core::objective::{HMax, Objective, PenaltyUnits, Switch};
use apo_core::policy::{ActionKind, MlpPolicyConfig};
use apo_core::tensor_batch::TensorBatch;
use burn::backend::ndarray::NdArrayDevice;
use burn::backend::wgpu::WgpuDevice;
use burn::backend::NdArray;
use burn::tensor::backend::Backend;
use burn::tensor::{DType, Tensor, TensorData};

/// The float64 CPU backend every reference-precision test runs on.
pub type F64 = NdArray<f64>;

// ---------------------------------------------------------------------------------------
// Devices
// ---------------------------------------------------------------------------------------

/// Panics unless tensors that `B` creates on `device` have the float dtype `expected`.
///
/// Burn 0.21 keeps the default float dtype per *device type* in a process-wide registry,
/// and `NdArray<f32>` and `NdArray<f64>` share the device type `NdArrayDevice`: whichever
/// is used first in a process fixes the dtype of both. A test binary that used
/// NdArray<f32> first would silently run its "float64" references in float32. That is why
/// the NdArray<f32> runs live in their own test binary (`tests/ndarray_f32.rs`), and
/// why every float64 test goes through this check.
pub fn assert_float_dtype<B: Backend>(device: &B::Device, expected: DType, name: &str) {
    let t = Tensor::<B, 1>::from_data(TensorData::new(vec![1.0f64, 1.0 + 1e-12], [2]), device);
    let dtype = t.dtype();
    assert_eq!(
        dtype, expected,
        "{name} creates {dtype:?} tensors, expected {expected:?}"
    );
    if expected == DType::F64 {
        let v: Vec<f64> = t.into_data().iter::<f64>().collect();
        assert!(
            v[1] - v[0] > 5e-13,
            "{name} does not keep float64 precision: {v:?}"
        );
    }
}

/// The NdArray<f64> device, after checking that it really computes in float64.
pub fn ndarray_f64() -> NdArrayDevice {
    let device = NdArrayDevice::default();
    assert_float_dtype::<F64>(&device, DType::F64, "NdArray<f64>");
    device
}

static WGPU_ADAPTER: OnceLock<Result<String, String>> = OnceLock::new();

/// The default wgpu device, initialized once per test binary.
///
/// Panics (the test fails, it is never skipped) with a clear message when no adapter is
/// available. Prints the adapter in use (run with `--nocapture` to see it): on a machine
/// without a GPU it must be Mesa's software Vulkan driver (`llvmpipe`, package
/// `mesa-vulkan-drivers`).
pub fn wgpu() -> WgpuDevice {
    let device = WgpuDevice::default();
    let adapter = WGPU_ADAPTER.get_or_init(|| {
        let dev = device.clone();
        std::panic::catch_unwind(move || {
            use burn::backend::wgpu::{graphics::AutoGraphicsApi, init_setup, RuntimeOptions};
            let setup = init_setup::<AutoGraphicsApi>(&dev, RuntimeOptions::default());
            let info = setup.adapter.get_info();
            format!(
                "{} ({:?}, {:?}, driver {} {})",
                info.name, info.backend, info.device_type, info.driver, info.driver_info
            )
        })
        .map_err(|e| {
            e.downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default()
        })
    });
    match adapter {
        Ok(name) => {
            eprintln!("wgpu adapter: {name}");
            device
        }
        Err(msg) => panic!(
            "wgpu backend: no usable adapter ({msg}). These tests need a GPU or Mesa's software \
             Vulkan driver: `apt-get install -y mesa-vulkan-drivers`."
        ),
    }
}

// ---------------------------------------------------------------------------------------
// Random numbers (splitmix64 + Box–Muller), deterministic and dependency-free
// ---------------------------------------------------------------------------------------

pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }

    pub fn normals(&mut self, n: usize, scale: f64) -> Vec<f64> {
        (0..n).map(|_| scale * self.normal()).collect()
    }

    pub fn matrix(&mut self, rows: usize, cols: usize, scale: f64) -> Vec<Vec<f64>> {
        (0..rows).map(|_| self.normals(cols, scale)).collect()
    }
}

// ---------------------------------------------------------------------------------------
// Comparisons
// ---------------------------------------------------------------------------------------

/// `‖a − e‖₂ / ‖e‖₂`.
pub fn rel_err(a: &[f64], e: &[f64]) -> f64 {
    assert_eq!(a.len(), e.len(), "length mismatch");
    let num: f64 = a
        .iter()
        .zip(e)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt();
    let den: f64 = e.iter().map(|y| y * y).sum::<f64>().sqrt();
    assert!(den > 0.0, "reference vector is zero");
    num / den
}

/// `|a − e| ≤ tol · scale` with `scale = max(|e|, floor)`; the message names the quantity.
pub fn assert_close(what: &str, a: f64, e: f64, tol: f64, floor: f64) {
    let scale = e.abs().max(floor);
    assert!(a.is_finite(), "{what}: got {a}, expected {e}");
    assert!(
        (a - e).abs() <= tol * scale,
        "{what}: got {a:.17e}, expected {e:.17e} (|diff| {:.3e} > {tol:.1e} × {scale:.3e})",
        (a - e).abs()
    );
}

/// `assert_close` with a pure relative tolerance (`e` must not be 0).
pub fn assert_rel(what: &str, a: f64, e: f64, tol: f64) {
    assert!(e != 0.0, "{what}: reference is exactly 0, use assert_close");
    assert_close(what, a, e, tol, 0.0)
}

pub fn assert_vec_rel(what: &str, a: &[f64], e: &[f64], tol: f64) -> f64 {
    let err = rel_err(a, e);
    assert!(
        err <= tol,
        "{what}: relative error {err:.3e} > {tol:.1e}\n  got      {a:?}\n  expected {e:?}"
    );
    err
}

/// The value of a `[1]` (or any) tensor as host `f64`s.
pub fn host<B: Backend, const D: usize>(t: Tensor<B, D>) -> Vec<f64> {
    t.into_data().iter::<f64>().collect()
}

pub fn scalar<B: Backend>(t: Tensor<B, 1>) -> f64 {
    let v = host(t);
    assert_eq!(v.len(), 1, "expected a [1] tensor");
    v[0]
}

pub fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a * b).sum()
}

pub fn norm(x: &[f64]) -> f64 {
    dot(x, x).sqrt()
}

// ---------------------------------------------------------------------------------------
// Tensors from host f64 data
// ---------------------------------------------------------------------------------------

pub fn t1<B: Backend>(v: &[f64], device: &B::Device) -> Tensor<B, 1> {
    Tensor::from_data(TensorData::new(v.to_vec(), [v.len()]), device)
}

pub fn t2<B: Backend>(rows: &[Vec<f64>], device: &B::Device) -> Tensor<B, 2> {
    let n = rows.len();
    let m = rows.first().map_or(0, |r| r.len());
    let flat: Vec<f64> = rows.iter().flat_map(|r| r.iter().copied()).collect();
    Tensor::from_data(TensorData::new(flat, [n, m]), device)
}

// ---------------------------------------------------------------------------------------
// Reference distributions (plain f64)
// ---------------------------------------------------------------------------------------

const LN_2PI: f64 = 1.837_877_066_409_345_5; // ln(2π)

/// Distribution parameters of a batch, on the host.
#[derive(Debug, Clone)]
pub enum RefDist {
    Gaussian {
        mean: Vec<Vec<f64>>,
        log_std: Vec<Vec<f64>>,
    },
    Categorical {
        logits: Vec<Vec<f64>>,
    },
}

impl RefDist {
    pub fn len(&self) -> usize {
        match self {
            RefDist::Gaussian { mean, .. } => mean.len(),
            RefDist::Categorical { logits } => logits.len(),
        }
    }

    pub fn to_params<B: Backend>(&self, device: &B::Device) -> DistParams<B> {
        match self {
            RefDist::Gaussian { mean, log_std } => DistParams::Gaussian {
                mean: t2(mean, device),
                log_std: t2(log_std, device),
            },
            RefDist::Categorical { logits } => DistParams::Categorical {
                logits: t2(logits, device),
            },
        }
    }

    /// Log-density of each action (one-hot rows for a categorical).
    pub fn log_prob(&self, actions: &[Vec<f64>]) -> Vec<f64> {
        match self {
            RefDist::Gaussian { mean, log_std } => (0..mean.len())
                .map(|n| {
                    let mut lp = 0.0;
                    for i in 0..mean[n].len() {
                        let sigma = log_std[n][i].exp();
                        let z = (actions[n][i] - mean[n][i]) / sigma;
                        lp += -0.5 * z * z - sigma.ln() - 0.5 * LN_2PI;
                    }
                    lp
                })
                .collect(),
            RefDist::Categorical { logits } => (0..logits.len())
                .map(|n| {
                    let p = softmax(&logits[n]);
                    p.iter().zip(&actions[n]).map(|(pi, ai)| ai * pi.ln()).sum()
                })
                .collect(),
        }
    }

    pub fn entropy(&self) -> Vec<f64> {
        match self {
            RefDist::Gaussian { log_std, .. } => log_std
                .iter()
                .map(|row| {
                    row.iter()
                        .map(|s| 0.5 * (2.0 * std::f64::consts::PI * std::f64::consts::E).ln() + s)
                        .sum()
                })
                .collect(),
            RefDist::Categorical { logits } => logits
                .iter()
                .map(|l| softmax(l).iter().map(|p| -p * p.ln()).sum())
                .collect(),
        }
    }

    /// `KL(old ‖ self)` per state, from the textbook closed forms.
    pub fn kl_from(&self, old: &RefDist) -> Vec<f64> {
        match (old, self) {
            (
                RefDist::Gaussian {
                    mean: m0,
                    log_std: s0,
                },
                RefDist::Gaussian {
                    mean: m1,
                    log_std: s1,
                },
            ) => (0..m0.len())
                .map(|n| {
                    (0..m0[n].len())
                        .map(|i| {
                            let (sig0, sig1) = (s0[n][i].exp(), s1[n][i].exp());
                            (sig1 / sig0).ln()
                                + (sig0 * sig0 + (m0[n][i] - m1[n][i]).powi(2))
                                    / (2.0 * sig1 * sig1)
                                - 0.5
                        })
                        .sum()
                })
                .collect(),
            (RefDist::Categorical { logits: l0 }, RefDist::Categorical { logits: l1 }) => (0..l0
                .len())
                .map(|n| {
                    let (p, q) = (softmax(&l0[n]), softmax(&l1[n]));
                    p.iter().zip(&q).map(|(pi, qi)| pi * (pi / qi).ln()).sum()
                })
                .collect(),
            _ => panic!("KL across families"),
        }
    }
}

impl RefDist {
    /// `D_α(old ‖ self)` per state: `(∫ p_old^α p^(1−α) − 1) / (α(α − 1))`, the Gaussian
    /// closed form per dimension summed over dimensions, the categorical sum directly.
    pub fn alpha_divergence_from(&self, old: &RefDist, alpha: f64) -> Vec<f64> {
        let scale = 1.0 / (alpha * (alpha - 1.0));
        match (old, self) {
            (
                RefDist::Gaussian {
                    mean: m0,
                    log_std: s0,
                },
                RefDist::Gaussian {
                    mean: m1,
                    log_std: s1,
                },
            ) => (0..m0.len())
                .map(|n| {
                    (0..m0[n].len())
                        .map(|i| {
                            let (sig0, sig1) = (s0[n][i].exp(), s1[n][i].exp());
                            gaussian_alpha_divergence(m0[n][i], sig0, m1[n][i], sig1, alpha)
                        })
                        .sum()
                })
                .collect(),
            (RefDist::Categorical { logits: l0 }, RefDist::Categorical { logits: l1 }) => (0..l0
                .len())
                .map(|n| {
                    let (p, q) = (softmax(&l0[n]), softmax(&l1[n]));
                    let overlap: f64 = p
                        .iter()
                        .zip(&q)
                        .map(|(pi, qi)| pi.powf(alpha) * qi.powf(1.0 - alpha))
                        .sum();
                    (overlap - 1.0) * scale
                })
                .collect(),
            _ => panic!("α-divergence across families"),
        }
    }
}

/// The closed form of `D_α(N(μ0, σ0²) ‖ N(μ1, σ1²))`:
/// `(σ0^(1−α) σ1^α / s · exp(α(α−1)(μ0 − μ1)² / (2 s²)) − 1) / (α(α − 1))`,
/// `s² = α σ1² + (1 − α) σ0²`.
pub fn gaussian_alpha_divergence(mu0: f64, sig0: f64, mu1: f64, sig1: f64, alpha: f64) -> f64 {
    let s2 = alpha * sig1 * sig1 + (1.0 - alpha) * sig0 * sig0;
    let c = sig0.powf(1.0 - alpha) * sig1.powf(alpha) / s2.sqrt()
        * (alpha * (alpha - 1.0) * (mu0 - mu1).powi(2) / (2.0 * s2)).exp();
    (c - 1.0) / (alpha * (alpha - 1.0))
}

/// V-MPO's loss terms by hand: `(policy_loss, temperature_loss, trust_region_loss)` for the
/// log-probabilities `logp` of the batch's actions and the mean KL `kl`, with the rows of
/// the top half chosen here by sorting.
pub fn ref_vmpo(
    p: &apo_core::objective::VmpoParams,
    logp: &[f64],
    kl: f64,
    adv: &[f64],
) -> (f64, f64, f64) {
    let mut rows: Vec<usize> = (0..adv.len()).collect();
    rows.sort_by(|&a, &b| adv[b].partial_cmp(&adv[a]).expect("finite"));
    let top = &rows[..(adv.len() / 2).max(1)];
    let max = top
        .iter()
        .map(|&i| adv[i])
        .fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = top
        .iter()
        .map(|&i| ((adv[i] - max) / p.eta).exp())
        .collect();
    let z: f64 = w.iter().sum();
    let policy = -top
        .iter()
        .zip(&w)
        .map(|(&i, wi)| wi / z * logp[i])
        .sum::<f64>();
    let mean_exp = top.iter().map(|&i| (adv[i] / p.eta).exp()).sum::<f64>() / top.len() as f64;
    let temperature = p.eta * p.eps_eta + p.eta * mean_exp.ln();
    let trust = p.alpha * (p.eps_alpha - kl) + p.alpha * kl;
    (policy, temperature, trust)
}

pub fn softmax(logits: &[f64]) -> Vec<f64> {
    let m = logits.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = logits.iter().map(|l| (l - m).exp()).collect();
    let s: f64 = e.iter().sum();
    e.iter().map(|x| x / s).collect()
}

// ---------------------------------------------------------------------------------------
// Reference MLP policy (plain f64, from the flat parameter vector)
// ---------------------------------------------------------------------------------------

/// Layer sizes `[input, hidden…, output]`.
pub fn layer_sizes(cfg: &MlpPolicyConfig) -> Vec<usize> {
    let mut s = vec![cfg.observation_dim];
    s.extend(&cfg.hidden);
    s.push(cfg.action.width());
    s
}

/// Number of parameters of an MLP with these sizes (weights `[in, out]` and biases).
pub fn mlp_params(sizes: &[usize]) -> usize {
    sizes.windows(2).map(|w| w[0] * w[1] + w[1]).sum()
}

pub fn policy_params(cfg: &MlpPolicyConfig) -> usize {
    let extra = match cfg.action {
        ActionKind::Continuous { dim } => dim,
        ActionKind::Discrete { .. } => 0,
    };
    mlp_params(&layer_sizes(cfg)) + extra
}

/// The MLP `x → tanh(x W1 + b1) → … → x Wn + bn`, reading, layer after layer, the weight
/// `[in, out]` row-major and then the bias from `theta`. (This is the layout the
/// library's `flatten` must produce; `distributions.rs` checks it.)
pub fn ref_mlp(sizes: &[usize], theta: &[f64], x: &[f64]) -> Vec<f64> {
    let mut h = x.to_vec();
    let mut off = 0;
    let layers = sizes.len() - 1;
    for (l, w) in sizes.windows(2).enumerate() {
        let (nin, nout) = (w[0], w[1]);
        let weight = &theta[off..off + nin * nout];
        let bias = &theta[off + nin * nout..off + nin * nout + nout];
        off += nin * nout + nout;
        let mut out = bias.to_vec();
        for i in 0..nin {
            for j in 0..nout {
                out[j] += h[i] * weight[i * nout + j];
            }
        }
        if l + 1 < layers {
            out.iter_mut().for_each(|v| *v = v.tanh());
        }
        h = out;
    }
    h
}

/// The distributions of the built-in MLP policy with parameters `theta` on `obs`.
pub fn ref_policy(cfg: &MlpPolicyConfig, theta: &[f64], obs: &[Vec<f64>]) -> RefDist {
    assert_eq!(theta.len(), policy_params(cfg), "parameter count");
    let sizes = layer_sizes(cfg);
    let out: Vec<Vec<f64>> = obs.iter().map(|x| ref_mlp(&sizes, theta, x)).collect();
    match cfg.action {
        ActionKind::Continuous { dim } => {
            let log_std = theta[theta.len() - dim..].to_vec();
            RefDist::Gaussian {
                log_std: vec![log_std; out.len()],
                mean: out,
            }
        }
        ActionKind::Discrete { .. } => RefDist::Categorical { logits: out },
    }
}

pub fn gaussian_cfg(obs: usize, hidden: &[usize], act: usize) -> MlpPolicyConfig {
    MlpPolicyConfig {
        observation_dim: obs,
        action: ActionKind::Continuous { dim: act },
        hidden: hidden.to_vec(),
        init_log_std: -0.5,
    }
}

pub fn categorical_cfg(obs: usize, hidden: &[usize], n: usize) -> MlpPolicyConfig {
    MlpPolicyConfig {
        observation_dim: obs,
        action: ActionKind::Discrete { n },
        hidden: hidden.to_vec(),
        init_log_std: 0.0,
    }
}

/// Random policy parameters: weights ~ N(0, 0.5²/fan-in-ish), log-std around −0.4.
pub fn random_theta(cfg: &MlpPolicyConfig, rng: &mut Rng) -> Vec<f64> {
    let sizes = layer_sizes(cfg);
    let mut theta = Vec::new();
    for w in sizes.windows(2) {
        let scale = 1.2 / (w[0] as f64).sqrt();
        theta.extend(rng.normals(w[0] * w[1], scale));
        theta.extend(rng.normals(w[1], 0.1));
    }
    if let ActionKind::Continuous { dim } = cfg.action {
        theta.extend((0..dim).map(|_| -0.4 + 0.2 * rng.normal()));
    }
    theta
}

// ---------------------------------------------------------------------------------------
// Reference batch
// ---------------------------------------------------------------------------------------

/// One epoch's data on the host, in f64.
#[derive(Debug, Clone)]
pub struct RefBatch {
    pub obs: Vec<Vec<f64>>,
    pub actions: Vec<Vec<f64>>,
    pub logp_old: Vec<f64>,
    pub dist_old: RefDist,
    pub value: Vec<f64>,
    pub delta: Vec<f64>,
    pub adv: Vec<f64>,
    pub ret: Vec<f64>,
    /// σ_A, the scale the raw advantages were divided by (the scale-free penalty's unit).
    pub adv_scale: f64,
}

impl RefBatch {
    pub fn len(&self) -> usize {
        self.adv.len()
    }

    pub fn to_tensors<B: Backend>(&self, device: &B::Device) -> TensorBatch<B> {
        TensorBatch {
            obs: t2(&self.obs, device),
            actions: t2(&self.actions, device),
            logp_old: t1(&self.logp_old, device),
            dist_old: self.dist_old.to_params(device),
            value: t1(&self.value, device),
            delta: t1(&self.delta, device),
            adv: t1(&self.adv, device),
            ret: t1(&self.ret, device),
            adv_scale: self.adv_scale,
            comm: apo_core::Comm::default(),
        }
    }
}

/// Samples actions from `dist` (one-hot rows for a categorical).
pub fn sample_actions(dist: &RefDist, rng: &mut Rng) -> Vec<Vec<f64>> {
    match dist {
        RefDist::Gaussian { mean, log_std } => mean
            .iter()
            .zip(log_std)
            .map(|(m, s)| {
                m.iter()
                    .zip(s)
                    .map(|(mi, si)| mi + si.exp() * rng.normal())
                    .collect()
            })
            .collect(),
        RefDist::Categorical { logits } => logits
            .iter()
            .map(|l| {
                let p = softmax(l);
                let u = rng.uniform();
                let mut acc = 0.0;
                let mut k = p.len() - 1;
                for (i, pi) in p.iter().enumerate() {
                    acc += pi;
                    if u < acc {
                        k = i;
                        break;
                    }
                }
                (0..p.len())
                    .map(|i| if i == k { 1.0 } else { 0.0 })
                    .collect()
            })
            .collect(),
    }
}

/// A batch of `n` transitions collected by the MLP policy `theta_old` (actions sampled from
/// it, `logp_old` and `dist_old` its own), with random values, deltas and advantages.
/// `value_mean` shifts the critic values (it decides the side of the `min_J_sq` switch).
pub fn sample_batch(
    cfg: &MlpPolicyConfig,
    theta_old: &[f64],
    n: usize,
    value_mean: f64,
    rng: &mut Rng,
) -> RefBatch {
    let obs = rng.matrix(n, cfg.observation_dim, 1.0);
    let dist_old = ref_policy(cfg, theta_old, &obs);
    let actions = sample_actions(&dist_old, rng);
    let logp_old = dist_old.log_prob(&actions);
    RefBatch {
        obs,
        actions,
        logp_old,
        dist_old,
        value: (0..n).map(|_| value_mean + rng.normal()).collect(),
        delta: (0..n).map(|_| rng.normal()).collect(),
        adv: (0..n).map(|_| rng.normal()).collect(),
        ret: (0..n).map(|_| rng.normal()).collect(),
        adv_scale: 1.0,
    }
}

// ---------------------------------------------------------------------------------------
// Reference objectives (plain f64, from the formulas of docs/algorithms.md)
// ---------------------------------------------------------------------------------------

/// The terms of an objective, computed by hand.
#[derive(Debug, Clone)]
pub struct RefTerms {
    pub objective: f64,
    pub mean_surr: f64,
    pub mean_variance: Option<f64>,
    pub variance_mean: Option<f64>,
    pub min_j_sq: Option<f64>,
    /// `mean_surr + mean(V) − bias` (the switch is on when ≥ 0).
    pub switch_margin: Option<f64>,
    /// The smallest distance of the data to a kink of the objective (abs, min, clip):
    /// finite differences need it to be larger than their step's effect.
    pub kink_margin: f64,
    /// The function whose θ-gradient the objective's graph carries: the objective itself,
    /// except where stop-gradients make them differ (V-MPO: `sg(KL)` and `sg(α)` leave
    /// `−(policy + α · KL)` plus terms constant in θ).
    pub differentiated: f64,
}

fn clampf(x: f64, lo: f64, hi: f64) -> f64 {
    x.max(lo).min(hi)
}

/// The objective `obj` for a policy whose log-probabilities of the batch's actions are
/// `logp` and whose mean KL from the batch's `dist_old` is `kl_mean`.
// written index by index, as the paper's sums over the batch
#[allow(clippy::needless_range_loop)]
pub fn ref_terms_dist(obj: &Objective, dist: &RefDist, b: &RefBatch) -> RefTerms {
    let logp = dist.log_prob(&b.actions);
    let kl_mean = mean(&dist.kl_from(&b.dist_old));
    let n = b.len();
    let ratio: Vec<f64> = (0..n).map(|i| (logp[i] - b.logp_old[i]).exp()).collect();
    let mut kink = f64::INFINITY;
    let surr_clipped = |eps: f64, kink: &mut f64| -> f64 {
        let mut s = 0.0;
        for i in 0..n {
            let r = ratio[i];
            *kink = kink
                .min((r - (1.0 - eps)).abs())
                .min((r - (1.0 + eps)).abs());
            s += (r * b.adv[i]).min(clampf(r, 1.0 - eps, 1.0 + eps) * b.adv[i]);
        }
        s / n as f64
    };
    let only = |ms: f64, kink: f64| RefTerms {
        objective: ms,
        mean_surr: ms,
        mean_variance: None,
        variance_mean: None,
        min_j_sq: None,
        switch_margin: None,
        kink_margin: kink,
        differentiated: ms,
    };
    match *obj {
        Objective::A2c => only(
            mean(&(0..n).map(|i| logp[i] * b.adv[i]).collect::<Vec<_>>()),
            kink,
        ),
        Objective::Trpo => only(
            mean(&(0..n).map(|i| ratio[i] * b.adv[i]).collect::<Vec<_>>()),
            kink,
        ),
        Objective::Ppo { clip } => {
            let ms = surr_clipped(clip, &mut kink);
            only(ms, kink)
        }
        Objective::AlphaPpo { alpha, beta } => {
            let ms = mean(&(0..n).map(|i| ratio[i] * b.adv[i]).collect::<Vec<_>>());
            let div = mean(&dist.alpha_divergence_from(&b.dist_old, alpha));
            let objective = (1.0 - beta) * ms - beta * div;
            RefTerms {
                objective,
                differentiated: objective,
                ..only(ms, kink)
            }
        }
        Objective::Vmpo(p) => {
            let (policy, temperature, trust) = ref_vmpo(&p, &logp, kl_mean, &b.adv);
            RefTerms {
                objective: -(policy + temperature + trust),
                differentiated: -(policy + p.alpha * kl_mean),
                ..only(-policy, kink)
            }
        }
        Objective::Apo(p) | Objective::Papo { params: p, .. } => {
            let clip = match *obj {
                Objective::Papo { clip, .. } => Some(clip),
                _ => None,
            };
            let ms = match clip {
                None => mean(&(0..n).map(|i| ratio[i] * b.adv[i]).collect::<Vec<_>>()),
                Some(eps) => surr_clipped(eps, &mut kink),
            };
            if p.k == 0.0 {
                return only(ms, kink);
            }
            let g = p.gamma;
            let max_abs_adv = b.adv.iter().map(|a| a.abs()).fold(0.0, f64::max);
            let h: Vec<f64> = (0..n)
                .map(|i| match p.h_max {
                    HMax::Fixed(w2) => w2,
                    HMax::Estimated => {
                        2.0 * g * (1.0 + g) / (1.0 - g).powi(2) * max_abs_adv * kl_mean
                            + (ratio[i] * b.adv[i]).abs()
                    }
                })
                .collect();
            // the penalty's units: reward (the batch's own numbers) or σ_A
            let unit = match p.units {
                PenaltyUnits::Reward => 1.0,
                PenaltyUnits::Advantage => b.adv_scale,
            };
            let delta: Vec<f64> = b.delta.iter().map(|d| d / unit).collect();
            let value: Vec<f64> = b.value.iter().map(|v| v / unit).collect();
            let t = |r: f64, i: usize| (r - 1.0) * delta[i] * delta[i] + 2.0 * r * delta[i] * h[i];
            let mut mv_sum = 0.0;
            for i in 0..n {
                match clip {
                    None => {
                        let ti = t(ratio[i], i);
                        kink = kink.min(ti.abs());
                        mv_sum += ti.abs();
                    }
                    Some(eps) => {
                        let (a, c) = (t(ratio[i], i), t(clampf(ratio[i], 1.0 - eps, 1.0 + eps), i));
                        // min(t(r), t(c)) has a kink where they cross outside the clip range
                        if (ratio[i] - clampf(ratio[i], 1.0 - eps, 1.0 + eps)).abs() > 0.0 {
                            kink = kink.min((a - c).abs());
                        }
                        mv_sum += a.min(c);
                    }
                }
            }
            let mv = p.omega1 * mv_sum / n as f64;
            let max_adv = b.adv.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let mean_dlogp = mean(&(0..n).map(|i| b.logp_old[i] - logp[i]).collect::<Vec<_>>());
            let bias = 4.0 * g * mean_dlogp.abs() * max_adv / (1.0 - g).powi(2);
            let mean_v = mean(&value);
            let margin = ms + mean_v - bias;
            let on = match p.switch {
                Switch::Paper => margin >= 0.0,
                // the paper's condition at θ_j: ratio 1 (mean_surr = mean(adv)) and bias 0
                Switch::Held => mean(&b.adv) + mean_v >= 0.0,
                Switch::Off => false,
            };
            let min_j_sq = if on { ms * ms + 2.0 * mean_v * ms } else { 0.0 };
            let spread = mean(
                &(0..n)
                    .map(|i| b.adv[i].abs().powi(2) + 2.0 * b.adv[i].abs() * value[i])
                    .collect::<Vec<_>>(),
            );
            let vm = p.omega1 * (1.0 - g * g) / p.k * spread - min_j_sq;
            RefTerms {
                objective: ms - p.k * (mv + vm),
                mean_surr: ms,
                mean_variance: Some(mv),
                variance_mean: Some(vm),
                min_j_sq: Some(min_j_sq),
                switch_margin: Some(margin),
                kink_margin: kink,
                differentiated: ms - p.k * (mv + vm),
            }
        }
    }
}

/// The objective of the MLP policy with parameters `theta`.
pub fn ref_objective(
    cfg: &MlpPolicyConfig,
    obj: &Objective,
    theta: &[f64],
    b: &RefBatch,
) -> RefTerms {
    ref_terms_dist(obj, &ref_policy(cfg, theta, &b.obs), b)
}

/// Mean `KL(π_old ‖ π_θ)` of the MLP policy on the batch.
pub fn ref_mean_kl(cfg: &MlpPolicyConfig, theta: &[f64], b: &RefBatch) -> f64 {
    mean(&ref_policy(cfg, theta, &b.obs).kl_from(&b.dist_old))
}

// ---------------------------------------------------------------------------------------
// Finite differences (float64)
// ---------------------------------------------------------------------------------------

/// Central differences `(f(θ + h e_i) − f(θ − h e_i)) / 2h`.
pub fn fd_gradient(f: impl Fn(&[f64]) -> f64, theta: &[f64], h: f64) -> Vec<f64> {
    let mut x = theta.to_vec();
    (0..theta.len())
        .map(|i| {
            x[i] = theta[i] + h;
            let fp = f(&x);
            x[i] = theta[i] - h;
            let fm = f(&x);
            x[i] = theta[i];
            (fp - fm) / (2.0 * h)
        })
        .collect()
}

/// Central differences in direction `v` of a gradient: `(g(θ + εv) − g(θ − εv)) / 2ε`.
pub fn fd_directional(
    g: impl Fn(&[f64]) -> Vec<f64>,
    theta: &[f64],
    v: &[f64],
    eps: f64,
) -> Vec<f64> {
    let plus: Vec<f64> = theta.iter().zip(v).map(|(t, vi)| t + eps * vi).collect();
    let minus: Vec<f64> = theta.iter().zip(v).map(|(t, vi)| t - eps * vi).collect();
    let (gp, gm) = (g(&plus), g(&minus));
    gp.iter()
        .zip(&gm)
        .map(|(a, b)| (a - b) / (2.0 * eps))
        .collect()
}

/// `∇²f(θ)·v` by mixed central differences of `f` alone:
/// `[f(θ+h eᵢ+εv) − f(θ+h eᵢ−εv) − f(θ−h eᵢ+εv) + f(θ−h eᵢ−εv)] / 4hε`.
/// No gradient code is involved, so this reference is independent of any autodiff.
pub fn fd_hvp_of_value(
    f: impl Fn(&[f64]) -> f64,
    theta: &[f64],
    v: &[f64],
    h: f64,
    eps: f64,
) -> Vec<f64> {
    let mut x = theta.to_vec();
    let mut eval = |i: usize, si: f64, sv: f64| {
        for (j, xj) in x.iter_mut().enumerate() {
            *xj = theta[j] + sv * eps * v[j];
        }
        x[i] += si * h;
        f(&x)
    };
    (0..theta.len())
        .map(|i| {
            (eval(i, 1.0, 1.0) - eval(i, 1.0, -1.0) - eval(i, -1.0, 1.0) + eval(i, -1.0, -1.0))
                / (4.0 * h * eps)
        })
        .collect()
}

/// A random unit vector.
pub fn unit_vector(n: usize, rng: &mut Rng) -> Vec<f64> {
    let v = rng.normals(n, 1.0);
    let s = norm(&v);
    v.iter().map(|x| x / s).collect()
}
