//! `apo`: train, evaluate, plot and benchmark APO, PAPO, TRPO, PPO and A2C.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{bail, Context};
use apo_cli::config::{BackendKind, RunConfig};
use apo_cli::progress::ProgressRow;
use apo_cli::trainer::{self, Observer, TrainEnd};
use apo_core::Algorithm;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

#[derive(Parser)]
#[command(name = "apo", version, about = "Absolute Policy Optimization and baselines on Burn")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Train a policy.
    Train(TrainArgs),
    /// Evaluate a run's policy: prints the mean and the minimum return.
    Eval {
        /// The run directory.
        #[arg(long)]
        run: PathBuf,
        /// Number of episodes.
        #[arg(long, default_value_t = 10)]
        episodes: usize,
        /// Act with the mean (Gaussian) or most likely (categorical) action.
        #[arg(long)]
        deterministic: bool,
        /// Seed of the evaluation episodes.
        #[arg(long, default_value_t = 12345)]
        seed: u64,
    },
    /// List environments and algorithms.
    List,
    /// Plot learning curves of runs (mean return, min–max band, worst return).
    Plot {
        /// Run directories.
        #[arg(required = true)]
        runs: Vec<PathBuf>,
        /// Output image, .png or .svg.
        #[arg(long)]
        out: PathBuf,
    },
    /// The paper's metrics of runs: average mean and worst return over all and the last N epochs.
    Summary {
        /// Run directories.
        #[arg(required = true)]
        runs: Vec<PathBuf>,
        /// N of "the last N epochs" (paper: 20 continuous, 100 Atari).
        #[arg(long, default_value_t = 20)]
        last: usize,
    },
    /// Benchmarks.
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Time one APO and one TRPO trust-region update and a Hessian-vector product.
    Update {
        /// Backend.
        #[arg(long, value_enum, default_value_t = BackendKind::Cpu)]
        backend: BackendKind,
        /// Samples in the batch.
        #[arg(long, default_value_t = 30_000)]
        batch: usize,
        /// Observation dimension.
        #[arg(long, default_value_t = 60)]
        obs: usize,
        /// Action dimension.
        #[arg(long, default_value_t = 8)]
        act: usize,
        /// Timed repeats (after one warm-up); the median is printed.
        #[arg(long, default_value_t = 3)]
        repeats: usize,
    },
    /// Environment steps per second of one environment with random actions.
    Env {
        /// Environment name.
        #[arg(long)]
        env: String,
        /// Steps to time.
        #[arg(long, default_value_t = 100_000)]
        steps: usize,
    },
    /// Microseconds per rollout policy call (host MLP, (64, 64)).
    Policy {
        /// Observation dimension.
        #[arg(long, default_value_t = 11)]
        obs: usize,
        /// Action dimension.
        #[arg(long, default_value_t = 3)]
        act: usize,
        /// Observations per call (environments stepped together).
        #[arg(long, default_value_t = 1)]
        batch: usize,
        /// Calls to time.
        #[arg(long, default_value_t = 100_000)]
        calls: usize,
    },
}

