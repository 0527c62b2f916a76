//! Benchmarks behind `apo bench`: the policy update (APO vs TRPO, Hessian- and Fisher-vector
//! products), an epoch's time split, the rollout policy call, and environment steps.

use std::time::Instant;

use apo_core::algorithm::{ApoConfig, TrpoConfig};
use apo_core::flat::{flatten, to_host};
use apo_core::hvp::hessian_vector_product;
use apo_core::inference::{ActBuffers, HostPolicy};
use apo_core::objective::{PenaltyUnits, Switch};
use apo_core::trust_region::{trust_region_step, TrustRegionConfig};
use apo_core::{
    ActionKind, AlgoConfig, AlgorithmConfig, Batch, BufferLayout, FisherOperator, Kernels, Learner,
    MlpPolicy, MlpPolicyConfig, Policy, PolicyFamily, PolicyStep, RolloutBuffer, TensorBatch,
    ValueConfig,
};
use burn::backend::Autodiff;
use burn::tensor::backend::Backend;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

/// Timings of the update benchmark, seconds (medians over the repeats).
#[derive(Debug, Clone, PartialEq)]
pub struct UpdateTimings {
    /// Policy parameters.
    pub params: usize,
    /// One TRPO trust-region step.
    pub trpo_s: f64,
    /// One APO trust-region step.
    pub apo_s: f64,
    /// One APO trust-region step with `--preset robust`'s variant (the penalty in the
    /// advantages' units, the switch off, ω1 0.01, ω2 0.005).
    pub apo_robust_s: f64,
    /// One Hessian-vector product of the mean KL by double backward (the reference path).
    pub hvp_s: f64,
    /// One Fisher-vector product `Jᵀ M J v / N` (what the trust-region step uses for MLP
    /// policies) on Burn's graph and on the host kernels.
    pub fvp_s: [f64; 2],
    /// One Fisher-vector product of the same policy without its JVP (`J v` by a finite
    /// difference: what a `burn::nn` policy gets), on Burn's graph.
    pub fvp_fd_s: f64,
    /// Line-search tries of the last TRPO, APO and robust-APO steps.
    pub tries: [String; 3],
    /// One Adam step of the value fit (the paper's 80 per epoch, full batch) on Burn's graph
    /// and on the host kernels.
    pub value_step_s: (f64, f64),
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A synthetic epoch: `n` Gaussian observations of `obs_dim`, actions sampled from a fresh
/// (64, 64) policy, random rewards and values, paths of 1000 steps.
pub fn synthetic_batch(
    policy: &mut HostPolicy,
    n: usize,
    obs_dim: usize,
    act_dim: usize,
    rng: &mut StdRng,
) -> Batch {
    let layout = BufferLayout {
        observation_dim: obs_dim,
        action_width: act_dim,
        dist_width: 2 * act_dim,
    };
    let mut buffer = RolloutBuffer::new(layout, 0.99, 0.97, n);
    let mut act = ActBuffers::default();
    let mut obs = vec![0.0f32; obs_dim];
    for t in 0..n {
        obs.iter_mut().for_each(|o| *o = rng.sample(StandardNormal));
        policy.act(&obs, 1, false, rng, &mut act);
        let (value, reward) = (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        buffer.store(&obs, &act.actions, act.logp[0], &act.dist, value, reward);
        if (t + 1) % 1000 == 0 || t + 1 == n {
            buffer.finish_path(0.0);
        }
    }
    buffer.take()
}

/// Times APO and TRPO trust-region steps (Fisher-vector products on `kernels`), and on
/// backend `B` and the host kernels: KL Hessian- and Fisher-vector products and value-fit steps.
pub fn update<B: Backend>(
    device: &B::Device,
    n: usize,
    obs_dim: usize,
    act_dim: usize,
    repeats: usize,
    kernels: Kernels,
) -> UpdateTimings {
    let action = ActionKind::Continuous { dim: act_dim };
    let family = MlpPolicyConfig::new(obs_dim, action);
    B::seed(device, 0);
    let policy_b = family.init::<B>(device);
    let theta = to_host(flatten(&policy_b));
    let mut rng = StdRng::seed_from_u64(0);
    let mut host = HostPolicy::new(&policy_b, action);
    let batch = synthetic_batch(&mut host, n, obs_dim, act_dim, &mut rng);
    let tb = TensorBatch::<B>::new(&batch, action, device);
    let robust = ApoConfig {
        penalty_units: PenaltyUnits::Advantage,
        switch: Switch::Off,
        omega1: apo_train::run_config::ROBUST_OMEGA.0,
        omega2: apo_train::run_config::ROBUST_OMEGA.1,
        ..ApoConfig::paper_defaults()
    };
    let configs = [
        AlgoConfig::Trpo(TrpoConfig::paper_defaults()),
        AlgoConfig::Apo(ApoConfig::paper_defaults()),
        AlgoConfig::Apo(robust),
    ]
    .map(|c| {
        let region = match c.settings().policy_step() {
            PolicyStep::TrustRegion(region) => *region,
            PolicyStep::Proximal(_) => TrustRegionConfig::default(),
        };
        (c.objective(), region)
    });
    let mut times: [Vec<f64>; 3] = Default::default();
    let mut tries: [String; 3] = Default::default();
    // one warm-up of each, then in turn so that all see the same machine state
    for round in 0..=repeats {
        for ((config, times), tried) in configs.iter().zip(&mut times).zip(&mut tries) {
            let start = Instant::now();
            let report = trust_region_step(&family, &config.0, &theta, &tb, &config.1, kernels);
            if round > 0 {
                times.push(start.elapsed().as_secs_f64());
            }
            *tried = format!("{:?}", report.outcome);
        }
    }
    let [trpo_s, apo_s, apo_robust_s] = times.map(median);
    let tb2 = tb.lift::<Autodiff<B>>().lift::<Autodiff<Autodiff<B>>>();
    let template = family.init::<Autodiff<Autodiff<B>>>(device);
    let v: Vec<f64> = (0..theta.len())
        .map(|_| rng.sample(StandardNormal))
        .collect();
    let hvp_s = (0..=repeats)
        .map(|_| {
            let start = Instant::now();
            let hv = hessian_vector_product::<B, _>(&template, &theta, &v, device, |p| {
                p.distribution(tb2.obs.clone())
                    .kl_from(&tb2.dist_old)
                    .mean()
            });
            std::hint::black_box(hv.ok());
            start.elapsed().as_secs_f64()
        })
        .skip(1)
        .collect();
    let fvp_s = [Kernels::Backend, Kernels::Host].map(|kernels| {
        let fisher = FisherOperator::new(&family, &theta, tb.obs.clone(), &tb.dist_old)
            .with_kernels(kernels);
        let times = (0..=repeats)
            .map(|_| {
                let start = Instant::now();
                std::hint::black_box(fisher.apply(&v));
                start.elapsed().as_secs_f64()
            })
            .skip(1)
            .collect();
        median(times)
    });
    let fisher_fd = FisherOperator::new(
        &WithoutJvp(family.clone()),
        &theta,
        tb.obs.clone(),
        &tb.dist_old,
    );
    let fvp_fd_s = median(
        (0..=repeats)
            .map(|_| {
                let start = Instant::now();
                std::hint::black_box(fisher_fd.apply(&v));
                start.elapsed().as_secs_f64()
            })
            .skip(1)
            .collect(),
    );
    let value_step_s = (
        value_step::<B>(device, &batch, obs_dim, action, Kernels::Backend, repeats),
        value_step::<B>(device, &batch, obs_dim, action, Kernels::Host, repeats),
    );
    UpdateTimings {
        value_step_s,
        params: theta.len(),
        trpo_s,
        apo_s,
        apo_robust_s,
        hvp_s: median(hvp_s),
        fvp_s,
        fvp_fd_s,
        tries,
    }
}

/// The built-in MLP policy without its forward-mode JVP, as a `burn::nn` policy is.
#[derive(burn::module::Module, Debug)]
struct NoJvp<B: Backend> {
    inner: MlpPolicy<B>,
}

impl<B: Backend> Policy<B> for NoJvp<B> {
    fn distribution(&self, obs: burn::tensor::Tensor<B, 2>) -> apo_core::DistParams<B> {
        self.inner.distribution(obs)
    }
}

/// The family of [`NoJvp`].
#[derive(Debug, Clone)]
struct WithoutJvp(MlpPolicyConfig);

impl PolicyFamily for WithoutJvp {
    type Policy<B: Backend> = NoJvp<B>;

    fn init<B: Backend>(&self, device: &B::Device) -> NoJvp<B> {
        NoJvp {
            inner: self.0.init(device),
        }
    }
}

/// Seconds per Adam step of the value fit on `batch` with `kernels`: the median over `repeats`
/// (after one warm-up) of a whole value update's time over its steps.
fn value_step<B: Backend>(
    device: &B::Device,
    batch: &Batch,
    obs_dim: usize,
    action: ActionKind,
    kernels: Kernels,
    repeats: usize,
) -> f64 {
    let mut config = TrpoConfig::paper_defaults();
    // the policy step is not timed here: make it as short as it gets
    config.trust_region.cg_iters = 1;
    config.trust_region.backtrack_iters = 1;
    let steps = config.value_update.iters.max(1) as f64;
    let value = ValueConfig {
        observation_dim: obs_dim,
        hidden: vec![64, 64],
    };
    let family = MlpPolicyConfig::new(obs_dim, action);
    let config = AlgoConfig::Trpo(config);
    let Ok(mut learner) = Learner::<B, _>::new(family, action, &value, config, device, 0) else {
        return f64::NAN;
    };
    learner.set_kernels(kernels);
    let mut rng = StdRng::seed_from_u64(1);
    let times = (0..=repeats)
        .map(|_| {
            learner
                .update(batch, &mut rng)
                .map_or(f64::NAN, |report| report.value_update_s / steps)
        })
        .skip(1)
        .collect();
    median(times)
}

/// The memory [`policy_call_us`] allocates, in bytes (an upper estimate: the observations,
/// the network with its Burn and host copies, the activations and the action buffers, f32,
/// with a factor 2 for the allocator and copies).
pub fn policy_call_bytes(obs_dim: usize, act_dim: usize, batch: usize) -> f64 {
    let (obs, act, batch) = (obs_dim as f64, act_dim as f64, batch as f64);
    let hidden = 64.0;
    let params = obs * hidden + hidden * hidden + hidden * 2.0 * act + 2.0 * hidden + 2.0 * act;
    let per_sample = obs + 2.0 * hidden + 4.0 * act;
    2.0 * 4.0 * (3.0 * params + batch * per_sample)
}

/// Microseconds per host policy call for a batch of `batch` observations.
pub fn policy_call_us(obs_dim: usize, action: ActionKind, batch: usize, calls: usize) -> f64 {
    let family = MlpPolicyConfig::new(obs_dim, action);
    let device = Default::default();
    let mut policy = HostPolicy::new(&family.init::<burn::backend::NdArray>(&device), action);
    let mut rng = StdRng::seed_from_u64(0);
    let obs: Vec<f32> = (0..obs_dim * batch)
        .map(|_| rng.sample(StandardNormal))
        .collect();
    let mut act = ActBuffers::default();
    policy.act(&obs, batch, false, &mut rng, &mut act);
    let start = Instant::now();
    for _ in 0..calls {
        policy.act(std::hint::black_box(&obs), batch, false, &mut rng, &mut act);
    }
    start.elapsed().as_secs_f64() * 1e6 / calls as f64
}

/// Where an epoch's time went, seconds (from the epoch's `progress.csv` row). Each rollout is
/// charged to the epoch whose data it collects, also when, pipelined, it ran during the
/// previous epoch's value fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpochSplit {
    /// Epoch number, from 1.
    pub epoch: usize,
    /// The epoch's share of the run's wall time (from the end of the previous one; epoch 1
    /// includes the set-up; pipelined, it includes the next epoch's rollout and not its own,
    /// except epoch 1's).
    pub total_s: f64,
    /// The rollout.
    pub rollout_s: f64,
    /// The rollout's time inside the simulator's calls.
    pub sim_s: f64,
    /// The policy update.
    pub policy_s: f64,
    /// The value update.
    pub value_s: f64,
    /// The time the parts overlapped, `max(0, rollout + policy + value − total)`: with the
    /// pipelined epoch, the value fit hidden behind the next epoch's rollout.
    pub hidden_s: f64,
    /// Everything else: host-copy synchronization, progress and checkpoint writes
    /// (`max(0, total − rollout − policy − value)`).
    pub other_s: f64,
}

/// What [`epoch`] measured: each epoch's split and the whole run's throughput.
#[derive(Debug, Clone, PartialEq)]
pub struct EpochBench {
    /// Each epoch's split, in order.
    pub epochs: Vec<EpochSplit>,
    /// Environment steps of the whole run.
    pub steps: u64,
    /// Wall time of the whole run, from creating it to the end of its last epoch, seconds.
    pub wall_s: f64,
    /// Whether the value fit ran beside the next rollout.
    pub pipeline: bool,
}

impl EpochBench {
    /// End to end: the run's steps over its wall time, what a user waits for.
    pub fn steps_per_s(&self) -> f64 {
        self.steps as f64 / self.wall_s.max(1e-9)
    }

