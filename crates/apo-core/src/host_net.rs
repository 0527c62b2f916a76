//! The built-in MLP on the host: forward, reverse (vector–Jacobian) and forward-mode
//! (Jacobian–vector) passes over plain `f32` arrays, for the host kernels of
//! [`crate::kernels::Kernels::Host`].
//!
//! Burn's autodiff runs these passes as a graph of separate tensor ops; on the NdArray
//! backend each op is its own pass over a `[batch, 64]` tensor, and those passes, not the
//! matmuls, are most of the time (`docs/benchmarks.md`). Here a layer is one matmul (the
//! `gemm` crate's or `matrixmultiply`'s, whichever is faster for the shape, see [`gemm`];
//! runtime-dispatched AVX-512/AVX2 kernels, one thread, so results are bit-reproducible) and
//! one sweep that adds the bias and applies the activation; the backward and tangent passes
//! fuse the activation's derivative into one sweep each.
//! Large batches are split into parts run in parallel ([`HostNet::run`]). Buffers are kept
//! between calls: nothing is allocated once the sizes are known.

/// Beyond this `|x|`, `tanh(x)` rounds to ±1 in f32 (`1 − tanh(9) = 3.0e−8`, below half an
/// ulp of 1).
const TANH_SATURATION: f32 = 9.0;

/// `1.5 · 2²³`: adding it rounds an `f32` of magnitude below 2²² to an integer, which is
/// then the low bits of the sum's representation.
const ROUNDING_MAGIC: f32 = 12_582_912.0;

/// `exp(x)` for `|x| ≤ 18` (the activation's range), with straight-line code the compiler
/// vectorizes: `x = k·ln 2 + r`, `|r| ≤ ln 2 / 2`, `exp(x) = 2^k · p(r)` with `p` the degree-7
/// Taylor polynomial of `exp` (truncation error below 5.3e−9 relative, under an f32 ulp).
#[inline(always)]
fn exp_reduced(x: f32) -> f32 {
    const LOG2_E: f32 = std::f32::consts::LOG2_E;
    // ln 2 split so that `k · LN2_HI` is exact for |k| < 2⁹
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    let shifted = x * LOG2_E + ROUNDING_MAGIC;
    let k = shifted - ROUNDING_MAGIC;
    let r = (x - k * LN2_HI) - k * LN2_LO;
    let p = 1.0
        + r * (1.0
            + r * (1.0 / 2.0
                + r * (1.0 / 6.0
                    + r * (1.0 / 24.0
                        + r * (1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0)))))));
    // `shifted`'s representation is 0x4B40_0000 + k; 2^k has exponent field k + 127
    let k_bits = shifted.to_bits().wrapping_sub(0x4B40_0000);
    f32::from_bits(k_bits.wrapping_add(127) << 23) * p
}

/// `tanh(x) = (e − 1) / (e + 1)` with `e = exp(2x)`, `x` clamped to ±[`TANH_SATURATION`];
/// NaN stays NaN. Absolute error ≤ 2e−7 against float64 `tanh` (unit-tested).
#[inline(always)]
fn tanh_scalar(x: f32) -> f32 {
    // `clamp` keeps NaN
    let x = x.clamp(-TANH_SATURATION, TANH_SATURATION);
    let e = exp_reduced(2.0 * x);
    (e - 1.0) / (e + 1.0)
}