#[derive(clap::Args)]
struct TrainArgs {
    /// Algorithm: apo, papo, trpo, ppo, a2c.
    #[arg(long, value_parser = parse_algo)]
    algo: Option<Algorithm>,
    /// Environment name (see `apo list`).
    #[arg(long)]
    env: Option<String>,
    /// Backend of the updates.
    #[arg(long, value_enum)]
    backend: Option<BackendKind>,
    /// TOML config file (keys as in a run's config.toml; defaults fill the rest).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Number of epochs.
    #[arg(long)]
    epochs: Option<usize>,
    /// Environment steps per epoch.
    #[arg(long)]
    steps_per_epoch: Option<usize>,
    /// Run directory (default runs/<env>-<algo>-s<seed>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Override a config key, e.g. --set algo.k=5 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Continue the run in this directory from its last checkpoint (--epochs may extend it).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["algo", "env", "config", "out", "force"])]
    resume: Option<PathBuf>,
    /// Replace an existing run directory.
    #[arg(long)]
    force: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

fn parse_algo(s: &str) -> Result<Algorithm, String> {
    s.parse::<Algorithm>().map_err(|_| {
        let names: Vec<&str> = Algorithm::ALL.iter().map(|a| a.name()).collect();
        let best = names
            .iter()
            .map(|n| (strsim::jaro_winkler(n, &s.to_lowercase()), *n))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .filter(|(score, _)| *score > 0.7)
            .map(|(_, n)| format!("; did you mean `{n}`?"))
            .unwrap_or_default();
        format!("unknown algorithm `{s}`{best} (known: {})", names.join(", "))
    })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Train(args) => train(args),
        Command::List => {
            list();
            Ok(())
        }
        Command::Eval { run, episodes, deterministic, seed } => eval(&run, episodes, deterministic, seed),
        Command::Plot { runs, out } => apo_cli::plot::plot(&runs, &out).map(|()| println!("wrote {}", out.display())),
        Command::Bench(command) => bench(command),
        Command::Summary { runs, last } => summary(&runs, last),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn eval(run: &Path, episodes: usize, deterministic: bool, seed: u64) -> anyhow::Result<()> {
    if episodes == 0 {
        bail!("--episodes must be at least 1");
    }
    let result = apo_cli::eval::evaluate(run, episodes, deterministic, seed)?;
    let stats = apo_core::EpisodeStats::from_episodes(&result.returns, &result.lengths, 0.0)
        .context("no episode was run")?;
    println!("episodes={} mean_return={:.3} min_return={:.3} max_return={:.3} mean_length={:.1}",
        stats.count, stats.ret_mean, stats.ret_min, stats.ret_max, stats.len_mean);
    Ok(())
}

fn summary(runs: &[PathBuf], last: usize) -> anyhow::Result<()> {
    let fmt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    println!("run,epochs,env_steps,mean_all,mean_last{last},worst_all,worst_last{last},steps_per_s");
    for run in runs {
        let s = apo_cli::summary::summarize(run, last)?;
        println!(
            "{},{},{},{},{},{},{},{:.0}",
            run.display(), s.epochs, s.env_steps, fmt(s.mean_all), fmt(s.mean_last), fmt(s.worst_all), fmt(s.worst_last), s.steps_per_s
        );
    }
    Ok(())
}

fn bench(command: BenchCommand) -> anyhow::Result<()> {
    match command {
        BenchCommand::Update { backend, batch, obs, act, repeats } => {
            let repeats = repeats.max(1);
            let t = match backend {
                BackendKind::Cpu => apo_cli::bench::update::<burn::backend::NdArray>(&Default::default(), batch, obs, act, repeats),
                BackendKind::Wgpu => apo_cli::bench::update::<burn::backend::Wgpu>(&Default::default(), batch, obs, act, repeats),
            };
            println!("backend={backend} batch={batch} obs={obs} act={act} params={} repeats={repeats}", t.params);
            println!("trpo_update_s={:.4} ({})", t.trpo_s, t.tries.0);
            println!("apo_update_s={:.4} ({})", t.apo_s, t.tries.1);
            println!("hvp_s={:.5}", t.hvp_s);
            println!("apo_over_trpo={:.3}", t.apo_s / t.trpo_s);
        }
        BenchCommand::Env { env, steps } => {
            let mut e = apo_envs::make(&env)?;
            let rate = apo_envs::mujoco::steps_per_second(e.as_mut(), steps, 0);
            println!("env={env} steps={steps}");
            println!("steps_per_sec={rate:.1}");
        }
        BenchCommand::Policy { obs, act, batch, calls } => {
            let us = apo_cli::bench::policy_call_us(obs, apo_core::ActionKind::Continuous { dim: act }, batch.max(1), calls.max(1));
            println!("obs={obs} act={act} batch={batch}");
            println!("policy_call_us={us:.3}");
        }
    }
    Ok(())
}

fn list() {
    println!("{:<28} {:>8}  {:<14} {:>9}", "environment", "obs dim", "actions", "max steps");
    for spec in apo_envs::list() {
        let actions = match &spec.action_space {
            apo_envs::Space::Discrete { n } => format!("discrete({n})"),
            apo_envs::Space::Box { low, .. } => format!("box({})", low.len()),
        };
        println!("{:<28} {:>8}  {:<14} {:>9}", spec.name, spec.observation_dim, actions, spec.max_episode_steps);
    }
    println!();
    println!("algorithms: {}", Algorithm::ALL.iter().map(|a| a.name()).collect::<Vec<_>>().join(", "));
}

struct Bar(Option<ProgressBar>);

impl Observer for Bar {
    fn epoch(&mut self, row: &ProgressRow, epochs: usize) {
        if let Some(bar) = &self.0 {
            bar.set_length(epochs as u64);
            bar.set_position(row.epoch as u64);
            let fmt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
            bar.set_message(format!(
                "{:.0} steps/s  return mean {}  min {}",
                row.steps_per_s,
                fmt(row.ep_ret_mean),
                fmt(row.ep_ret_min)
            ));
        }
    }
}

fn init_logging(run_dir: &Path) -> anyhow::Result<()> {
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    use tracing_subscriber::{fmt, EnvFilter, Layer};
    let file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(run_dir.join("train.log"))
        .with_context(|| format!("cannot open {}", run_dir.join("train.log").display()))?;
    let stderr_filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("warn"));
    tracing_subscriber::registry()
        .with(fmt::layer().with_writer(std::sync::Mutex::new(file)).with_ansi(false).with_filter(EnvFilter::new("info")))
        .with(fmt::layer().with_writer(std::io::stderr).with_filter(stderr_filter))
        .try_init()
        .ok();
    Ok(())
}

fn train(args: TrainArgs) -> anyhow::Result<()> {
    let (config, run_dir, resume) = match &args.resume {
        Some(dir) => {
            let mut config = RunConfig::load(&dir.join("config.toml"))
                .with_context(|| format!("{} is not a run directory", dir.display()))?;
            if let Some(epochs) = args.epochs {
                config.epochs = epochs;
            }
            if args.seed.is_some() || args.steps_per_epoch.is_some() || args.backend.is_some() || !args.sets.is_empty() {
                bail!("--resume continues a run with its own config.toml; only --epochs may change");
            }
            (config, dir.clone(), true)
        }
        None => {
            let algo = args.algo.context("--algo is required (apo, papo, trpo, ppo, a2c)")?;
            let env = args.env.clone().context("--env is required (see `apo list`)")?;
            apo_envs::registry::spec(&env)?;
            let mut sets = args.sets.clone();
            let flag = |k: &str, v: Option<String>| v.map(|v| format!("{k}={v}"));
            sets.extend(
                [
                    flag("env", Some(format!("{env:?}"))),
                    flag("seed", args.seed.map(|v| v.to_string())),
                    flag("epochs", args.epochs.map(|v| v.to_string())),
                    flag("steps_per_epoch", args.steps_per_epoch.map(|v| v.to_string())),
                    flag("backend", args.backend.map(|b| format!("\"{b}\""))),
                ]
                .into_iter()
                .flatten(),
            );
            let config = RunConfig::build(algo, &env, args.config.as_deref(), &sets)?;
            let dir = args
                .out
                .clone()
                .unwrap_or_else(|| PathBuf::from(format!("runs/{}-{}-s{}", config.env, algo, config.seed)));
            prepare_run_dir(&dir, args.force)?;
            apo_cli::atomic::write(&dir.join("config.toml"), config.to_toml().as_bytes())?;
            (config, dir, false)
        }
    };
    apo_envs::registry::spec(&config.env)?;
    init_logging(&run_dir)?;

    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)).context("installing the Ctrl-C handler")?;
    }
    let bar = (!args.quiet).then(|| {
        let bar = ProgressBar::new(config.epochs as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:30} epoch {pos}/{len} [{elapsed_precise}] {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar
    });
    let mut observer = Bar(bar.clone());
    let end = match config.backend {
        BackendKind::Cpu => trainer::train::<burn::backend::NdArray>(&config, &run_dir, &Default::default(), resume, &stop, &mut observer),
        BackendKind::Wgpu => trainer::train::<burn::backend::Wgpu>(&config, &run_dir, &Default::default(), resume, &stop, &mut observer),
    }?;
    if let Some(bar) = bar {
        bar.finish();
    }
    match end {
        TrainEnd::Finished => println!("run finished: {}", run_dir.display()),
        TrainEnd::Interrupted => println!(
            "interrupted; checkpoint written. Continue with: apo train --resume {}",
            run_dir.display()
        ),
    }
    Ok(())
}

fn prepare_run_dir(dir: &Path, force: bool) -> anyhow::Result<()> {
    if dir.exists() && std::fs::read_dir(dir)?.next().is_some() {
        if !force {
            bail!(
                "run directory {} already exists; pass --force to replace it, or --resume {} to continue it",
                dir.display(),
                dir.display()
            );
        }
        std::fs::remove_dir_all(dir).with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))
}
