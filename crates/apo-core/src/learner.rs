//! The learner: a policy, a critic and their optimizers, updated once per epoch by any
//! [`Algorithm`](crate::Algorithm).
//!
//! The learner's networks live on `Autodiff<B>`. Rollouts should not call them per
//! step: take a copy on the backend of your choice with [`Learner::policy_on`] /
//! [`Learner::value_on`] after each update (for example an NdArray copy when `B` is a
//! GPU backend, since batch-1 inference on a GPU is slow).

use burn::backend::Autodiff;
use burn::module::AutodiffModule;
use burn::optim::adaptor::OptimizerAdaptor;
use burn::optim::{Adam, AdamConfig};
use burn::tensor::backend::Backend;
use rand::Rng;

use crate::adam::{ADAM_BETA_1, ADAM_BETA_2, ADAM_EPSILON};
use crate::algorithm::{AlgoConfig, ConfigError, PolicyStep};
use crate::buffer::Batch;
use crate::collective::Comm;
use crate::flat::{flatten, from_host, to_host, unflatten};
use crate::host_head::HostHead;
use crate::host_proximal::host_proximal_update;
use crate::kernels::Kernels;
use crate::objective::{Multipliers, Objective};
use crate::policy::{check_distribution, ActionKind, Policy, PolicyError, PolicyFamily};
use crate::proximal::{proximal_update, value_update, ProximalReport};
use crate::shaping::{shape, Shaped, ShapingError, ShapingReport, ShapingState};
use crate::tensor_batch::TensorBatch;
use crate::trust_region::{trust_region_step, LineSearchOutcome, Rejections};
use crate::value::{ValueConfig, ValueNet};
use crate::value_fit::host_value_update;

type Ad<B> = Autodiff<B>;

/// The Adam state of the policy of family `F` on `Autodiff<B>`.
pub type PolicyAdam<B, F> =
    OptimizerAdaptor<Adam, <F as PolicyFamily>::Policy<Autodiff<B>>, Autodiff<B>>;

/// The Adam state of the value network on `Autodiff<B>`.
pub type ValueAdam<B> = OptimizerAdaptor<Adam, ValueNet<Autodiff<B>>, Autodiff<B>>;

/// What one update did, for the epoch's log.
#[derive(Debug, Clone, PartialEq)]
pub struct UpdateReport {
    /// `−objective` at θ_j (the policy loss before the update).
    pub loss_pi: f64,
    /// `mean_surr` at θ_j.
    pub mean_surr: f64,
    /// The MeanVariance term at θ_j (APO/PAPO).
    pub mean_variance: Option<f64>,
    /// The VarianceMean term at θ_j (APO/PAPO).
    pub variance_mean: Option<f64>,
    /// Mean KL(π_j ‖ π_{j+1}) over the batch.
    pub kl: f64,
    /// Mean entropy of π_j over the batch.
    pub entropy: f64,
    /// Value MSE before the value update.
    pub loss_v: f64,
    /// Trust-region line-search outcome (APO, TRPO).
    pub line_search: Option<LineSearchOutcome>,
    /// The line search's rejected tries by reason (APO, TRPO).
    pub rejections: Option<Rejections>,
    /// `min_J_sq`'s bias at θ_{j+1} (APO/PAPO with `k > 0`).
    pub bias: Option<f64>,
    /// Whether `min_J_sq`'s switch is on at θ_{j+1} (APO/PAPO with `k > 0`).
    pub min_j_sq_on: Option<bool>,
    /// Proximal step report (PAPO, PPO, A2C, ESPO, AlphaPPO, V-MPO).
    pub proximal: Option<ProximalReport>,
    /// V-MPO's temperature η and multiplier α after the update.
    pub multipliers: Option<Multipliers>,
    /// What the risk shaping did to the batch ([`Learner::shape`]; MVPI, CVaR, return
    /// capping), filled in by the caller that shaped it.
    pub shaping: Option<ShapingReport>,
    /// Wall time of the policy update (with the evaluation of the terms at θ_j), seconds.
    pub policy_update_s: f64,
    /// Wall time of the value update, seconds.
    pub value_update_s: f64,
}

