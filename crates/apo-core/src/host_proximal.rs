//! The proximal policy update of PAPO, PPO, ESPO, AlphaPPO, V-MPO and A2C on the host kernels
//! ([`Kernels::Host`](crate::kernels::Kernels::Host)).
//!
//! Each Adam step of [`crate::proximal::proximal_update`] is a forward pass of the policy's
//! network over the (mini)batch, the objective and its gradient, a reverse pass and Adam's
//! update. Here the network's passes run on a [`HostHead`] (one matmul and one fused sweep per
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
use rand::Rng;

use crate::adam::HostAdam;
use crate::distribution::DistParams;
use crate::host_head::{HostHead, Leaves};
use crate::objective::{Multipliers, Objective};
use crate::policy::Policy;
use crate::proximal::{run_proximal, Engine, ProximalReport, ProximalStep};
use crate::tensor_batch::TensorBatch;

/// The policy's network and log-stds as host arrays, with their Adam state.
struct HostEngine<AB: AutodiffBackend> {
    head: HostHead,
    /// Adam over the network's parameters, then the log-stds.
    adam: HostAdam,
    /// The update's observations, `[N, observation_dim]`.
    obs: Vec<f32>,
    /// The rows of the current minibatch (empty: the whole batch).
    gathered: Vec<f32>,
    /// The leaves of the last [`Engine::distribution`].
    leaves: Option<Leaves<AB>>,
}

impl<AB: AutodiffBackend> HostEngine<AB> {
    /// `None` when `policy` has no host form, or its form does not fit its flat parameters,
    /// its Adam state or the batch's observations `obs: [N, observation_dim]`.
    fn new<P: Policy<AB>>(policy: &P, adam: HostAdam, obs: Vec<f32>) -> Option<Self> {
        let head = HostHead::of(policy)?;
        let fits = adam.len() == head.num_params() && obs.len().is_multiple_of(head.net.input());
        fits.then(|| Self {
            head,
            adam,
            obs,
            gathered: Vec::new(),
            leaves: None,
        })
    }
}

/// The rows of the current minibatch, `gathered`, or the whole batch's `obs` when none were
/// gathered.
fn minibatch_rows<'a>(obs: &'a [f32], gathered: &'a [f32]) -> &'a [f32] {
    if gathered.is_empty() {
        obs
    } else {
        gathered
    }
}

impl<AB: AutodiffBackend> Engine<AB> for HostEngine<AB> {
    fn distribution(&mut self, part: &TensorBatch<AB>, rows: Option<&[usize]>) -> DistParams<AB> {
        let width = self.head.net.input();
        self.gathered.clear();
        if let Some(rows) = rows {
            for &r in rows {
                self.gathered
                    .extend_from_slice(&self.obs[r * width..(r + 1) * width]);
            }
        }
        let input = minibatch_rows(&self.obs, &self.gathered);
        let (dist, leaves) = self.head.distribution(input, &part.adv.device());
        self.leaves = Some(leaves);
        dist
    }

    fn step(&mut self, grads: AB::Gradients, part: &TensorBatch<AB>, lr: f64) {
        let Some(leaves) = self.leaves.take() else {
            return;
        };
        let input = minibatch_rows(&self.obs, &self.gathered);
        let mut grads = self.head.gradient(input, leaves, &grads).to_vec();
        if part.comm.is_distributed() {
            let mut totals: Vec<f64> = grads.iter().map(|&g| f64::from(g)).collect();
            part.comm.sum(&mut totals);
            for (g, t) in grads.iter_mut().zip(&totals) {
                *g = *t as f32;
            }
        }
        self.adam.step(self.head.params_mut(), &grads, lr as f32);
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
    if engine.obs.len() != batch.len() * engine.head.net.input() {
        return None;
    }
    let report = run_proximal(&mut engine, objective, batch, step, multipliers, rng);
    let (policy, optim) = engine
        .adam
        .write(policy.clone(), optim.clone(), &engine.head.params());
    Some((policy, optim, report))
}
