//! The proximal policy update of PAPO, PPO, ESPO, AlphaPPO, V-MPO and A2C on the host kernels
//! ([`Kernels::Host`](crate::kernels::Kernels::Host)).
//!
//! Each Adam step of [`crate::proximal::proximal_update`] is a forward pass of the policy's
//! network over the (mini)batch, the objective and its gradient, a reverse pass and Adam's
//! update. Here the network's passes run on [`HostNet`] (one matmul and one fused sweep per
//! layer, `f32`) and Adam on [`HostAdam`]. The objective stays Burn's: it is evaluated on the
//! network's output — the head, `[n, action_dim]` means or `[n, n_actions]` logits — made a
//! leaf of the autodiff graph, with the log-stds `[action_dim]` a second leaf, so every
//! objective in [`crate::objective`] runs unchanged and only this small graph is Burn's. Its
//! backward gives `∂loss/∂head`, the reverse pass's input.
//!
//! The steps draw the same minibatches from the same random stream as Burn's path, and the
//! policy and its Adam state stay Burn's (read before, written back after the update), so
//! checkpoints do not depend on where the update ran. Only the rounding differs (tests compare
//! the two paths over several epochs).

use burn::module::AutodiffModule;
use burn::optim::adaptor::OptimizerAdaptor;
use burn::optim::Adam;
use burn::tensor::backend::AutodiffBackend;
use burn::tensor::{Tensor, TensorData};
use rand::Rng;

use crate::adam::HostAdam;
use crate::distribution::DistParams;
use crate::flat::{flatten, to_host};
use crate::host_net::HostNet;
use crate::objective::{Multipliers, Objective};
use crate::policy::{HostForm, Policy};
use crate::proximal::{run_proximal, Engine, ProximalReport, ProximalStep};
use crate::tensor_batch::TensorBatch;

/// The policy's network and log-stds as host arrays, with their Adam state.
struct HostEngine<AB: AutodiffBackend> {
    net: HostNet,
    /// The log-stds `[action_dim]` (empty for a categorical policy).
    log_std: Vec<f32>,
    /// Whether the policy is a Gaussian.
    gaussian: bool,
    /// Adam over the network's parameters, then the log-stds.
    adam: HostAdam,
    /// The update's observations, `[N, observation_dim]`.
    obs: Vec<f32>,
    /// The rows of the current minibatch (empty: the whole batch).
    gathered: Vec<f32>,
    /// The leaves of the last [`Engine::distribution`]: the head and the log-stds.
    leaves: Option<(Tensor<AB, 2>, Option<Tensor<AB, 1>>)>,
    /// The gradient of the loss in the head, `[n, output]`, and the flat gradient.
    head_grad: Vec<f32>,
    grads: Vec<f32>,
}

impl<AB: AutodiffBackend> HostEngine<AB> {
    /// `None` when `policy` has no host form, or its form does not fit its flat parameters,
    /// its Adam state or the batch's observations `obs: [N, observation_dim]`.
    fn new<P: Policy<AB>>(policy: &P, adam: HostAdam, obs: Vec<f32>) -> Option<Self> {
        let HostForm { layers, log_std } = policy.host_form()?;
        let net = HostNet::new(&layers)?;
        let theta = to_host(flatten(policy));
        let rest = theta.get(net.num_params()..)?;
        let fits = rest.len() == log_std.unwrap_or(0)
            && adam.len() == theta.len()
            && log_std.is_none_or(|dim| dim == net.output())
            && obs.len().is_multiple_of(net.input());
        fits.then(|| Self {
            log_std: rest.iter().map(|&x| x as f32).collect(),
            gaussian: log_std.is_some(),
            net,
            adam,
            obs,
            gathered: Vec::new(),
            leaves: None,
            head_grad: Vec::new(),
            grads: Vec::new(),
        })
    }

    /// θ, `[num_params]`: the network's parameters, then the log-stds.
    fn params(&self) -> Vec<f32> {
        let mut theta = self.net.params.clone();
        theta.extend_from_slice(&self.log_std);
        theta
    }
}

/// `t`'s values as `f32`, `[numel]`.
fn host<B: burn::tensor::backend::Backend, const D: usize>(t: Tensor<B, D>) -> Vec<f32> {
    t.into_data().iter::<f32>().collect()
}

