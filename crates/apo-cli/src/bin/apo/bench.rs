//! `apo bench`: timings of updates, epochs, environments and policy calls.

use apo_core::Algorithm;
use apo_envs::mujoco::Physics;
use apo_train::backend::{BackendKind, KernelsKind};
use apo_train::run_config::RunConfig;
use clap::Subcommand;

#[derive(Subcommand)]
pub enum BenchCommand {
    /// Time one TRPO, one APO and one robust-APO (`--preset robust`'s variant) trust-region
    /// update, a KL Hessian-vector product (double backward), a Fisher-vector product and a
    /// value-fit Adam step (the last two on Burn's graph and on the host kernels), and the
    /// Fisher-vector product of a policy without a JVP (by finite differences).
    #[command(after_help = "Example:\n  apo bench update --batch 4000 --obs 11 --act 3")]
    Update {
        /// Backend.
        #[arg(long, value_enum, default_value_t = BackendKind::Cpu)]
        backend: BackendKind,
        /// Where the trust-region updates' Fisher-vector products run.
        #[arg(long, value_enum, default_value_t = KernelsKind::Auto)]
        kernels: KernelsKind,
        /// Samples in the batch; 1..=10000000.
        #[arg(long, default_value_t = 30_000, value_parser = apo_cli::flags::count::<u64>(1, 10_000_000))]
        batch: u64,
        /// Observation dimension; 1..=100000.
        #[arg(long, default_value_t = 60, value_parser = apo_cli::flags::count::<u64>(1, 100_000))]
        obs: u64,
        /// Action dimension; 1..=10000.
        #[arg(long, default_value_t = 8, value_parser = apo_cli::flags::count::<u64>(1, 10_000))]
        act: u64,
        /// Timed repeats (after one warm-up); the median is printed; 1..=1000.
        #[arg(long, default_value_t = 3, value_parser = apo_cli::flags::count::<u64>(1, 1000))]
        repeats: u64,
    },
    /// Train a few epochs and print where each epoch's time goes (rollout and the simulator's
    /// share of it, policy update, value update, other), the medians over the steady epochs, and
    /// the whole run's end-to-end steps/s and simulator share (last line).
    #[command(
        after_help = "Example:\n  apo bench epoch --algo ppo --env Goal_Point --steps-per-epoch 10000 --threads 2"
    )]
    Epoch {
        /// Algorithm.
        #[arg(long, value_parser = crate::parse_algo, default_value = "apo")]
        algo: Algorithm,
        /// Environment name.
        #[arg(long, default_value = "Hopper")]
        env: String,
        /// Environment steps per epoch; 1..=100000000.
        #[arg(long, default_value_t = 4000, value_parser = apo_cli::flags::count::<usize>(1, apo_train::config::MAX_STEPS_PER_EPOCH as u64))]
        steps_per_epoch: usize,
        /// Epochs (the first, with the set-up, and, pipelined, the last, with no rollout ahead,
        /// are left out of the medians); 2..=1000.
        #[arg(long, default_value_t = 5, value_parser = apo_cli::flags::count::<u64>(2, 1000))]
        epochs: u64,
        /// Environments stepped together; 1..=65536.
        #[arg(long, default_value_t = 1, value_parser = apo_cli::flags::count::<usize>(1, apo_train::config::MAX_NUM_ENVS as u64))]
        num_envs: usize,
        /// Backend of the updates.
        #[arg(long, value_enum, default_value_t = BackendKind::Cpu)]
        backend: BackendKind,
        /// Where the Fisher-vector products, the proximal policy steps and the value fit run.
        #[arg(long, value_enum, default_value_t = KernelsKind::Auto)]
        kernels: KernelsKind,
        /// Threads that step the environments (0: the cores available); 0..=1024.
        #[arg(long, default_value_t = 0, value_parser = apo_cli::flags::count::<usize>(0, 1024))]
        threads: usize,
        /// The sequential epoch: no overlap of the value fit with the next rollout.
        #[arg(long)]
        no_pipeline: bool,
        /// Physics of MuJoCo environments: mujoco2, or mujoco3 (builds with the `mujoco3` feature).
        #[arg(long, value_parser = crate::parse_physics, default_value = "mujoco2")]
        physics: Physics,
    },
    /// Environment steps per second of one environment with random actions.
    #[command(
        after_help = "Example:\n  apo bench env --env Hopper --steps 100000 --physics mujoco3"
    )]
    Env {
        /// Environment name.
        #[arg(long)]
        env: String,
        /// Steps to time (environment steps, summed over the vector); 1..=1000000000.
        #[arg(long, default_value_t = 100_000, value_parser = apo_cli::flags::count::<u64>(1, 1_000_000_000))]
        steps: u64,
        /// Environments stepped together as a vector (1: one bare environment); 1..=65536.
        #[arg(long, default_value_t = 1, value_parser = apo_cli::flags::count::<usize>(1, 65_536))]
        num_envs: usize,
        /// Threads that step the vector (0: the cores available); 0..=1024.
        #[arg(long, default_value_t = 1, value_parser = apo_cli::flags::count::<usize>(0, 1024))]
        threads: usize,
        /// Physics of MuJoCo environments: mujoco2, or mujoco3 (builds with the `mujoco3` feature).
        #[arg(long, value_parser = crate::parse_physics, default_value = "mujoco2")]
        physics: Physics,
    },
    /// Microseconds per rollout policy call (host MLP, (64, 64)).
    #[command(after_help = "Example:\n  apo bench policy --obs 30 --act 2")]
    Policy {
        /// Observation dimension; 1..=100000.
        #[arg(long, default_value_t = 11, value_parser = apo_cli::flags::count::<u64>(1, 100_000))]
        obs: u64,
        /// Action dimension; 1..=10000.
        #[arg(long, default_value_t = 3, value_parser = apo_cli::flags::count::<u64>(1, 10_000))]
        act: u64,
        /// Observations per call (environments stepped together); 1..=1000000.
        #[arg(long, default_value_t = 1, value_parser = apo_cli::flags::count::<u64>(1, 1_000_000))]
        batch: u64,
        /// Calls to time; 1..=1000000000.
        #[arg(long, default_value_t = 100_000, value_parser = apo_cli::flags::count::<u64>(1, 1_000_000_000))]
        calls: u64,
    },
}

