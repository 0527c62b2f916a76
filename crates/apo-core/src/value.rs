//! The critic: a state-value MLP.

use burn::module::Module;
use burn::tensor::backend::Backend;
use burn::tensor::Tensor;
use serde::{Deserialize, Serialize};

use crate::mlp::Mlp;

/// Config of the value network (the paper's: tanh, (64, 64)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValueConfig {
    /// Observation dimension.
    pub observation_dim: usize,
    /// Hidden layer sizes.
    pub hidden: Vec<usize>,
}

impl ValueConfig {
    /// The value network on `device`.
    pub fn init<B: Backend>(&self, device: &B::Device) -> ValueNet<B> {
        ValueNet {
            net: Mlp::new(self.observation_dim, &self.hidden, 1, device),
        }
    }
}

/// State-value function `V(s)`.
#[derive(Module, Debug)]
pub struct ValueNet<B: Backend> {
    /// The network `obs → V`.
    pub net: Mlp<B>,
}

impl<B: Backend> ValueNet<B> {
    /// `obs: [batch, observation_dim]` → `V(s)`, `[batch]`.
    pub fn forward(&self, obs: Tensor<B, 2>) -> Tensor<B, 1> {
        self.net.forward(obs).squeeze_dim(1)
    }
}
