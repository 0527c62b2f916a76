//! The proximal step of PPO, PAPO, A2C, ESPO, AlphaPPO and V-MPO (Adam with early stopping),
//! and the value update shared by every algorithm (Adam on the mean squared error to the
//! rewards-to-go).

use burn::module::AutodiffModule;
use burn::optim::{GradientsParams, Optimizer};
use burn::tensor::backend::AutodiffBackend;
use burn::tensor::Tensor;
use rand::seq::SliceRandom;
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::distribution::DistParams;
use crate::flat::to_host;
use crate::objective::vmpo::VmpoTerms;
use crate::objective::{Multipliers, Objective};
use crate::policy::Policy;
use crate::tensor_batch::TensorBatch;
use crate::validate::{check, ConfigError};
use crate::value::ValueNet;

/// Settings of an Adam-based update.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProximalConfig {
    /// Adam learning rate (paper: 3e-4 for policies, 1e-3 for the value).
    pub lr: f64,
    /// Passes over the batch (paper: 80).
    pub iters: usize,
    /// Stop before a gradient step once the approximate KL `mean(logp_old − logp)` of the
    /// step's (mini)batch exceeds this (paper: 0.02); `None` never stops early.
    pub target_kl: Option<f64>,
    /// Minibatch size; `None` is full-batch (the default).
    pub minibatch_size: Option<usize>,
}

impl ProximalConfig {
    /// The paper's policy update: 80 full-batch Adam passes at lr 3e-4, stopping once the
    /// approximate KL exceeds 0.02.
    pub const PAPER_POLICY: ProximalConfig = ProximalConfig {
        lr: 3e-4,
        iters: 80,
        target_kl: Some(0.02),
        minibatch_size: None,
    };

    /// Checks every field's range; errors name the field as `<name>.<field>`.
    pub fn validate(&self, name: &str) -> Result<(), ConfigError> {
        let finite_pos = |x: f64| x.is_finite() && x > 0.0;
        check(
            // an Adam step moves a parameter by at most lr: 1e8 steps of 1e30 stay finite in f32
            finite_pos(self.lr) && self.lr <= 1e30,
            &format!("{name}.lr"),
            self.lr,
            "must be in (0, 1e30]",
        )?;
        check(
            (1..=10_000).contains(&self.iters),
            &format!("{name}.iters"),
            self.iters,
            "must be in 1..=10000",
        )?;
        if let Some(t) = self.target_kl {
            check(
                finite_pos(t) && t <= 1000.0,
                &format!("{name}.target_kl"),
                t,
                "must be in (0, 1000]",
            )?;
        }
        if let Some(m) = self.minibatch_size {
            check(
                (1..=100_000_000).contains(&m),
                &format!("{name}.minibatch_size"),
                m,
                "must be in 1..=100000000",
            )?;
        }
        Ok(())
    }

    /// Documentation of the keys of an update named `name`.
    pub fn key_docs(name: &str) -> Vec<(String, &'static str)> {
        [
            ("lr", "Adam learning rate (paper: 3e-4 policy, 1e-3 value); (0, 1e30]"),
            ("iters", "passes over the batch (paper: 80); 1..=10000"),
            ("target_kl", "stop early once the approximate KL exceeds this (paper: 0.02 for policies; unused by the value update); (0, 1000], optional"),
            ("minibatch_size", "minibatch size; 1..=100000000, optional (unset: full batch)"),
        ]
        .into_iter()
        .map(|(k, d)| (format!("{name}.{k}"), d))
        .collect()
    }
}

/// A proximal policy update: Adam's settings and the early stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProximalStep<'a> {
    /// Adam's passes, and the approximate-KL stop `target_kl`.
    pub update: &'a ProximalConfig,
    /// ESPO's stop: before each step, stop once the mean absolute ratio deviation
    /// `mean(|ratio − 1|)` of the step's (mini)batch exceeds this.
    pub max_ratio_deviation: Option<f64>,
}

impl<'a> ProximalStep<'a> {
    /// `update` with its KL stop only.
    pub fn new(update: &'a ProximalConfig) -> Self {
        Self {
            update,
            max_ratio_deviation: None,
        }
    }
}

/// What a proximal policy update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProximalReport {
    /// Gradient steps taken.
    pub steps: usize,
    /// Whether an early stop (KL or ratio deviation) fired.
    pub stopped_early: bool,
    /// The last approximate KL measured (0 without a KL stop).
    pub approx_kl: f64,
    /// The last mean absolute ratio deviation measured (with ESPO's stop).
    pub ratio_deviation: Option<f64>,
}

