//! The built-in policy's network on the host kernels, its output made the leaves of a small
//! Burn graph.
//!
//! The policy updates evaluate the objective on the policy's distributions over the whole
//! batch, again and again: the proximal algorithms once per Adam step, the trust-region step
//! for its gradient and each line-search try, and every update before and after it for the
//! diagnostics. A [`HostHead`] runs the network's forward pass on [`HostNet`] (one matmul and
//! one fused sweep per layer, `f32`) and hands its output, the head (`[n, action_dim]` means or
//! `[n, n_actions]` logits), and the log-stds to Burn as the distribution's tensors. So every
//! objective in [`crate::objective`] runs unchanged on a graph of the head's size only; made
//! leaves of an autodiff graph, the objective's backward gives `∂/∂head`, and
//! [`HostHead::gradient`] carries it through the network by the reverse pass.

use burn::tensor::backend::{AutodiffBackend, Backend};
use burn::tensor::{Tensor, TensorData};

use crate::distribution::DistParams;
use crate::flat::{flatten, to_host};
use crate::host_net::HostNet;
use crate::policy::{HostForm, Policy};

/// The tensors a [`HostHead::distribution`] made its distribution from: the head
/// `[n, output]` and, for a Gaussian, the log-stds `[output]`.
pub(crate) struct Leaves<B: Backend> {
    head: Tensor<B, 2>,
    log_std: Option<Tensor<B, 1>>,
}

/// A policy with a [`HostForm`]: its network on the host, then its log-stds.
#[derive(Debug)]
pub(crate) struct HostHead {
    /// The network, whose `params` are θ's first part.
    pub(crate) net: HostNet,
    /// The log-stds `[action_dim]`, θ's last part (empty for a categorical policy).
    pub(crate) log_std: Vec<f32>,
    /// Whether the policy is a Gaussian.
    gaussian: bool,
    /// The gradient in the head, `[n, output]`, and the flat gradient `[num_params]`.
    head_grad: Vec<f32>,
    grads: Vec<f32>,
}

impl HostHead {
    /// `policy`'s network and log-stds; `None` when it has no host form or its form does not
    /// fit its flat parameters.
    pub(crate) fn of<B: Backend, P: Policy<B>>(policy: &P) -> Option<Self> {
        let HostForm { layers, log_std } = policy.host_form()?;
        let net = HostNet::new(&layers)?;
        let theta = to_host(flatten(policy));
        let rest = theta.get(net.num_params()..)?;
        let fits =
            rest.len() == log_std.unwrap_or(0) && log_std.is_none_or(|dim| dim == net.output());
        fits.then(|| Self {
            log_std: rest.iter().map(|&x| x as f32).collect(),
            gaussian: log_std.is_some(),
            net,
            head_grad: Vec::new(),
            grads: Vec::new(),
        })
    }

    /// Number of parameters: the network's, then the log-stds.
    pub(crate) fn num_params(&self) -> usize {
        self.net.num_params() + self.log_std.len()
    }

    /// θ, `[num_params]`.
    pub(crate) fn params(&self) -> Vec<f32> {
        let mut theta = self.net.params.clone();
        theta.extend_from_slice(&self.log_std);
        theta
    }

    /// θ's elements in order, to update in place.
    pub(crate) fn params_mut(&mut self) -> impl Iterator<Item = &mut f32> {
        self.net.params.iter_mut().chain(self.log_std.iter_mut())
    }

    /// Sets θ (`[num_params]`, rounded to `f32`).
    ///
    /// # Panics
    /// If `theta` does not have [`HostHead::num_params`] elements.
    pub(crate) fn set_params(&mut self, theta: &[f64]) {
        assert_eq!(
            theta.len(),
            self.num_params(),
            "HostHead::set_params: θ's length"
        );
        for (p, t) in self.params_mut().zip(theta) {
            *p = *t as f32;
        }
    }

    /// The distributions at the states `x: [n, input]`, on `device`, with the tensors they are
    /// made from (leaves of the graph when `B` is an autodiff backend). The forward pass is
    /// kept for [`HostHead::gradient`] on the same `x`.
    pub(crate) fn distribution<B: Backend>(
        &mut self,
        x: &[f32],
        device: &B::Device,
    ) -> (DistParams<B>, Leaves<B>) {
        self.net.run(x, |w, p, _, x_rows| w.forward(p, x_rows));
        let out = self.net.output();
        let mut head = Vec::with_capacity(x.len() / self.net.input() * out);
        for p in self.net.parts() {
            head.extend_from_slice(p.output());
        }
        let n = head.len() / out;
        let head =
            Tensor::<B, 2>::from_data(TensorData::new(head, [n, out]), device).require_grad();
        if !self.gaussian {
            let dist = DistParams::Categorical {
                logits: head.clone(),
            };
            return (
                dist,
                Leaves {
                    head,
                    log_std: None,
                },
            );
        }
        let log_std = Tensor::<B, 1>::from_data(
            TensorData::new(self.log_std.clone(), [self.log_std.len()]),
            device,
        )
        .require_grad();
        let dist = DistParams::Gaussian {
            mean: head.clone(),
            log_std: log_std.clone().unsqueeze_dim::<2>(0).expand([n, out]),
        };
        let log_std = Some(log_std);
        (dist, Leaves { head, log_std })
    }

    /// The gradient in θ, `[num_params]`, of the value whose backward gave `grads`, through the
    /// distributions of the last [`HostHead::distribution`] (on the same states `x`, which
    /// made `leaves`).
    pub(crate) fn gradient<AB: AutodiffBackend>(
        &mut self,
        x: &[f32],
        leaves: Leaves<AB>,
        grads: &AB::Gradients,
    ) -> &[f32] {
        let [n, out] = leaves.head.dims();
        self.head_grad.clear();
        match leaves.head.grad(grads) {
            Some(g) => self.head_grad.extend(g.into_data().iter::<f32>()),
            None => self.head_grad.resize(n * out, 0.0),
        }
        let d_log_std = leaves.log_std.and_then(|t| t.grad(grads));
        let head_grad = &self.head_grad;
        // the same rows, hence the same parts, as the forward pass the parts still hold
        self.net.run(x, |w, p, rows, x_rows| {
            p.head.clear();
            p.head
                .extend_from_slice(&head_grad[rows.start * out..rows.end * out]);
            w.backward(p, x_rows);
        });
        self.net.sum_grads();
        self.grads.clear();
        self.grads.extend_from_slice(&self.net.grads);
        match d_log_std {
            Some(d) => self.grads.extend(d.into_data().iter::<f32>()),
            None => self
                .grads
                .resize(self.grads.len() + self.log_std.len(), 0.0),
        }
        &self.grads
    }
}
