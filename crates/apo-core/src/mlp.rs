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
            let h = h.matmul(layer.weight.val());
            let h = match &layer.bias {
                Some(bias) => h + bias.val().unsqueeze_dim(0),
                None => h,
            };
            if i < last {
                h.tanh()
            } else {
                h
            }
        })
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