/// One pass's minibatches of a batch of `n` rows: `None` for the whole batch in order
/// (`size` absent, 0 or ≥ `n`), else the rows `0..n` shuffled by `rng`, to be cut into chunks
/// of `size`.
pub(crate) fn minibatches(n: usize, size: Option<usize>, rng: &mut impl Rng) -> Option<Vec<usize>> {
    size.filter(|&s| s > 0 && s < n).map(|_| {
        let mut idx: Vec<usize> = (0..n).collect();
        idx.shuffle(rng);
        idx
    })
}

/// Where a proximal update's policy passes run: Burn's graph of the policy module
/// ([`BurnEngine`]), or the host kernels (`crate::host_proximal`).
pub(crate) trait Engine<AB: AutodiffBackend> {
    /// π_θ's distributions on the states of `part`, the rows `rows` of the update's batch
    /// (`None`: the whole batch, in order), as a graph whose loss's gradients
    /// [`Engine::step`] takes.
    fn distribution(&mut self, part: &TensorBatch<AB>, rows: Option<&[usize]>) -> DistParams<AB>;

    /// One Adam step at learning rate `lr` down `grads`, the gradients of a loss of the last
    /// [`Engine::distribution`] (with several ranks, summed over them first).
    fn step(&mut self, grads: AB::Gradients, part: &TensorBatch<AB>, lr: f64);
}

/// The policy module on Burn's autodiff, stepped by Burn's optimizer `O`.
pub(crate) struct BurnEngine<'o, P, O> {
    /// The policy (`None` only during a step).
    pub(crate) policy: Option<P>,
    /// Its optimizer.
    pub(crate) optim: &'o mut O,
}

impl<AB, P, O> Engine<AB> for BurnEngine<'_, P, O>
where
    AB: AutodiffBackend,
    P: Policy<AB> + AutodiffModule<AB>,
    O: Optimizer<P, AB>,
{
    fn distribution(&mut self, part: &TensorBatch<AB>, _: Option<&[usize]>) -> DistParams<AB> {
        match &self.policy {
            Some(policy) => policy.distribution(part.obs.clone()),
            None => unreachable!("the policy is only taken out during a step"),
        }
    }

    fn step(&mut self, grads: AB::Gradients, part: &TensorBatch<AB>, lr: f64) {
        if let Some(policy) = self.policy.take() {
            let grads = part
                .comm
                .sum_gradients(&policy, GradientsParams::from_grads(grads, &policy));
            self.policy = Some(self.optim.step(lr, policy, grads));
        }
    }
}

/// Up to `step.update.iters` passes of Adam ascending `objective` on `batch` (with several
/// ranks, on the union of their batches: gradients summed, stops on global means), stopping early
/// before a step when the approximate KL `mean(logp_old − logp)` exceeds `target_kl` or the
/// ratio deviation `mean(|ratio − 1|)` exceeds `max_ratio_deviation`.
///
/// With V-MPO's objective and `multipliers`, η and α are learned too: each step also moves
/// them by their own Adam (at the same learning rate) down the loss's gradient, with
/// [`Objective::Vmpo`]'s η and α replaced by theirs.
pub fn proximal_update<AB, P, O>(
    policy: P,
    optim: &mut O,
    objective: &Objective,
    batch: &TensorBatch<AB>,
    step: ProximalStep<'_>,
    multipliers: Option<&mut Multipliers>,
    rng: &mut impl Rng,
) -> (P, ProximalReport)
where
    AB: AutodiffBackend,
    P: Policy<AB> + AutodiffModule<AB>,
    O: Optimizer<P, AB>,
{
    let mut engine = BurnEngine {
        policy: Some(policy),
        optim,
    };
    let report = run_proximal(&mut engine, objective, batch, step, multipliers, rng);
    match engine.policy {
        Some(policy) => (policy, report),
        None => unreachable!("the policy is only taken out during a step"),
    }
}