/// Why [`Learner::update`] updated nothing.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UpdateError {
    /// The policy's distributions do not fit the batch's actions.
    #[error(transparent)]
    Policy(#[from] PolicyError),
    /// The batch does not record what the algorithm's risk shaping needs.
    #[error(transparent)]
    Shaping(#[from] ShapingError),
}

/// A policy of family `F` and a value network, with their Adam states, on `Autodiff<B>`.
pub struct Learner<B: Backend, F: PolicyFamily>
where
    F::Policy<Ad<B>>: AutodiffModule<Ad<B>>,
{
    family: F,
    action: ActionKind,
    config: AlgoConfig,
    device: B::Device,
    policy: F::Policy<Ad<B>>,
    value: ValueNet<Ad<B>>,
    policy_optim: PolicyAdam<B, F>,
    value_optim: ValueAdam<B>,
    /// V-MPO's learned η and α (`None` for the other algorithms).
    multipliers: Option<Multipliers>,
    /// What the risk shaping carries from epoch to epoch (return capping's cap).
    shaping: ShapingState,
    kernels: Kernels,
    comm: Comm,
}

static INIT_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn adam() -> AdamConfig {
    // PyTorch's defaults, as in the paper's implementation (shared with the host value fit).
    AdamConfig::new()
        .with_beta_1(ADAM_BETA_1)
        .with_beta_2(ADAM_BETA_2)
        .with_epsilon(ADAM_EPSILON)
}

impl<B: Backend, F: PolicyFamily> Learner<B, F>
where
    F::Policy<Ad<B>>: AutodiffModule<Ad<B>>,
{
    /// A learner with freshly initialized networks. `action` must match what `family`'s
    /// policies output; `seed` seeds Burn's initializers on `device`.
    pub fn new(
        family: F,
        action: ActionKind,
        value: &ValueConfig,
        config: AlgoConfig,
        device: &B::Device,
        seed: u64,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let (policy, value) = {
            // Burn's backends draw initial weights from one process-wide RNG: seed it and run
            // every lazy initializer (by reading the parameters) while holding a lock, so that
            // learners built concurrently with the same seed get the same weights.
            let _guard = INIT_LOCK
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            B::seed(device, seed);
            let policy = family.init::<Ad<B>>(device);
            let value = value.init::<Ad<B>>(device);
            let _ = (flatten(&policy), flatten(&value));
            (policy, value)
        };
        let multipliers = match config.objective() {
            Objective::Vmpo(p) => Some(Multipliers::new(p.eta, p.alpha)),
            _ => None,
        };
        Ok(Self {
            multipliers,
            shaping: ShapingState::default(),
            policy,
            value,
            family,
            action,
            config,
            device: device.clone(),
            policy_optim: adam().init(),
            value_optim: adam().init(),
            kernels: Kernels::default(),
            comm: Comm::default(),
        })
    }

    /// Makes every update one update over the union of the batches of `comm`'s ranks
    /// ([`crate::collective`]): each rank passes its own part to [`Learner::update`] and every
    /// rank ends with the same networks. The default is one rank.
    pub fn set_comm(&mut self, comm: Comm) {
        self.comm = comm;
    }

    /// The ranks an update spans.
    pub fn comm(&self) -> &Comm {
        &self.comm
    }

    /// Where the Fisher-vector products, the proximal policy steps and the value fit run from
    /// now on (default
    /// [`Kernels::Backend`]). The networks and optimizer states do not depend on it.
    pub fn set_kernels(&mut self, kernels: Kernels) {
        self.kernels = kernels;
    }

    /// Where the Fisher-vector products, the proximal policy steps and the value fit run.
    pub fn kernels(&self) -> Kernels {
        self.kernels
    }

    /// The hyperparameters.
    pub fn config(&self) -> &AlgoConfig {
        &self.config
    }

    /// The policy's action kind.
    pub fn action(&self) -> ActionKind {
        self.action
    }

    /// The policy family.
    pub fn family(&self) -> &F {
        &self.family
    }

    /// The current policy parameters θ as host values, `[num_params]`.
    pub fn policy_params(&self) -> Vec<f64> {
        to_host(flatten(&self.policy))
    }

    /// The current value-network parameters as host values.
    pub fn value_params(&self) -> Vec<f64> {
        to_host(flatten(&self.value))
    }

    /// A copy of the current policy on backend `B2` (e.g. NdArray for rollouts).
    pub fn policy_on<B2: Backend>(&self, device: &B2::Device) -> F::Policy<B2> {
        unflatten(
            self.family.init::<B2>(device),
            from_host::<B2>(&self.policy_params(), device),
        )
    }

    /// A copy of the current value network on backend `B2`, built from `value`'s sizes.
    pub fn value_on<B2: Backend>(&self, value: &ValueConfig, device: &B2::Device) -> ValueNet<B2> {
        unflatten(
            value.init::<B2>(device),
            from_host::<B2>(&self.value_params(), device),
        )
    }

    /// The policy and value networks (for checkpoints).
    pub fn networks(&self) -> (&F::Policy<Ad<B>>, &ValueNet<Ad<B>>) {
        (&self.policy, &self.value)
    }

    /// The optimizers (for checkpoints).
    pub fn optimizers(&self) -> (&PolicyAdam<B, F>, &ValueAdam<B>) {
        (&self.policy_optim, &self.value_optim)
    }

    /// V-MPO's learned temperature and multiplier with their Adam state (for checkpoints);
    /// `None` for the other algorithms.
    pub fn multipliers(&self) -> Option<&Multipliers> {
        self.multipliers.as_ref()
    }

    /// Replaces V-MPO's multipliers (when resuming from a checkpoint); no effect for the other
    /// algorithms, which have none.
    pub fn restore_multipliers(&mut self, multipliers: Multipliers) {
        if let Some(m) = &mut self.multipliers {
            *m = multipliers;
        }
    }

    /// What the risk shaping carries from epoch to epoch (for checkpoints).
    pub fn shaping_state(&self) -> &ShapingState {
        &self.shaping
    }

    /// Replaces what the risk shaping carries (when resuming from a checkpoint).
    pub fn restore_shaping_state(&mut self, state: ShapingState) {
        self.shaping = state;
    }

    /// The epoch's `batch` (this rank's part, collected by the current policy) shaped by the
    /// algorithm's risk shaping ([`crate::shaping`]: MVPI's augmented rewards, CVaR's worst
    /// episodes, return capping's capped rewards), updating what the shaping carries to the
    /// next epoch; `None` for the algorithms that use the batch as it is. Call it once per
    /// epoch, before [`Learner::update_policy`] (on [`Shaped::policy`]) and
    /// [`Learner::update_value`] (on [`Shaped::value`], or the policy's batch when that is
    /// `None`).
    ///
    /// # Errors
    /// [`ShapingError`] when the algorithm shapes batches and `batch` does not record a reward
    /// per row and paths that cover its rows (a [`crate::RolloutBuffer`]'s batch does).
    pub fn shape(&mut self, batch: &Batch) -> Result<Option<Shaped>, ShapingError> {
        let Some(rule) = self.config.settings().shaping() else {
            return Ok(None);
        };
        let common = self.config.common();
        shape(
            batch,
            rule,
            &mut self.shaping,
            common.gamma,
            common.lambda,
            &self.comm,
        )
        .map(Some)
    }

    /// The objective the next update maximizes: the configured one, with V-MPO's learned
    /// η and α.
    pub fn objective(&self) -> Objective {
        match (self.config.objective(), &self.multipliers) {
            (Objective::Vmpo(p), Some(m)) => Objective::Vmpo(m.apply(p)),
            (objective, _) => objective,
        }
    }

    /// Replaces the networks and optimizer states (when resuming from a checkpoint).
    pub fn restore(
        &mut self,
        policy: F::Policy<Ad<B>>,
        value: ValueNet<Ad<B>>,
        policy_optim: PolicyAdam<B, F>,
        value_optim: ValueAdam<B>,
    ) {
        self.policy = policy;
        self.value = value;
        self.policy_optim = policy_optim;
        self.value_optim = value_optim;
    }

    /// One epoch's update of the policy (by the configured algorithm) and of the value
    /// network, on `batch` collected by the current policy (with several ranks, this rank's
    /// part of the epoch's batch); `rng` shuffles minibatches. The same as
    /// [`Learner::shape`], then [`Learner::update_policy`] and [`Learner::update_value`] on
    /// the batches it gives.
    ///
    /// # Errors
    /// [`UpdateError::Policy`] when the policy's distributions on the batch's states do not fit
    /// its actions (family, action width or batch size), [`UpdateError::Shaping`] when the
    /// algorithm shapes batches and this one does not record its rewards and paths; nothing is
    /// updated then.
    pub fn update(
        &mut self,
        batch: &Batch,
        rng: &mut impl Rng,
    ) -> Result<UpdateReport, UpdateError> {
        let before = self.shaping;
        let shaped = self.shape(batch)?;
        let (policy_batch, value_batch) = match &shaped {
            Some(s) => (&s.policy, s.value.as_ref().unwrap_or(&s.policy)),
            None => (batch, batch),
        };
        let mut report = self.update_policy(policy_batch, rng).inspect_err(|_| {
            self.shaping = before;
        })?;
        report.shaping = shaped.as_ref().map(|s| s.report);
        self.update_value(value_batch, rng, &mut report);
        Ok(report)
    }

    /// The policy's half of [`Learner::update`]: the report's value fields (`loss_v`,
    /// `value_update_s`) are 0 until [`Learner::update_value`] fills them in. The policy step
    /// does not read the critic (the batch holds the advantages), so the value update may run
    /// later, while the next rollout runs with the new policy.
    ///
    /// # Errors
    /// As [`Learner::update`]; nothing is updated then.
    pub fn update_policy(
        &mut self,
        batch: &Batch,
        rng: &mut impl Rng,
    ) -> Result<UpdateReport, PolicyError> {
        let start = std::time::Instant::now();
        let objective = self.objective();
        let tb =
            TensorBatch::<B>::new(batch, self.action, &self.device).with_comm(self.comm.clone());
        let theta = self.policy_params();
        let before = unflatten(
            self.family.init::<B>(&self.device),
            from_host::<B>(&theta, &self.device),
        );
        // the diagnostics' forward passes over the batch, on the host kernels when chosen
        let mut host = match self.kernels {
            Kernels::Host => HostHead::of(&before),
            Kernels::Backend => None,
        };
        let dist = match &mut host {
            Some(head) => head.distribution::<B>(&batch.obs, &self.device).0,
            None => before.distribution(tb.obs.clone()),
        };
        check_distribution::<B, F::Policy<B>>(&dist, batch.len, self.action)?;
        let entropy = to_host(self.comm.mean(dist.entropy()))[0];
        let terms = objective.evaluate(&dist, &tb);
        let scalar = |t: Option<burn::tensor::Tensor<B, 1>>| t.map(|t| to_host(t)[0]);

        let tb1 = tb.lift::<Ad<B>>();
        let (line_search, rejections, proximal) = match self.config.settings().policy_step() {
            PolicyStep::TrustRegion(trust_region) => {
                let report = trust_region_step(
                    &self.family,
                    &objective,
                    &theta,
                    &tb,
                    trust_region,
                    self.kernels,
                );
                let leaf = from_host::<Ad<B>>(&report.theta, &self.device);
                self.policy = unflatten(self.policy.clone(), leaf);
                (Some(report.outcome), Some(report.rejections), None)
            }
            PolicyStep::Proximal(step) => {
                let host = match self.kernels {
                    Kernels::Host => host_proximal_update(
                        &self.policy,
                        &self.policy_optim,
                        &objective,
                        &batch.obs,
                        &tb1,
                        step,
                        self.multipliers.as_mut(),
                        rng,
                    ),
                    Kernels::Backend => None,
                };
                let report = match host {
                    Some((policy, optim, report)) => {
                        self.policy = policy;
                        self.policy_optim = optim;
                        report
                    }
                    None => {
                        let (policy, report) = proximal_update(
                            self.policy.clone(),
                            &mut self.policy_optim,
                            &objective,
                            &tb1,
                            step,
                            self.multipliers.as_mut(),
                            rng,
                        );
                        self.policy = policy;
                        report
                    }
                };
                (None, None, Some(report))
            }
        };
        let policy_update_s = start.elapsed().as_secs_f64();
        let after = match &mut host {
            Some(head) => {
                head.set_params(&self.policy_params());
                head.distribution::<B>(&batch.obs, &self.device).0
            }
            None => self
                .policy_on::<B>(&self.device)
                .distribution(tb.obs.clone()),
        };
        let kl = to_host(self.comm.mean(after.kl_from(&tb.dist_old)))[0];
        // the switch's diagnostics exist for APO and PAPO only
        let terms_after = matches!(objective, Objective::Apo(_) | Objective::Papo { .. })
            .then(|| objective.evaluate(&after, &tb));
        Ok(UpdateReport {
            loss_pi: -to_host(terms.objective)[0],
            mean_surr: to_host(terms.mean_surr)[0],
            mean_variance: scalar(terms.mean_variance),
            variance_mean: scalar(terms.variance_mean),
            kl,
            entropy,
            loss_v: 0.0,
            line_search,
            rejections,
            bias: terms_after.as_ref().and_then(|t| scalar(t.bias.clone())),
            min_j_sq_on: terms_after
                .and_then(|t| scalar(t.min_j_sq_on))
                .map(|on| on > 0.5),
            proximal,
            multipliers: self.multipliers,
            shaping: None,
            policy_update_s,
            value_update_s: 0.0,
        })
    }

    /// The value network's half of [`Learner::update`], on the same `batch` and continuing
    /// the same `rng` as [`Learner::update_policy`]: fills in `report`'s `loss_v` (the mean
    /// squared error before the update) and `value_update_s`.
    pub fn update_value(&mut self, batch: &Batch, rng: &mut impl Rng, report: &mut UpdateReport) {
        let start = std::time::Instant::now();
        let value_config = self.config.common().value_update;
        let host = match self.kernels {
            Kernels::Host => host_value_update::<B>(
                &self.value,
                &self.value_optim,
                batch,
                &value_config,
                &self.comm,
                rng,
            ),
            Kernels::Backend => None,
        };
        let value_report = match host {
            Some((value, optim, report)) => {
                self.value = value;
                self.value_optim = optim;
                report
            }
            None => {
                let tb = TensorBatch::<B>::new(batch, self.action, &self.device)
                    .with_comm(self.comm.clone())
                    .lift::<Ad<B>>();
                let (value, report) = value_update(
                    self.value.clone(),
                    &mut self.value_optim,
                    &tb,
                    &value_config,
                    rng,
                );
                self.value = value;
                report
            }
        };
        report.loss_v = value_report.loss_before;
        report.value_update_s = start.elapsed().as_secs_f64();
    }
}