pub fn run(command: BenchCommand) -> anyhow::Result<()> {
    match command {
        BenchCommand::Update {
            backend,
            kernels,
            batch,
            obs,
            act,
            repeats,
        } => {
            let (batch, obs, act, repeats) =
                (batch as usize, obs as usize, act as usize, repeats as usize);
            let mut sized = RunConfig::defaults(Algorithm::Apo, "");
            sized.train.steps_per_epoch = batch;
            let action = apo_core::ActionKind::Continuous { dim: act };
            apo_train::input::check_fits(
                apo_train::run_config::memory_estimate(&sized, obs, action, 0.0),
                &format!("apo bench update --batch {batch} --obs {obs} --act {act}"),
            )?;
            let t = apo_cli::bench::UpdateBench {
                batch,
                obs,
                act,
                repeats,
                kernels: kernels.resolve(backend),
            }
            .on(backend)?;
            apo_cli::outln!(
                "backend={backend} kernels={kernels} batch={batch} obs={obs} act={act} params={} repeats={repeats}",
                t.params
            )?;
            apo_cli::outln!("trpo_update_s={:.4} ({})", t.trpo_s, t.tries[0])?;
            apo_cli::outln!("apo_update_s={:.4} ({})", t.apo_s, t.tries[1])?;
            apo_cli::outln!("apo_robust_update_s={:.4} ({})", t.apo_robust_s, t.tries[2])?;
            apo_cli::outln!("hvp_s={:.5}", t.hvp_s)?;
            apo_cli::outln!("fvp_s_burn={:.5}", t.fvp_s[0])?;
            apo_cli::outln!("fvp_s_host={:.5}", t.fvp_s[1])?;
            apo_cli::outln!("fvp_s_finite_difference={:.5}", t.fvp_fd_s)?;
            let (burn_step, host_step) = t.value_step_s;
            apo_cli::outln!("value_step_s_burn={burn_step:.5}")?;
            apo_cli::outln!("value_step_s_host={host_step:.5}")?;
            apo_cli::outln!("apo_over_trpo={:.3}", t.apo_s / t.trpo_s)?;
            apo_cli::outln!("apo_robust_over_trpo={:.3}", t.apo_robust_s / t.trpo_s)?;
        }
        BenchCommand::Epoch {
            algo,
            env,
            steps_per_epoch,
            epochs,
            num_envs,
            backend,
            kernels,
            threads,
            no_pipeline,
            physics,
        } => {
            let spec = apo_envs::registry::spec(&env)?;
            let mut config = RunConfig {
                backend,
                kernels,
                ..RunConfig::defaults(algo, &env)
            };
            config.train.steps_per_epoch = steps_per_epoch;
            config.train.epochs = epochs as usize;
            config.train.num_envs = num_envs;
            config.train.pipeline = !no_pipeline;
            config.train.physics = physics;
            config.validate()?;
            apo_train::input::check_fits(
                apo_train::run_config::memory_estimate(
                    &config,
                    spec.observation_dim,
                    apo_train::action_kind(&spec.action_space),
                    config.env_bytes(),
                ),
                &format!("apo bench epoch --env {env} --steps-per-epoch {steps_per_epoch} --num-envs {num_envs}"),
            )?;
            let signals = crate::signals::Signals::install()?;
            let bench = apo_cli::bench::epoch(&config, threads, &signals.stop)?;
            if signals.stop.load(std::sync::atomic::Ordering::SeqCst) {
                let signal = signals.which.load(std::sync::atomic::Ordering::SeqCst);
                anyhow::bail!(
                    "interrupted by {} after {} epoch(s); the temporary run is removed",
                    crate::signals::signal_name(signal),
                    bench.epochs.len()
                );
            }
            apo_cli::outln!("algo={algo} env={env} steps_per_epoch={steps_per_epoch} num_envs={num_envs} backend={backend} pipeline={} physics={physics}", !no_pipeline)?;
            apo_cli::outln!(
                "epoch  total_s  rollout_s    sim_s  policy_s  value_s  hidden_s  other_s"
            )?;
            for e in &bench.epochs {
                apo_cli::outln!(
                    "{:>5}  {:>7.3}  {:>9.3}  {:>7.3}  {:>8.3}  {:>7.3}  {:>8.3}  {:>7.3}",
                    e.epoch,
                    e.total_s,
                    e.rollout_s,
                    e.sim_s,
                    e.policy_s,
                    e.value_s,
                    e.hidden_s,
                    e.other_s,
                )?;
            }
            let steady = bench.steady();
            let med = |f: fn(&apo_cli::bench::EpochSplit) -> f64| {
                apo_cli::bench::median_of(steady.iter().map(f))
            };
            apo_cli::outln!(
                "median_steady_epochs ({}): total_s={:.3} rollout_s={:.3} sim_s={:.3} policy_s={:.3} value_s={:.3} hidden_s={:.3} other_s={:.3} overlap={:.2} outside_sim={:.3}",
                match (steady.first(), steady.last()) {
                    (Some(a), Some(b)) => format!("epochs {}-{}", a.epoch, b.epoch),
                    _ => "none".into(),
                },
                med(|e| e.total_s),
                med(|e| e.rollout_s),
                med(|e| e.sim_s),
                med(|e| e.policy_s),
                med(|e| e.value_s),
                med(|e| e.hidden_s),
                med(|e| e.other_s),
                med(|e| (e.hidden_s / e.value_s.max(1e-12)).min(1.0)),
                med(|e| (e.rollout_s - e.sim_s) / e.sim_s.max(1e-12)),
            )?;
            apo_cli::outln!("(each rollout is charged to the epoch whose data it collects; sim_s: its time inside the simulator's reset and step calls; outside_sim: (rollout_s − sim_s) / sim_s, the rollout's own work against the simulator's; hidden_s: rollout + policy + value − total, at least 0; overlap: hidden_s / value_s, the share of the value fit hidden behind the next rollout; end_to_end: the whole run, set-up included: steps_per_s = steps / wall_s, what a user waits for, never above sim_steps_per_s = steps / Σ sim_s, the simulator's own speed in this run; sim_share = Σ sim_s / wall_s)")?;
            apo_cli::outln!(
                "end_to_end: steps={} wall_s={:.3} steps_per_s={:.0} sim_steps_per_s={:.0} sim_share={:.3}",
                bench.steps,
                bench.wall_s,
                bench.steps_per_s(),
                bench.sim_steps_per_s(),
                bench.sim_share(),
            )?;
        }
        BenchCommand::Env {
            env,
            steps,
            num_envs,
            threads,
            physics,
        } => {
            let options = apo_envs::MakeOptions {
                physics: Some(physics),
                ..Default::default()
            };
            let rate = if num_envs == 1 {
                let mut e = apo_envs::make_with(&env, &options)?;
                apo_envs::throughput::steps_per_second(e.as_mut(), steps as usize, 0)
            } else {
                let mut envs = apo_envs::vector::VecEnv::make_with(&env, num_envs, &options)?
                    .with_threads(threads)?;
                apo_cli::outln!("threads={}", envs.threads())?;
                apo_envs::throughput::vector_steps_per_second(&mut envs, steps as usize, 0)
            };
            apo_cli::outln!("env={env} steps={steps} num_envs={num_envs} physics={physics}")?;
            apo_cli::outln!("steps_per_sec={rate:.1}")?;
        }
        BenchCommand::Policy {
            obs,
            act,
            batch,
            calls,
        } => {
            let (obs, act, batch, calls) =
                (obs as usize, act as usize, batch as usize, calls as usize);
            apo_train::input::check_fits(
                apo_cli::bench::policy_call_bytes(obs, act, batch),
                "apo bench policy --obs/--act/--batch",
            )?;
            let us = apo_cli::bench::policy_call_us(
                obs,
                apo_core::ActionKind::Continuous { dim: act },
                batch,
                calls,
            );
            apo_cli::outln!("obs={obs} act={act} batch={batch}")?;
            apo_cli::outln!("policy_call_us={us:.3}")?;
        }
    }
    Ok(())
}