/// [`proximal_update`]'s passes with the policy's passes on `engine`.
pub(crate) fn run_proximal<AB: AutodiffBackend>(
    engine: &mut impl Engine<AB>,
    objective: &Objective,
    batch: &TensorBatch<AB>,
    step: ProximalStep<'_>,
    mut multipliers: Option<&mut Multipliers>,
    rng: &mut impl Rng,
) -> ProximalReport {
    let config = step.update;
    let mut report = ProximalReport {
        steps: 0,
        stopped_early: false,
        approx_kl: 0.0,
        ratio_deviation: None,
    };
    // one (mini)batch's step; `false` once an early stop fires
    let mut one = |part: &TensorBatch<AB>, rows: Option<&[usize]>, report: &mut ProximalReport| {
        let dist = engine.distribution(part, rows);
        if config.target_kl.is_some() || step.max_ratio_deviation.is_some() {
            let log_ratio = dist.log_prob(part.actions.clone()).detach() - part.logp_old.clone();
            if let Some(target) = config.target_kl {
                report.approx_kl = to_host(part.comm.mean(log_ratio.clone().neg()))[0];
                report.stopped_early |= report.approx_kl > target;
            }
            if let Some(max) = step.max_ratio_deviation {
                let deviation = to_host(part.comm.mean(log_ratio.exp().sub_scalar(1.0).abs()))[0];
                report.ratio_deviation = Some(deviation);
                report.stopped_early |= deviation > max;
            }
            if report.stopped_early {
                return false;
            }
        }
        let grads = match (objective, multipliers.as_deref_mut()) {
            (Objective::Vmpo(params), Some(m)) => {
                let (eta, alpha) = m.leaves::<AB>(&part.adv.device());
                let logp = dist.log_prob(part.actions.clone());
                let terms = VmpoTerms::new(&dist, logp, part, params, eta.clone(), alpha.clone());
                let grads = terms.loss().backward();
                let grad = |t: Tensor<AB, 1>| t.grad(&grads).map_or(0.0, |g| to_host(g)[0]);
                let (grad_eta, grad_alpha) = terms
                    .multiplier_grads
                    .unwrap_or_else(|| (grad(eta), grad(alpha)));
                m.step(grad_eta, grad_alpha, config.lr);
                grads
            }
            _ => objective.evaluate(&dist, part).objective.neg().backward(),
        };
        engine.step(grads, part, config.lr);
        report.steps += 1;
        true
    };
    for _ in 0..config.iters {
        match minibatches(batch.len(), config.minibatch_size, rng) {
            None => {
                if !one(batch, None, &mut report) {
                    return report;
                }
            }
            Some(idx) => {
                for rows in idx.chunks(config.minibatch_size.unwrap_or(1)) {
                    if !one(&batch.select(rows), Some(rows), &mut report) {
                        return report;
                    }
                }
            }
        }
    }
    report
}

/// What a value update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValueReport {
    /// Mean squared error to the rewards-to-go before the update.
    pub loss_before: f64,
    /// Mean squared error on the last step's (mini)batch, just before that step.
    pub loss_after: f64,
}

/// `config.iters` passes of Adam descending `mean((V(s) − ret)²)` on `batch`
/// (`target_kl` is ignored).
pub fn value_update<AB, O>(
    mut value: ValueNet<AB>,
    optim: &mut O,
    batch: &TensorBatch<AB>,
    config: &ProximalConfig,
    rng: &mut impl Rng,
) -> (ValueNet<AB>, ValueReport)
where
    AB: AutodiffBackend,
    O: Optimizer<ValueNet<AB>, AB>,
{
    let mse = |v: &ValueNet<AB>, part: &TensorBatch<AB>| {
        part.comm
            .mean((v.forward(part.obs.clone()) - part.ret.clone()).square())
    };
    let loss_before = to_host(mse(&value, batch).detach())[0];
    let mut loss_after = loss_before;
    let mut one = |value: ValueNet<AB>, part: &TensorBatch<AB>| {
        let loss = mse(&value, part);
        loss_after = to_host(loss.clone().detach())[0];
        let grads = part
            .comm
            .sum_gradients(&value, GradientsParams::from_grads(loss.backward(), &value));
        optim.step(config.lr, value, grads)
    };
    for _ in 0..config.iters {
        match minibatches(batch.len(), config.minibatch_size, rng) {
            None => value = one(value, batch),
            Some(idx) => {
                for rows in idx.chunks(config.minibatch_size.unwrap_or(1)) {
                    value = one(value, &batch.select(rows));
                }
            }
        }
    }
    (
        value,
        ValueReport {
            loss_before,
            loss_after,
        },
    )
}