    /// The simulator's own speed inside the run: the steps over the rollouts' time inside the
    /// simulator's calls. [`EpochBench::steps_per_s`] never exceeds it (the rollouts run one
    /// after another, so the run's wall time holds every one of those calls).
    pub fn sim_steps_per_s(&self) -> f64 {
        self.steps as f64 / self.sim_s().max(1e-9)
    }

    /// The rollouts' time inside the simulator's calls, seconds.
    pub fn sim_s(&self) -> f64 {
        self.epochs.iter().map(|e| e.sim_s).sum()
    }

    /// The simulator's share of the run's wall time, in `[0, 1]`.
    pub fn sim_share(&self) -> f64 {
        self.sim_s() / self.wall_s.max(1e-9)
    }

    /// The epochs in the steady state: without epoch 1 (the set-up, and pipelined, two
    /// rollouts) and, pipelined, without the last (no rollout ahead). All of them when that
    /// leaves none.
    pub fn steady(&self) -> &[EpochSplit] {
        let n = self.epochs.len();
        let end = if self.pipeline {
            n.saturating_sub(1)
        } else {
            n
        };
        match self.epochs.get(1..end) {
            Some(steady) if !steady.is_empty() => steady,
            _ => &self.epochs,
        }
    }
}

/// [`update`] on the backend [`apo_train::BackendKind::dispatch`] picks, on its default device.
#[derive(Debug, Clone, Copy)]
pub struct UpdateBench {
    /// Batch size.
    pub batch: usize,
    /// Observation dimension.
    pub obs: usize,
    /// Action dimension.
    pub act: usize,
    /// Timed repeats.
    pub repeats: usize,
    /// Where the Fisher-vector products and value fit run.
    pub kernels: Kernels,
}

impl UpdateBench {
    /// [`update`] on `backend`, on its default device.
    ///
    /// Not generic, so that the updates of every backend are compiled once, here, and not
    /// again in each program that picks the backend at run time.
    ///
    /// # Errors
    /// A backend this build lacks ([`apo_train::BackendKind::dispatch`]).
    #[inline(never)]
    pub fn on(self, backend: apo_train::BackendKind) -> anyhow::Result<UpdateTimings> {
        backend.dispatch(self)
    }
}

impl apo_train::OnBackend for UpdateBench {
    type Output = UpdateTimings;