impl<AB: AutodiffBackend> Engine<AB> for HostEngine<AB> {
    fn distribution(&mut self, part: &TensorBatch<AB>, rows: Option<&[usize]>) -> DistParams<AB> {
        let width = self.net.input();
        self.gathered.clear();
        if let Some(rows) = rows {
            for &r in rows {
                self.gathered
                    .extend_from_slice(&self.obs[r * width..(r + 1) * width]);
            }
        }
        let input: &[f32] = if self.gathered.is_empty() {
            &self.obs
        } else {
            &self.gathered
        };
        self.net.run(input, |w, p, _, x_rows| w.forward(p, x_rows));
        let out = self.net.output();
        let mut head = Vec::with_capacity(input.len() / width * out);
        for p in self.net.parts() {
            head.extend_from_slice(p.output());
        }
        let n = head.len() / out;
        let device = part.adv.device();
        let head =
            Tensor::<AB, 2>::from_data(TensorData::new(head, [n, out]), &device).require_grad();
        if self.gaussian {
            let log_std = Tensor::<AB, 1>::from_data(
                TensorData::new(self.log_std.clone(), [self.log_std.len()]),
                &device,
            )
            .require_grad();
            self.leaves = Some((head.clone(), Some(log_std.clone())));
            DistParams::Gaussian {
                mean: head,
                log_std: log_std.unsqueeze_dim::<2>(0).expand([n, out]),
            }
        } else {
            self.leaves = Some((head.clone(), None));
            DistParams::Categorical { logits: head }
        }
    }

    fn step(&mut self, grads: AB::Gradients, part: &TensorBatch<AB>, lr: f64) {
        let Some((head, log_std)) = self.leaves.take() else {
            return;
        };
        let [n, out] = head.dims();
        self.head_grad.clear();
        match head.grad(&grads) {
            Some(g) => self.head_grad.extend(host(g)),
            None => self.head_grad.resize(n * out, 0.0),
        }
        let d_log_std = log_std.and_then(|t| t.grad(&grads)).map(host);
        let input: &[f32] = if self.gathered.is_empty() {
            &self.obs
        } else {
            &self.gathered
        };
        let head_grad = &self.head_grad;
        // the same rows, hence the same parts, as the forward pass the parts still hold
        self.net.run(input, |w, p, rows, x_rows| {
            p.head.clear();
            p.head
                .extend_from_slice(&head_grad[rows.start * out..rows.end * out]);
            w.backward(p, x_rows);
        });
        self.net.sum_grads();
        self.grads.clear();
        self.grads.extend_from_slice(&self.net.grads);
        match d_log_std {
            Some(d) => self.grads.extend(d),
            None => self
                .grads
                .resize(self.grads.len() + self.log_std.len(), 0.0),
        }
        if part.comm.is_distributed() {
            let mut totals: Vec<f64> = self.grads.iter().map(|&g| f64::from(g)).collect();
            part.comm.sum(&mut totals);
            for (g, t) in self.grads.iter_mut().zip(&totals) {
                *g = *t as f32;
            }
        }
        self.adam.step(
            self.net.params.iter_mut().chain(self.log_std.iter_mut()),
            &self.grads,
            lr as f32,
        );
    }
}

/// [`crate::proximal::proximal_update`] with the policy's passes and Adam on the host: the
/// updated policy and optimizer and the report, or `None` (nothing consumed from `rng`, nothing
/// changed) when the policy has no host form that fits `obs` (`[N, observation_dim]`, the rows
/// of `batch`).
#[allow(clippy::too_many_arguments)]
pub(crate) fn host_proximal_update<AB, P>(
    policy: &P,
    optim: &OptimizerAdaptor<Adam, P, AB>,
    objective: &Objective,
    obs: &[f32],
    batch: &TensorBatch<AB>,
    step: ProximalStep<'_>,
    multipliers: Option<&mut Multipliers>,
    rng: &mut impl Rng,
) -> Option<(P, OptimizerAdaptor<Adam, P, AB>, ProximalReport)>
where
    AB: AutodiffBackend,
    P: Policy<AB> + AutodiffModule<AB>,
{
    let adam = HostAdam::read(policy, optim);
    let mut engine = HostEngine::<AB>::new(policy, adam, obs.to_vec())?;
    if engine.obs.len() != batch.len() * engine.net.input() {
        return None;
    }
    let report = run_proximal(&mut engine, objective, batch, step, multipliers, rng);
    let (policy, optim) = engine
        .adam
        .write(policy.clone(), optim.clone(), &engine.params());
    Some((policy, optim, report))
}
