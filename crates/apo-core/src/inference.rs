//! Rollout inference on the host: the built-in MLP policy and critic as plain `f32`
//! arrays.
//!
//! The rollout is the hot path: one policy call per environment step. A Burn forward pass
//! per step costs tensor allocations and, on a GPU backend, a device round trip for a batch
//! of a few rows. So after each update the learner's MLPs are copied into these host
//! networks (a few thousand floats), which compute `x·W + b` and `tanh` in plain loops with
//! preallocated scratch buffers: no allocation per step.

use burn::tensor::backend::Backend;
use rand::Rng;
use rand_distr::StandardNormal;

use crate::host_net::{add_bias, bias_tanh, gemm, rows_times_weight};
use crate::mlp::Mlp;
use crate::policy::{ActionKind, MlpPolicy};
use crate::value::ValueNet;

/// From this many rows on (the critic's values over a finished path), a layer is one matrix
/// product, whose packing the rows amortize; below it (the policy's call, a row per
/// environment), plain row loops.
const BATCHED_ROWS: usize = 32;

/// From this many rows on (the critic over a whole epoch's path), the rows are cut into parts
/// of at least [`ROWS_PER_PART`] consecutive rows, at most [`MAX_PARTS`], computed in parallel
/// on rayon's pool. The cut depends on the number of rows only, so the values do not depend on
/// the number of threads.
const PARALLEL_ROWS: usize = 2 * ROWS_PER_PART;
/// See [`PARALLEL_ROWS`].
const ROWS_PER_PART: usize = 1024;
/// See [`PARALLEL_ROWS`].
const MAX_PARTS: usize = 8;

/// `0.5 * ln(2π)`.
const HALF_LN_2PI: f32 = 0.918_938_5;

/// Outputs are padded with zero columns to a multiple of this many lanes, so that the row
/// loops run on fixed-size chunks the compiler keeps in vector registers (an AVX-512 register
/// holds 16 `f32`).
const LANES: usize = 16;

/// One layer with its output padded to `width` columns: the padding's weights and biases are
/// zero, so its activations are `tanh(0) = 0`, and the next layer's rows for them are zero too.
#[derive(Debug, Clone)]
struct HostLayer {
    /// `[input, width]`, row-major.
    weight: Vec<f32>,
    /// `[width]`.
    bias: Vec<f32>,
    /// The rows of `weight`: the observation width for the first layer, else the layer
    /// below's `width`.
    input: usize,
    /// The true output width.
    output: usize,
    /// `output` rounded up to a multiple of [`LANES`].
    width: usize,
}

/// A host copy of an [`Mlp`] for the rollout's forward pass, a few rows per call (one per
/// environment). It differs from the update's `HostNet` (module `host_net`), which holds the
/// same layers for batches of thousands of rows with reverse and tangent passes split over
/// threads: here a call costs microseconds and must allocate nothing, so it is plain row
/// loops over one scratch pair (a matrix product's packing would cost more than the call),
/// or one product per layer from 32 rows on (the critic over a finished path), with the rows
/// cut into parts run on rayon's threads from 2 048 rows on (a whole epoch's path). Both are built
/// from [`Mlp::host_layers`]; `host_net`'s test
/// `the_three_forms_of_the_mlp_compute_the_same_function` checks that they agree with Burn's
/// module, row by row and batched.
#[derive(Debug, Clone)]
pub struct HostMlp {
    layers: Vec<HostLayer>,
    scratch: [Vec<f32>; 2],
    /// One scratch pair per part of a batch of [`PARALLEL_ROWS`] rows or more.
    parts: Vec<[Vec<f32>; 2]>,
    /// The parts' outputs side by side, `[n, output]`.
    out: Vec<f32>,
}

impl HostMlp {
    /// Copies `mlp`'s weights to the host.
    pub fn from_mlp<B: Backend>(mlp: &Mlp<B>) -> Self {
        let mut layers: Vec<HostLayer> = Vec::new();
        for (weight, bias) in mlp.host_layers() {
            let output = bias.len();
            let true_input = weight.len() / output.max(1);
            let input = layers.last().map_or(true_input, |below| below.width);
            let width = output.div_ceil(LANES) * LANES;
            let mut padded = vec![0.0; input * width];
            for (row, from) in padded
                .chunks_exact_mut(width)
                .zip(weight.chunks_exact(output))
            {
                row[..output].copy_from_slice(from);
            }
            let mut padded_bias = vec![0.0; width];
            padded_bias[..output].copy_from_slice(&bias);
            layers.push(HostLayer {
                weight: padded,
                bias: padded_bias,
                input,
                output,
                width,
            });
        }
        Self {
            layers,
            scratch: [Vec::new(), Vec::new()],
            parts: Vec::new(),
            out: Vec::new(),
        }
    }