    fn run<B: Backend>(self) -> UpdateTimings {
        update::<B>(
            &Default::default(),
            self.batch,
            self.obs,
            self.act,
            self.repeats,
            self.kernels,
        )
    }
}

/// Trains `config` for its epochs in a fresh temporary run directory (removed afterwards,
/// also when `stop` is raised: then the epochs done so far are returned), the environments
/// stepped on `threads` threads, and returns each epoch's time split and the whole run's
/// steps and wall time.
pub fn epoch(
    config: &apo_train::RunConfig,
    threads: usize,
    stop: &std::sync::atomic::AtomicBool,
) -> anyhow::Result<EpochBench> {
    // the run's wall time, seconds
    let train = |dir: &std::path::Path| -> anyhow::Result<f64> {
        let start = Instant::now();
        let launch = apo_train::run::Launch::new(threads);
        let mut run = apo_train::AnyRun::create(dir, config.clone(), &launch, false)?;
        while run.epoch(stop, &mut |_| {})?.is_some() {}
        Ok(start.elapsed().as_secs_f64())
    };
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let dir = std::env::temp_dir().join(format!("apo-bench-epoch-{}-{nanos}", std::process::id()));
    // the run takes the prepared directory (its lock released for it) and trains in it
    let mut prepared = apo_train::run_dir::NewRunDir::prepare(&dir, false)?;
    drop(prepared.take_lock());
    let trained = train(&dir);
    let progress = dir.join(apo_train::run_dir::PROGRESS);
    let trained = trained.and_then(|wall_s| {
        let rows = match progress.exists() {
            true => apo_train::progress_csv::read(&progress)?,
            // stopped before the first epoch
            false => Vec::new(),
        };
        Ok((wall_s, rows))
    });
    prepared.discard();
    let (wall_s, rows) = trained?;
    let mut previous = 0.0;
    let epochs = rows
        .iter()
        .map(|r| {
            let total_s = r.time_s - previous;
            previous = r.time_s;
            EpochSplit {
                epoch: r.epoch,
                total_s,
                rollout_s: r.rollout_s,
                sim_s: r.sim_s,
                policy_s: r.update_pi_s,
                value_s: r.update_v_s,
                hidden_s: (r.rollout_s + r.update_pi_s + r.update_v_s - total_s).max(0.0),
                other_s: (total_s - r.rollout_s - r.update_pi_s - r.update_v_s).max(0.0),
            }
        })
        .collect();
    Ok(EpochBench {
        epochs,
        steps: rows.last().map_or(0, |r| r.env_steps),
        wall_s,
        pipeline: config.train.pipeline,
    })
}

/// The median of `values` (`NaN` for none).
pub fn median_of(values: impl IntoIterator<Item = f64>) -> f64 {
    let v: Vec<f64> = values.into_iter().collect();
    if v.is_empty() {
        return f64::NAN;
    }
    median(v)
}