/// Defines `$vis fn $name(args)` that runs the `#[inline(always)]` function `$body` compiled
/// for the widest vector unit the CPU has: AVX-512, AVX2 with FMA, or the baseline. Rust
/// never contracts `a * b + c` into a fused multiply-add and the bodies call no library
/// function, so every form performs the same IEEE operations and the result does not depend
/// on the CPU; only the width of the loops the compiler vectorizes does.
macro_rules! widest_simd {
    ($(#[$doc:meta])* $vis:vis fn $name:ident = $body:ident($($arg:ident: $ty:ty),* $(,)?)) => {
        $(#[$doc])*
        $vis fn $name($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
                fn avx512($($arg: $ty),*) {
                    $body($($arg),*)
                }
                #[target_feature(enable = "avx2,fma")]
                fn avx2($($arg: $ty),*) {
                    $body($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                    && std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: the CPU has every feature `avx512` is compiled for.
                    return unsafe { avx512($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: the CPU has every feature `avx2` is compiled for.
                    return unsafe { avx2($($arg),*) };
                }
            }
            $body($($arg),*)
        }
    };
}

#[inline(always)]
fn bias_tanh_body(rows: &mut [f32], bias: &[f32]) {
    for row in rows.chunks_exact_mut(bias.len()) {
        for (x, b) in row.iter_mut().zip(bias) {
            *x = tanh_scalar(*x + b);
        }
    }
}

widest_simd! {
    /// `row + bias` then `tanh`, in place, for each `[width]` row of `rows` (`[n, width]`).
    pub(crate) fn bias_tanh = bias_tanh_body(rows: &mut [f32], bias: &[f32])
}

#[inline(always)]
fn add_bias_body(rows: &mut [f32], bias: &[f32]) {
    for row in rows.chunks_exact_mut(bias.len()) {
        for (v, b) in row.iter_mut().zip(bias) {
            *v += b;
        }
    }
}

widest_simd! {
    /// `row + bias` for each `[width]` row of `rows` (`[n, width]`).
    pub(crate) fn add_bias = add_bias_body(rows: &mut [f32], bias: &[f32])
}

/// `row_out[start..start + C] += row_in · W[:, start..start + C]` with the chunk in a
/// fixed-size accumulator, which the compiler keeps in vector registers over the whole sum.
#[inline(always)]
fn add_chunk<const C: usize>(row_in: &[f32], weight: &[f32], start: usize, row_out: &mut [f32]) {
    let output = row_out.len();
    let mut acc = [0.0f32; C];
    acc.copy_from_slice(&row_out[start..start + C]);
    for (&xi, w) in row_in.iter().zip(weight.chunks_exact(output)) {
        let w = &w[start..start + C];
        for j in 0..C {
            acc[j] += xi * w[j];
        }
    }
    row_out[start..start + C].copy_from_slice(&acc);
}

#[inline(always)]
fn rows_times_weight_body(x: &[f32], weight: &[f32], input: usize, out: &mut [f32]) {
    let output = weight.len() / input.max(1);
    if output == 0 {
        return;
    }
    for (row_in, row_out) in x.chunks_exact(input).zip(out.chunks_exact_mut(output)) {
        let mut start = 0;
        while start + 64 <= output {
            add_chunk::<64>(row_in, weight, start, row_out);
            start += 64;
        }
        while start + 16 <= output {
            add_chunk::<16>(row_in, weight, start, row_out);
            start += 16;
        }
        if start < output {
            for (&xi, w) in row_in.iter().zip(weight.chunks_exact(output)) {
                for (o, &wij) in row_out[start..].iter_mut().zip(&w[start..]) {
                    *o += xi * wij;
                }
            }
        }
    }
}

widest_simd! {
    /// `out += x·W` row by row, for a few rows: `x` is `[n, input]`, `W` `[input, output]`
    /// (row-major, a few kilobytes that stay in L1), `out` `[n, output]`. Each row of `out` is
    /// a sum of `W`'s rows scaled by `x`'s, accumulated in chunks of 64 and 16 columns held in
    /// registers (pad `output` to a multiple of 16 to use only those), each sum in input
    /// order; no packing, which would cost more than a rollout's policy call.
    pub(crate) fn rows_times_weight = rows_times_weight_body(
        x: &[f32],
        weight: &[f32],
        input: usize,
        out: &mut [f32],
    )
}

#[inline(always)]
fn column_sums_body(rows: &[f32], sums: &mut [f32]) {
    sums.fill(0.0);
    for row in rows.chunks_exact(sums.len()) {
        for (g, d) in sums.iter_mut().zip(row) {
            *g += d;
        }
    }
}

widest_simd! {
    /// `sums = Σ rows`, the column sums of `rows` (`[n, width]`), summed in row order.
    fn column_sums = column_sums_body(rows: &[f32], sums: &mut [f32])
}

#[inline(always)]
fn times_tanh_derivative_body(delta: &mut [f32], act: &[f32]) {
    for (d, a) in delta.iter_mut().zip(act) {
        *d *= 1.0 - a * a;
    }
}

widest_simd! {
    /// `δ ⊙ (1 − a²)`, in place: through `tanh` backwards, with `a = tanh(h)`.
    fn times_tanh_derivative = times_tanh_derivative_body(delta: &mut [f32], act: &[f32])
}

#[inline(always)]
fn bias_times_tanh_derivative_body(rows: &mut [f32], bias: &[f32], act: &[f32]) {
    for (row, a_row) in rows
        .chunks_exact_mut(bias.len())
        .zip(act.chunks_exact(bias.len()))
    {
        for ((h, db), a) in row.iter_mut().zip(bias).zip(a_row) {
            *h = (*h + db) * (1.0 - a * a);
        }
    }
}

widest_simd! {
    /// `(row + bias) ⊙ (1 − a²)`, in place, for each `[width]` row of `rows` and of `act`:
    /// a tangent through the bias and then through `tanh`.
    fn bias_times_tanh_derivative = bias_times_tanh_derivative_body(
        rows: &mut [f32],
        bias: &[f32],
        act: &[f32],
    )
}

/// Below this inner dimension `k`, [`gemm`] calls `matrixmultiply`; from it on, the `gemm`
/// crate. Measured on the layers' shapes (parts of 1 250 rows, widths 1–64, one thread, Zen 4):
/// the `gemm` crate is 1.3–1.4× faster on the (64, 64) layers' forward and input-gradient
/// products and 2–9× on a thin output layer's forward (it packs less), while
/// `matrixmultiply` is 7× faster on the input gradient of a 2-wide output (`k` = 2).
const GEMM_CRATE_MIN_K: usize = 5;

/// `C = A·B + β·C`: `A` is `[m, k]` read with row stride `rsa` and column stride `csa`, `B`
/// is `[k, n]` with strides `(rsb, csb)`, `C` is `[m, n]` row-major. One thread, so each
/// call's result depends only on its operands and the CPU's kernels.
pub(crate) fn gemm(
    (m, k, n): (usize, usize, usize),
    a: &[f32],
    (rsa, csa): (usize, usize),
    b: &[f32],
    (rsb, csb): (usize, usize),
    beta: f32,
    c: &mut [f32],
) {
    let last = |rows: usize, cols: usize, rs: usize, cs: usize| {
        if rows == 0 || cols == 0 {
            0
        } else {
            (rows - 1) * rs + (cols - 1) * cs + 1
        }
    };
    // the bounds both kernels rely on; our callers size every buffer from the same dims
    assert!(a.len() >= last(m, k, rsa, csa) && b.len() >= last(k, n, rsb, csb));
    assert!(c.len() >= m * n);
    if k >= GEMM_CRATE_MIN_K {
        // SAFETY: the asserts above keep every element read or written inside the slices;
        // `c` does not alias `a` or `b` (it is borrowed mutably). The `gemm` crate computes
        // `dst = alpha·dst + beta·lhs·rhs`, reading `dst` only when asked to.
        unsafe {
            gemm::gemm(
                m,
                n,
                k,
                c.as_mut_ptr(),
                1,
                n as isize,
                beta != 0.0,
                a.as_ptr(),
                csa as isize,
                rsa as isize,
                b.as_ptr(),
                csb as isize,
                rsb as isize,
                beta,
                1.0,
                false,
                false,
                false,
                gemm::Parallelism::None,
            )
        }
        return;
    }
    // SAFETY: as above.
    unsafe {
        matrixmultiply::sgemm(
            m,
            k,
            n,
            1.0,
            a.as_ptr(),
            rsa as isize,
            csa as isize,
            b.as_ptr(),
            rsb as isize,
            csb as isize,
            beta,
            c.as_mut_ptr(),
            n as isize,
            1,
        )
    }
}

/// One layer's place in the flat parameter vector.
#[derive(Debug, Clone, Copy)]
struct Layer {
    input: usize,
    output: usize,
    /// Offset of the weight `[input, output]` (row-major); the bias `[output]` follows it.
    weight: usize,
}

impl Layer {
    fn bias(&self) -> usize {
        self.weight + self.input * self.output
    }

    fn end(&self) -> usize {
        self.bias() + self.output
    }
}

/// A batch is split into parts of at least this many rows…
const MIN_ROWS_PER_PART: usize = 256;
/// …and at most this many parts, run in parallel on rayon's pool.
const MAX_PARTS: usize = 8;

/// The buffers of one part of a batch (a contiguous range of rows).
#[derive(Debug, Clone, Default)]
pub(crate) struct Part {
    /// `acts[l]`: the output of layer `l` for the part's rows, `[rows, layers[l].output]`
    /// (after `tanh` for hidden layers), from the last forward pass.
    acts: Vec<Vec<f32>>,
    /// Two `[rows, width]` buffers the backward and tangent passes alternate between.
    scratch: [Vec<f32>; 2],
    /// The part's contribution to the gradient, `[num_params]`.
    grads: Vec<f32>,
    /// A `[rows, output]` buffer for the caller (the loss's gradient, `M J v`).
    pub(crate) head: Vec<f32>,
    /// A scalar the caller sums over parts (a partial loss).
    pub(crate) sum: f64,
}

impl Part {
    /// The output of the last forward pass, `[rows, output]`.
    pub(crate) fn output(&self) -> &[f32] {
        self.acts.last().map_or(&[], |a| a.as_slice())
    }

    /// The network's output from the last forward pass, `[rows, output]`, and the caller's
    /// buffer.
    pub(crate) fn output_and_head(&mut self) -> (&[f32], &mut Vec<f32>) {
        (
            self.acts.last().map_or(&[], |a| a.as_slice()),
            &mut self.head,
        )
    }
}

/// The layers and parameters, shared read-only by the parts' threads.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Weights<'a> {
    layers: &'a [Layer],
    params: &'a [f32],
}

impl Weights<'_> {
    /// The forward pass on the part's rows `x: [rows, input]`, keeping every layer's output
    /// (the network's, `[rows, output]`: [`Part::output_and_head`]).
    pub(crate) fn forward(&self, part: &mut Part, x: &[f32]) {
        let n = x.len() / self.layers[0].input;
        part.acts.resize(self.layers.len(), Vec::new());
        for (l, layer) in self.layers.iter().enumerate() {
            let (below, here) = part.acts.split_at_mut(l);
            let input: &[f32] = if l == 0 { x } else { &below[l - 1] };
            let out = &mut here[0];
            out.resize(n * layer.output, 0.0);
            gemm(
                (n, layer.input, layer.output),
                input,
                (layer.input, 1),
                &self.params[layer.weight..layer.bias()],
                (layer.output, 1),
                0.0,
                out,
            );
            let bias = &self.params[layer.bias()..layer.end()];
            if l + 1 < self.layers.len() {
                bias_tanh(out, bias);
            } else {
                add_bias(out, bias);
            }
        }
    }

    /// The reverse pass after [`Weights::forward`] on the same part: with `part.head =
    /// ∂L/∂output` for its rows `x: [rows, input]`, writes the part's `∂L/∂θ` to its gradient.
    pub(crate) fn backward(&self, part: &mut Part, x: &[f32]) {
        let n = x.len() / self.layers[0].input;
        let Part {
            acts,
            scratch: [current, below],
            grads,
            head,
            ..
        } = part;
        grads.resize(self.params.len(), 0.0);
        current.clear();
        current.extend_from_slice(head);
        for (l, layer) in self.layers.iter().enumerate().rev() {
            let input: &[f32] = if l == 0 { x } else { &acts[l - 1] };
            let (w, b) = (layer.weight, layer.bias());
            // ∂L/∂W = inputᵀ · δ, [input, output]
            gemm(
                (layer.input, n, layer.output),
                input,
                (1, layer.input),
                current,
                (layer.output, 1),
                0.0,
                &mut grads[w..b],
            );
            // ∂L/∂b = column sums of δ
            column_sums(current, &mut grads[b..layer.end()]);
            if l > 0 {
                // δ of the layer below: δ · Wᵀ, then through tanh, ⊙ (1 − a²)
                below.resize(n * layer.input, 0.0);
                gemm(
                    (n, layer.output, layer.input),
                    current,
                    (layer.output, 1),
                    &self.params[w..b],
                    (1, layer.output),
                    0.0,
                    below,
                );
                times_tanh_derivative(below, input);
                std::mem::swap(current, below);
            }
        }
    }

    /// The forward-mode pass after [`Weights::forward`] on the same part's rows `x` (a
    /// constant): the derivative of the output along the parameter direction `tangent`
    /// (`[num_params]`, flat like the parameters), `[rows, output]`, into `part.head`.
    ///
    /// Per layer, with `h = x·W + b` and `a = tanh(h)`: `ḣ = ẋ·W + x·Ẇ + ḃ`,
    /// `ȧ = (1 − a²) ⊙ ḣ`; the output layer has no activation.
    pub(crate) fn jvp(&self, part: &mut Part, x: &[f32], tangent: &[f32]) {
        let n = x.len() / self.layers[0].input;
        let Part {
            acts,
            scratch: [current, below],
            head,
            ..
        } = part;
        for (l, layer) in self.layers.iter().enumerate() {
            let input: &[f32] = if l == 0 { x } else { &acts[l - 1] };
            // from the second layer on, `below` holds ẋ (the layer below's ȧ)
            std::mem::swap(current, below);
            current.resize(n * layer.output, 0.0);
            gemm(
                (n, layer.input, layer.output),
                input,
                (layer.input, 1),
                &tangent[layer.weight..layer.bias()],
                (layer.output, 1),
                0.0,
                current,
            );
            if l > 0 {
                gemm(
                    (n, layer.input, layer.output),
                    below,
                    (layer.input, 1),
                    &self.params[layer.weight..layer.bias()],
                    (layer.output, 1),
                    1.0,
                    current,
                );
            }
            let d_bias = &tangent[layer.bias()..layer.end()];
            if l + 1 < self.layers.len() {
                bias_times_tanh_derivative(current, d_bias, &acts[l]);
            } else {
                add_bias(current, d_bias);
            }
        }
        head.clear();
        head.extend_from_slice(current);
    }
}

/// A host copy of a [`crate::mlp::Mlp`] (tanh hidden layers, linear output) with the
/// buffers of its passes.
///
/// Parameters (and every flat vector in parameter space) are in Burn's visiting order of
/// the `Mlp`: per layer the weight `[input, output]` row-major, then the bias.
///
/// A batch of `n` rows is cut into `clamp(n / 256, 1, 8)` parts of consecutive rows, run in
/// parallel on rayon's thread pool ([`HostNet::run`]); gradients are summed over the parts in
/// order. The split depends on `n` only and each element is computed by one thread in a fixed
/// order, so results do not depend on the number of threads or on scheduling.
#[derive(Debug, Clone)]
pub(crate) struct HostNet {
    layers: Vec<Layer>,
    /// θ, `[num_params]`.
    pub(crate) params: Vec<f32>,
    /// The gradient summed by the last [`HostNet::sum_grads`], `[num_params]`.
    pub(crate) grads: Vec<f32>,
    parts: Vec<Part>,
    /// Most parts a batch is cut into.
    max_parts: usize,
}

impl HostNet {
    /// From per-layer `(weight [input, output] row-major, bias [output])`; `None` if the
    /// shapes do not chain or there is no layer.
    pub(crate) fn new(layers: &[(Vec<f32>, Vec<f32>)]) -> Option<Self> {
        let mut params = Vec::new();
        let mut placed = Vec::with_capacity(layers.len());
        for (weight, bias) in layers {
            let output = bias.len();
            if output == 0 || weight.len() % output != 0 {
                return None;
            }
            let input = weight.len() / output;
            if input == 0 || placed.last().is_some_and(|l: &Layer| l.output != input) {
                return None;
            }
            placed.push(Layer {
                input,
                output,
                weight: params.len(),
            });
            params.extend_from_slice(weight);
            params.extend_from_slice(bias);
        }
        if placed.is_empty() {
            return None;
        }
        Some(Self {
            layers: placed,
            grads: vec![0.0; params.len()],
            params,
            parts: Vec::new(),
            max_parts: MAX_PARTS,
        })
    }

    /// Input width.
    pub(crate) fn input(&self) -> usize {
        self.layers[0].input
    }

    /// Output width.
    pub(crate) fn output(&self) -> usize {
        self.layers[self.layers.len() - 1].output
    }

    /// Number of parameters.
    pub(crate) fn num_params(&self) -> usize {
        self.params.len()
    }

    /// Splits batches into at most `parts` parts (at least 1).
    #[cfg(test)]
    pub(crate) fn set_max_parts(&mut self, parts: usize) {
        self.max_parts = parts.max(1);
    }

    /// The number of parts of a batch of `n` rows.
    fn num_parts(&self, n: usize) -> usize {
        (n / MIN_ROWS_PER_PART).clamp(1, self.max_parts)
    }

    /// Runs `pass(weights, part, rows, x_rows)` for every part of `x: [n, input]` (`rows`,
    /// its range of rows; `x_rows`, those rows of `x`), in parallel; a part keeps its buffers
    /// (its forward pass's activations included) until the next `run` on a batch of another
    /// size.
    pub(crate) fn run<F>(&mut self, x: &[f32], pass: F)
    where
        F: Fn(Weights<'_>, &mut Part, std::ops::Range<usize>, &[f32]) + Sync,
    {
        use rayon::prelude::*;
        let width = self.input();
        let n = x.len() / width;
        let parts = self.num_parts(n);
        self.parts.resize_with(parts, Part::default);
        let weights = Weights {
            layers: &self.layers,
            params: &self.params,
        };
        let job = |(i, part): (usize, &mut Part)| {
            let rows = i * n / parts..(i + 1) * n / parts;
            let x_rows = &x[rows.start * width..rows.end * width];
            pass(weights, part, rows, x_rows);
        };
        if parts == 1 {
            self.parts.iter_mut().enumerate().for_each(job);
        } else {
            self.parts.par_iter_mut().enumerate().for_each(job);
        }
    }

    /// The parts of the last [`HostNet::run`].
    pub(crate) fn parts(&self) -> &[Part] {
        &self.parts
    }

    /// Sums the parts' gradients (of the last [`HostNet::run`] that ran
    /// [`Weights::backward`]) in order into [`HostNet::grads`].
    pub(crate) fn sum_grads(&mut self) {
        self.grads.fill(0.0);
        for part in &self.parts {
            for (g, p) in self.grads.iter_mut().zip(&part.grads) {
                *g += p;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn tanh_within_2e7_of_f64_over_the_whole_range() {
        let mut xs: Vec<f32> = (-12_000..=12_000).map(|i| i as f32 * 1e-3).collect();
        xs.extend([
            -1e30,
            -88.0,
            -9.5,
            -1e-30,
            0.0,
            1e-30,
            9.5,
            88.0,
            1e30,
            f32::MAX,
        ]);
        let mut ys = xs.clone();
        bias_tanh(&mut ys, &[0.0]);
        let mut scalar = xs.clone();
        bias_tanh_body(&mut scalar, &[0.0]);
        for ((x, y), s) in xs.iter().zip(&ys).zip(&scalar) {
            let exact = f64::from(*x).tanh();
            assert!(
                (f64::from(*y) - exact).abs() <= 2e-7,
                "tanh({x}) = {y}, f64 {exact}"
            );
            assert_eq!(y.to_bits(), s.to_bits(), "dispatch changed tanh({x})");
        }
        let mut nan = [f32::NAN];
        bias_tanh(&mut nan, &[0.0]);
        assert!(nan[0].is_nan());
    }

    /// The MLP's output in f64, written independently of the kernel, `[n, output]`.
    pub(crate) fn forward_f64(params: &[f64], sizes: &[usize], x: &[f64]) -> Vec<f64> {
        let n = x.len() / sizes[0];
        let mut h: Vec<f64> = x.to_vec();
        let mut offset = 0;
        for (l, w) in sizes.windows(2).enumerate() {
            let (i, o) = (w[0], w[1]);
            let weight = &params[offset..offset + i * o];
            let bias = &params[offset + i * o..offset + i * o + o];
            offset += i * o + o;
            let mut next = vec![0.0; n * o];
            for r in 0..n {
                for c in 0..o {
                    let z: f64 = bias[c]
                        + (0..i)
                            .map(|k| h[r * i + k] * weight[k * o + c])
                            .sum::<f64>();
                    next[r * o + c] = if l + 2 < sizes.len() { z.tanh() } else { z };
                }
            }
            h = next;
        }
        h
    }

    /// Per layer, `(weight, bias)`.
    type Layers = Vec<(Vec<f32>, Vec<f32>)>;

    /// Random layers of `sizes` and `n` random inputs.
    pub(crate) fn random_net(sizes: &[usize], n: usize, seed: u64) -> (Layers, Vec<f32>) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let layers = sizes
            .windows(2)
            .map(|w| {
                let weight = (0..w[0] * w[1])
                    .map(|_| rng.random_range(-0.8..0.8))
                    .collect();
                let bias = (0..w[1]).map(|_| rng.random_range(-0.5..0.5)).collect();
                (weight, bias)
            })
            .collect();
        let x = (0..n * sizes[0])
            .map(|_| rng.random_range(-2.0..2.0))
            .collect();
        (layers, x)
    }

    fn widen(v: &[f32]) -> Vec<f64> {
        v.iter().map(|&x| f64::from(x)).collect()
    }

    /// `max |a − b| / max |b|`.
    fn rel_err(a: &[f64], b: &[f64]) -> f64 {
        let scale = b.iter().map(|v| v.abs()).fold(1e-30, f64::max);
        a.iter()
            .zip(b)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max)
            / scale
    }

    /// The output, `[n, output]`, over all parts.
    fn forward_all(net: &mut HostNet, x: &[f32]) -> Vec<f32> {
        net.run(x, |w, part, _, xr| w.forward(part, xr));
        let mut out = Vec::new();
        for part in &mut net.parts {
            out.extend_from_slice(part.output_and_head().0);
        }
        out
    }

    /// The built-in MLP has three forms, one description: Burn's [`crate::mlp::Mlp`] (the
    /// module the learner trains and checkpoints), [`crate::inference::HostMlp`] (the
    /// rollout's per-step forward pass, a few rows at a time, row by row) and [`HostNet`] (the
    /// update's batched forward, reverse and tangent passes, split in parts). The host forms
    /// are built from `Mlp::host_layers`, so the three must compute the same function.
    #[test]
    fn the_three_forms_of_the_mlp_compute_the_same_function() {
        use burn::backend::NdArray;
        use burn::tensor::{Tensor, TensorData};
        let device = Default::default();
        let (input, hidden, output, n) = (5, [16, 8], 3, 2500);
        <NdArray as burn::tensor::backend::Backend>::seed(&device, 3);
        let mlp = crate::mlp::Mlp::<NdArray>::new(input, &hidden, output, &device);
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        let x: Vec<f32> = (0..n * input)
            .map(|_| rng.random_range(-2.0..2.0))
            .collect();
        let burn: Vec<f32> = mlp
            .forward(Tensor::from_data(
                TensorData::new(x.clone(), [n, input]),
                &device,
            ))
            .into_data()
            .iter::<f32>()
            .collect();
        let layers = mlp.host_layers();
        let mut host_mlp = crate::inference::HostMlp::from_mlp(&mlp);
        // row loops below 32 rows, one matrix product per layer from there on, and from
        // 2 048 rows on parts of the rows in parallel (here 2 parts)
        let mut calls_of = |rows_per_call: usize| -> Vec<f32> {
            x.chunks(input * rows_per_call)
                .flat_map(|rows| host_mlp.forward(rows, rows.len() / input).to_vec())
                .collect()
        };
        let host_mlp_rows = calls_of(8);
        let host_mlp_batched = calls_of(40);
        let host_mlp_parts = calls_of(n);
        let mut net = HostNet::new(&layers).expect("shapes chain");
        let host_net = forward_all(&mut net, &x);
        for (form, out) in [
            ("HostMlp, 8 rows a call", &host_mlp_rows),
            ("HostMlp, 40 rows a call", &host_mlp_batched),
            ("HostMlp, 2 500 rows in 2 parts", &host_mlp_parts),
            ("HostNet", &host_net),
        ] {
            assert_eq!(out.len(), burn.len(), "{form}");
            let err = rel_err(&widen(out), &widen(&burn));
            assert!(err <= 1e-5, "{form} differs from Burn's Mlp by {err:e}");
        }
    }

    #[test]
    fn forward_backward_and_jvp_match_f64_references_in_one_and_several_parts() {
        let sizes = [5, 7, 6, 3];
        for (n, parts) in [(23, 1), (1600, 1), (1600, 3), (1600, 6)] {
            let (layers, x) = random_net(&sizes, n, 7);
            let mut net = HostNet::new(&layers).expect("shapes chain");
            net.set_max_parts(parts);
            assert_eq!(net.num_parts(n), parts);
            let params = widen(&net.params);
            let x64 = widen(&x);
            let out = widen(&forward_all(&mut net, &x));
            assert!(rel_err(&out, &forward_f64(&params, &sizes, &x64)) <= 1e-6);

            // backward: ∂/∂θ Σ ⟨c, out⟩ for a fixed c, against f64 central differences
            let mut rng = rand::rngs::StdRng::seed_from_u64(1);
            let c: Vec<f32> = (0..n * 3).map(|_| rng.random_range(-1.0..1.0)).collect();
            net.run(&x, |w, part, rows, xr| {
                w.forward(part, xr);
                part.head = c[rows.start * 3..rows.end * 3].to_vec();
                w.backward(part, xr);
            });
            net.sum_grads();
            let pairing = |p: &[f64]| -> f64 {
                forward_f64(p, &sizes, &x64)
                    .iter()
                    .zip(&c)
                    .map(|(o, c)| o * f64::from(*c))
                    .sum()
            };
            let eps = 1e-6;
            let fd: Vec<f64> = (0..params.len())
                .map(|i| {
                    let mut p = params.clone();
                    p[i] += eps;
                    let up = pairing(&p);
                    p[i] -= 2.0 * eps;
                    (up - pairing(&p)) / (2.0 * eps)
                })
                .collect();
            let err = rel_err(&widen(&net.grads), &fd);
            assert!(
                err <= 2e-6,
                "n {n}, {parts} parts: backward vs finite differences: {err}"
            );

            // jvp: the derivative of the output along a direction, against f64 central differences
            let v: Vec<f32> = (0..params.len())
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            net.run(&x, |w, part, _, xr| w.jvp(part, xr, &v));
            let jv: Vec<f32> = net.parts().iter().flat_map(|p| p.head.clone()).collect();
            let along = |s: f64| -> Vec<f64> {
                let p: Vec<f64> = params
                    .iter()
                    .zip(&v)
                    .map(|(p, v)| p + s * f64::from(*v))
                    .collect();
                forward_f64(&p, &sizes, &x64)
            };
            let (up, down) = (along(eps), along(-eps));
            let fd: Vec<f64> = up
                .iter()
                .zip(&down)
                .map(|(u, d)| (u - d) / (2.0 * eps))
                .collect();
            let err = rel_err(&widen(&jv), &fd);
            assert!(
                err <= 2e-6,
                "n {n}, {parts} parts: jvp vs finite differences: {err}"
            );
        }
    }

    #[test]
    fn shapes_that_do_not_chain_are_refused() {
        let layer = |i: usize, o: usize| (vec![0.0f32; i * o], vec![0.0f32; o]);
        assert!(HostNet::new(&[layer(3, 4), layer(5, 1)]).is_none());
        assert!(HostNet::new(&[(vec![0.0; 7], vec![0.0; 2])]).is_none());
        assert!(HostNet::new(&[]).is_none());
        let net = HostNet::new(&[layer(3, 4), layer(4, 2)]).expect("chains");
        assert_eq!((net.input(), net.output(), net.num_params()), (3, 2, 26));
    }
}