    /// Input width.
    pub fn input(&self) -> usize {
        self.layers.first().map_or(0, |l| l.input)
    }

    /// Output width.
    pub fn output(&self) -> usize {
        self.layers.last().map_or(0, |l| l.output)
    }

    /// `x: [n, input]` → `[n, output]`, borrowed from internal scratch space.
    pub fn forward(&mut self, x: &[f32], n: usize) -> &[f32] {
        if n < PARALLEL_ROWS {
            return forward_rows(&self.layers, x, n, &mut self.scratch);
        }
        use rayon::prelude::*;
        let (input, output) = (self.input(), self.output());
        let parts = (n / ROWS_PER_PART).clamp(1, MAX_PARTS);
        self.parts.resize_with(parts, Default::default);
        let layers = &self.layers;
        self.parts
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, scratch)| {
                let rows = i * n / parts..(i + 1) * n / parts;
                let x = &x[rows.start * input..rows.end * input];
                forward_rows(layers, x, rows.len(), scratch);
            });
        self.out.clear();
        for (i, [a, _]) in self.parts.iter().enumerate() {
            let rows = (i + 1) * n / parts - i * n / parts;
            self.out.extend_from_slice(&a[..rows * output]);
        }
        &self.out
    }
}

/// `layers`' forward pass over `x: [n, input]` → `[n, output]`, in `scratch`: row loops below
/// [`BATCHED_ROWS`] rows, one matrix product per layer from there on.
fn forward_rows<'s>(
    layers: &[HostLayer],
    x: &[f32],
    n: usize,
    scratch: &'s mut [Vec<f32>; 2],
) -> &'s [f32] {
    let last = layers.len() - 1;
    let output = layers.last().map_or(0, |l| l.output);
    let [a, b] = scratch;
    a.clear();
    a.extend_from_slice(x);
    for (k, layer) in layers.iter().enumerate() {
        b.clear();
        b.resize(n * layer.width, 0.0);
        let x = &a[..n * layer.input];
        if n >= BATCHED_ROWS {
            let shape = (n, layer.input, layer.width);
            gemm(
                shape,
                x,
                (layer.input, 1),
                &layer.weight,
                (layer.width, 1),
                0.0,
                b,
            );
        } else {
            rows_times_weight(x, &layer.weight, layer.input, b);
        }
        if k < last {
            bias_tanh(b, &layer.bias);
        } else {
            add_bias(b, &layer.bias);
        }
        std::mem::swap(a, b);
    }
    // drop the output's padding: row r moves from r·width to r·output (never forwards)
    if let Some(width) = layers.last().map(|l| l.width) {
        if width != output {
            for r in 0..n {
                a.copy_within(r * width..r * width + output, r * output);
            }
        }
    }
    &a[..n * output]
}

/// Per-step outputs of [`HostPolicy::act`], preallocated for `n` rows.
#[derive(Debug, Clone, Default)]
pub struct ActBuffers {
    /// Actions as stored in the rollout buffer, `[n, action_width]` (one-hot rows for
    /// discrete actions).
    pub actions: Vec<f32>,
    /// Actions as passed to the environment, `[n, env_width]` (the index for discrete actions).
    pub env_actions: Vec<f32>,
    /// Log-probabilities of the actions, `[n]`.
    pub logp: Vec<f32>,
    /// Distribution parameters, `[n, dist_width]` (means then log-stds, or logits).
    pub dist: Vec<f32>,
}

/// A host copy of the built-in [`MlpPolicy`] that samples actions.
#[derive(Debug, Clone)]
pub struct HostPolicy {
    net: HostMlp,
    log_std: Option<Vec<f32>>,
    action: ActionKind,
}

impl HostPolicy {
    /// Copies `policy` (whose actions are `action`) to the host.
    pub fn new<B: Backend>(policy: &MlpPolicy<B>, action: ActionKind) -> Self {
        let log_std = policy
            .log_std
            .as_ref()
            .map(|p| p.val().into_data().iter::<f32>().collect());
        Self {
            net: HostMlp::from_mlp(&policy.net),
            log_std,
            action,
        }
    }

