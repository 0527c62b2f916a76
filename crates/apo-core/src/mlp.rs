//! The multi-layer perceptron shared by the policies and the critic.

use burn::module::Module;
use burn::nn::{Linear, LinearConfig};
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;

/// A fully connected network with `tanh` after every hidden layer and a linear output,
/// as in the paper (hidden sizes (64, 64) by default).
#[derive(Module, Debug)]
pub struct Mlp<B: Backend> {
    layers: Vec<Linear<B>>,
}

impl<B: Backend> Mlp<B> {
    /// A network `input -> hidden[0] -> … -> hidden[last] -> output`.
    pub fn new(input: usize, hidden: &[usize], output: usize, device: &B::Device) -> Self {
        let sizes: Vec<usize> = std::iter::once(input)
            .chain(hidden.iter().copied())
            .chain(std::iter::once(output))
            .collect();
        let layers = sizes
            .windows(2)
            .map(|w| LinearConfig::new(w[0], w[1]).init(device))
            .collect();
        Self { layers }
    }

    /// `x: [batch, input]` → `[batch, output]`.
    ///
    /// Each layer is computed as `x·W + b` with `matmul` rather than Burn's fused `linear`
    /// op: the fused op's backward cannot be differentiated again, and the trust-region
    /// step needs second derivatives.
    pub fn forward(&self, x: Tensor<B, 2>) -> Tensor<B, 2> {
        let last = self.layers.len() - 1;
        self.layers.iter().enumerate().fold(x, |h, (i, layer)| {
            let h = affine(layer, h);
            if i < last {
                crate::activation::tanh(h)
            } else {
                h
            }
        })
    }

    /// The directional derivative of [`Mlp::forward`] with respect to the parameters, by
    /// forward-mode (tangent) propagation: `x: [batch, input]` (a constant, `ẋ = 0`) and
    /// `tangent`, a network of the same sizes whose weights and biases hold the direction
    /// `(Ẇ, ḃ)` of each layer, → `d/dε forward_{W + εẆ, b + εḃ}(x)` at `ε = 0`, `[batch, output]`.
    ///
    /// Per layer, with `h = x·W + b` and `a = tanh(h)` (the hidden activation, shared with
    /// [`Mlp::forward`]): `ḣ = ẋ·W + x·Ẇ + ḃ` and `ȧ = (1 − a²) ⊙ ḣ` (the derivative of `tanh`);
    /// the output layer has no activation. Runs on the plain backend, no autodiff: about
    /// the cost of two forward passes.
    pub fn jvp(&self, x: Tensor<B, 2>, tangent: &Mlp<B>) -> Tensor<B, 2> {
        let layers = self.layers.len();
        let (x, dx) = self.layers.iter().zip(&tangent.layers).enumerate().fold(
            (x, None::<Tensor<B, 2>>),
            |(x, dx), (i, (layer, d_layer))| {
                // x·Ẇ + ḃ, plus ẋ·W after the first layer
                let dh = affine(d_layer, x.clone());
                let dh = match dx {
                    Some(dx) => dh + dx.matmul(layer.weight.val()),
                    None => dh,
                };
                if i + 1 < layers {
                    let a = crate::activation::tanh(affine(layer, x));
                    let da = a.clone().square().neg().add_scalar(1.0) * dh;
                    (a, Some(da))
                } else {
                    (x, Some(dh))
                }
            },
        );
        // `None` only for a network without layers: the identity, which has no parameters
        dx.unwrap_or_else(|| x.zeros_like())
    }

    /// The weights and biases of each layer as host arrays, `(weight [in, out] row-major, bias [out])`.
    pub fn host_layers(&self) -> Vec<(Vec<f32>, Vec<f32>)> {
        self.layers
            .iter()
            .map(|l| {
                let w = l.weight.val().into_data().iter::<f32>().collect();
                let b = l
                    .bias
                    .as_ref()
                    .map(|b| b.val().into_data().iter::<f32>().collect())
                    .unwrap_or_else(|| vec![0.0; l.weight.val().dims()[1]]);
                (w, b)
            })
            .collect()
    }
}

/// `x·W + b` for one layer: `x: [batch, in]` → `[batch, out]` (weight `[in, out]`, bias `[out]`).
fn affine<B: Backend>(layer: &Linear<B>, x: Tensor<B, 2>) -> Tensor<B, 2> {
    let h = x.matmul(layer.weight.val());
    match &layer.bias {
        Some(bias) => h + bias.val().unsqueeze_dim(0),
        None => h,
    }
}