    /// Width of the distribution parameters per row.
    pub fn dist_width(&self) -> usize {
        self.action.dist_width()
    }

    /// Width of an action as the environment takes it.
    pub fn env_width(&self) -> usize {
        match self.action {
            ActionKind::Continuous { dim } => dim,
            ActionKind::Discrete { .. } => 1,
        }
    }

    /// Acts in `n` states `obs: [n, observation_dim]`: computes the distribution parameters
    /// into `out.dist` and samples from them ([`ActBuffers::sample`]; with `deterministic`,
    /// takes the mode).
    pub fn act(
        &mut self,
        obs: &[f32],
        n: usize,
        deterministic: bool,
        rng: &mut impl Rng,
        out: &mut ActBuffers,
    ) {
        let width = self.action.width();
        let dist_width = self.dist_width();
        out.dist.resize(n * dist_width, 0.0);
        let y = self.net.forward(obs, n);
        for r in 0..n {
            let y = &y[r * width..(r + 1) * width];
            let dist = &mut out.dist[r * dist_width..(r + 1) * dist_width];
            match &self.log_std {
                Some(log_std) => {
                    dist[..width].copy_from_slice(y);
                    dist[width..].copy_from_slice(log_std);
                }
                None => dist.copy_from_slice(y),
            }
        }
        out.sample(self.action, n, deterministic, rng);
    }
}

impl ActBuffers {
    /// Samples one action per row from the distribution parameters in `self.dist`
    /// (`[n, dist_width]`: means then log-stds for a Gaussian, logits for a categorical),
    /// filling `actions` (`[n, action_width]`), `env_actions` (`[n, env_width]`) and `logp`
    /// (`[n]`). With `deterministic`, takes the mode (the mean, or the most likely action).
    /// Gaussian rows draw `dim` standard normals in order, categorical rows one uniform.
    pub fn sample(
        &mut self,
        action: ActionKind,
        n: usize,
        deterministic: bool,
        rng: &mut impl Rng,
    ) {
        let width = action.width();
        let (dist_width, env_width) = (action.dist_width(), action.env_width());
        self.actions.resize(n * width, 0.0);
        self.env_actions.resize(n * env_width, 0.0);
        self.logp.resize(n, 0.0);
        for r in 0..n {
            let dist = &self.dist[r * dist_width..(r + 1) * dist_width];
            let action_row = &mut self.actions[r * width..(r + 1) * width];
            self.logp[r] = match action {
                ActionKind::Continuous { .. } => {
                    let (mean, log_std) = dist.split_at(width);
                    let mut logp = 0.0;
                    for ((a, &mean), &ls) in action_row.iter_mut().zip(mean).zip(log_std) {
                        let eps: f32 = if deterministic {
                            0.0
                        } else {
                            rng.sample(StandardNormal)
                        };
                        *a = mean + ls.exp() * eps;
                        logp += -0.5 * eps * eps - ls - HALF_LN_2PI;
                    }
                    self.env_actions[r * env_width..(r + 1) * env_width]
                        .copy_from_slice(action_row);
                    logp
                }
                ActionKind::Discrete { .. } => {
                    let y = dist;
                    let max = y.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                    let log_z = max + y.iter().map(|l| (l - max).exp()).sum::<f32>().ln();
                    let choice = if deterministic {
                        y.iter()
                            .enumerate()
                            .fold(0, |best, (i, &l)| if l > y[best] { i } else { best })
                    } else {
                        let u: f32 = rng.random();
                        let mut acc = 0.0;
                        y.iter()
                            .position(|&l| {
                                acc += (l - log_z).exp();
                                u < acc
                            })
                            .unwrap_or(width - 1)
                    };
                    action_row
                        .iter_mut()
                        .enumerate()
                        .for_each(|(i, a)| *a = if i == choice { 1.0 } else { 0.0 });
                    self.env_actions[r] = choice as f32;
                    y[choice] - log_z
                }
            };
        }
    }
}

/// A host copy of a [`ValueNet`].
#[derive(Debug, Clone)]
pub struct HostValue {
    net: HostMlp,
}

impl HostValue {
    /// Copies `value` to the host.
    pub fn new<B: Backend>(value: &ValueNet<B>) -> Self {
        Self {
            net: HostMlp::from_mlp(&value.net),
        }
    }

    /// `V(s)` for `obs: [n, observation_dim]` → `[n]`.
    pub fn values(&mut self, obs: &[f32], n: usize) -> &[f32] {
        self.net.forward(obs, n)
    }
}
