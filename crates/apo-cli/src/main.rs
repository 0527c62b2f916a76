//! `apo`: train, evaluate, plot and benchmark APO, PAPO, TRPO, PPO and A2C.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use anyhow::{bail, Context};
use apo_cli::checkpoint::Which;
use apo_cli::config::{BackendKind, KernelsKind, Preset, RunConfig};
use apo_cli::progress::ProgressRow;
use apo_cli::run_dir::{self, NewRunDir, RunLock};
use apo_cli::trainer::{self, Observer, TrainEnd};
use apo_core::Algorithm;
use apo_envs::mujoco::Physics;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

const CONFIG_HELP: &str = "Defaults are the paper's (configs/<algo>.toml spells them out). Every config key with its \
meaning, default and range: `apo config --algo <ALGO>`; set any key with --set key=value or a --config file.";

#[derive(Parser)]
#[command(
    name = "apo",
    version,
    about = "Absolute Policy Optimization and baselines on Burn"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Train a policy (Ctrl-C or SIGTERM: checkpoint and stop; a second one: stop at once).
    #[command(after_help = CONFIG_HELP)]
    Train(TrainArgs),
    /// Evaluate a run's policy: prints the mean, std, min and max return.
    Eval {
        /// The run directory.
        #[arg(long)]
        run: PathBuf,
        /// Number of episodes.
        #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
        episodes: u64,
        /// Act with the mean (Gaussian) or most likely (categorical) action.
        #[arg(long)]
        deterministic: bool,
        /// Seed of the evaluation episodes.
        #[arg(long, default_value_t = 12345)]
        seed: u64,
        /// Which checkpoint: `latest`, or an epoch kept by keep_checkpoint_every.
        #[arg(long, default_value = "latest")]
        checkpoint: Which,
    },
    /// Print the effective config with every key's meaning and range (TOML; usable as --config).
    Config {
        /// Algorithm whose defaults to start from.
        #[arg(long, value_parser = parse_algo, default_value = "apo")]
        algo: Algorithm,
        /// Environment name.
        #[arg(long)]
        env: Option<String>,
        /// TOML config file layered over the defaults.
        #[arg(long)]
        config: Option<PathBuf>,
        /// Settings layered over the defaults and --config, under --set.
        #[arg(long, value_enum)]
        preset: Option<Preset>,
        /// Override a config key, e.g. --set algo.k=5 (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// Print this run directory's config instead.
        #[arg(long, conflicts_with_all = ["env", "config", "preset", "sets"])]
        run: Option<PathBuf>,
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
        /// Moving average over this many epochs (1: none).
        #[arg(long, default_value_t = 1)]
        smooth: usize,
        /// Plot this numeric progress.csv column instead of the returns (e.g. kl,
        /// ls_rejected_objective, bias, min_j_sq_on).
        #[arg(long)]
        column: Option<String>,
    },
    /// The APO paper's Theorem 1 checked exactly on random tabular MDPs: (a) the surrogate
    /// M_k^j(π) ≤ B_k(π) = J − k·V, (b) equality at π_j, (c) B_k along exact APO iterations and
    /// along the practical trust-region surrogate, (d) Selberg's confidence (docs/theory.md).
    Theory(apo_cli::theory::TheoryArgs),
    /// The paper's metrics of runs: average mean and worst return over all and the last N epochs.
    Summary {
        /// Run directories.
        #[arg(required = true)]
        runs: Vec<PathBuf>,
        /// N of "the last N epochs" (paper: 20 continuous, 100 Atari).
        #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..))]
        last: u64,
        /// CSV instead of an aligned table.
        #[arg(long)]
        csv: bool,
    },
    /// The paper's metrics per environment and algorithm, mean ± std over seeds: average mean
    /// and worst return over all and the last N epochs, the bound and its confidence, the
    /// TRPO-normalized scores, the count of "best" per metric; Markdown on stdout, and with
    /// --out also report.md, report.csv and learning curves (mean ± std over seeds).
    Report {
        /// Run directories, or folders of runs (a sweep's); seeds of one setting are grouped
        /// by environment, algorithm and the directory name without `-s<seed>`.
        #[arg(required = true)]
        runs: Vec<PathBuf>,
        /// N of "the last N epochs" (paper: 20 continuous, 100 Atari).
        #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..))]
        last: u64,
        /// Folder for report.md, report.csv and curves-<env>.<image>.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Episodes of the random policy that the scores are normalized by.
        #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=100_000))]
        random_episodes: u64,
        /// Image format of the curves.
        #[arg(long, value_parser = ["png", "svg"], default_value = "png")]
        image: String,
        /// Moving average of the curves over this many epochs (1: none).
        #[arg(long, default_value_t = 1)]
        smooth: usize,
    },
    /// Run a grid of config values × seeds × algorithms × environments, each a separate run
    /// under one directory, several at once; run it again to resume (finished runs are
    /// skipped, interrupted ones resumed). Ends with each cell's metric over its seeds.
    Sweep(SweepArgs),
    /// Benchmarks.
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(clap::Args)]
struct SweepArgs {
    /// Algorithms, comma-separated (e.g. apo,trpo).
    #[arg(long, value_delimiter = ',', required = true)]
    algo: Vec<String>,
    /// Environments, comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    env: Vec<String>,
    /// Seeds: a list (0,1,2) or a range (0..5, end excluded).
    #[arg(long, default_value = "0..3")]
    seeds: String,
    /// A grid axis, key=v1,v2,… (repeatable; axes multiply). An axis applies to the
    /// algorithms that have the key.
    #[arg(long = "grid", value_name = "KEY=V1,V2,…")]
    grid: Vec<String>,
    /// The sweep's directory (runs are <env>-<algo>[-<key>=<value>…]-s<seed> inside it).
    #[arg(long)]
    out: PathBuf,
    /// Epochs of every run.
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..))]
    epochs: u64,
    /// Environment steps per epoch of every run [default: the config's].
    #[arg(long)]
    steps_per_epoch: Option<usize>,
    /// Preset of every run.
    #[arg(long, value_enum)]
    preset: Option<Preset>,
    /// Config file of every run (its algorithm section is ignored for other algorithms: give
    /// one algorithm with a config file).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Override a config key in every run (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Runs at once.
    #[arg(long, default_value_t = 1, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=256))]
    jobs: usize,
    /// Threads of each run (0: the cores available divided by --jobs).
    #[arg(long, default_value_t = 0, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=1024))]
    threads: usize,
    /// Metric that ranks the cells.
    #[arg(long, value_enum, default_value_t = apo_cli::sweep::Metric::WorstLast)]
    metric: apo_cli::sweep::Metric,
    /// N of "the last N epochs".
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..))]
    last: u64,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Time one APO and one TRPO trust-region update, a KL Hessian-vector product (double
    /// backward), a Fisher-vector product and a value-fit Adam step (the last two on Burn's
    /// graph and on the host kernels).
    Update {
        /// Backend.
        #[arg(long, value_enum, default_value_t = BackendKind::Cpu)]
        backend: BackendKind,
        /// Where the trust-region updates' Fisher-vector products run.
        #[arg(long, value_enum, default_value_t = KernelsKind::Auto)]
        kernels: KernelsKind,
        /// Samples in the batch.
        #[arg(long, default_value_t = 30_000, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
        batch: u64,
        /// Observation dimension.
        #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..=100_000))]
        obs: u64,
        /// Action dimension.
        #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u64).range(1..=10_000))]
        act: u64,
        /// Timed repeats (after one warm-up); the median is printed.
        #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=1000))]
        repeats: u64,
    },
    /// Train a few epochs and print where each epoch's time goes (rollout, policy update,
    /// value update, other) and the end-to-end steps/s (medians over epochs 2.. on the last line).
    Epoch {
        /// Algorithm.
        #[arg(long, value_parser = parse_algo, default_value = "apo")]
        algo: Algorithm,
        /// Environment name.
        #[arg(long, default_value = "Hopper")]
        env: String,
        /// Environment steps per epoch.
        #[arg(long, default_value_t = 4000)]
        steps_per_epoch: usize,
        /// Epochs (the first includes the set-up and is left out of the medians).
        #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(2..=1000))]
        epochs: u64,
        /// Environments stepped together.
        #[arg(long, default_value_t = 1)]
        num_envs: usize,
        /// Backend of the updates.
        #[arg(long, value_enum, default_value_t = BackendKind::Cpu)]
        backend: BackendKind,
        /// Where the Fisher-vector products and the value fit run.
        #[arg(long, value_enum, default_value_t = KernelsKind::Auto)]
        kernels: KernelsKind,
        /// Threads that step the environments (0: the cores available).
        #[arg(long, default_value_t = 0, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=1024))]
        threads: usize,
    },
    /// Environment steps per second of one environment with random actions.
    Env {
        /// Environment name.
        #[arg(long)]
        env: String,
        /// Steps to time (environment steps, summed over the vector).
        #[arg(long, default_value_t = 100_000, value_parser = clap::value_parser!(u64).range(1..))]
        steps: u64,
        /// Environments stepped together as a vector (1: one bare environment).
        #[arg(long, default_value_t = 1, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=65_536))]
        num_envs: usize,
        /// Threads that step the vector (0: the cores available).
        #[arg(long, default_value_t = 1, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=1024))]
        threads: usize,
        /// Physics of MuJoCo environments: mujoco2, or mujoco3 (builds with the `mujoco3` feature).
        #[arg(long, value_parser = parse_physics, default_value = "mujoco2")]
        physics: Physics,
    },
    /// Microseconds per rollout policy call (host MLP, (64, 64)).
    Policy {
        /// Observation dimension.
        #[arg(long, default_value_t = 11, value_parser = clap::value_parser!(u64).range(1..=100_000))]
        obs: u64,
        /// Action dimension.
        #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=10_000))]
        act: u64,
        /// Observations per call (environments stepped together).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
        batch: u64,
        /// Calls to time.
        #[arg(long, default_value_t = 100_000, value_parser = clap::value_parser!(u64).range(1..))]
        calls: u64,
    },
}

#[derive(clap::Args)]
struct TrainArgs {
    /// Algorithm [default with --config: the file's section [algo.<name>]].
    #[arg(long, value_parser = parse_algo)]
    algo: Option<Algorithm>,
    /// Environment name (see `apo list`).
    #[arg(long)]
    env: Option<String>,
    /// Backend of the updates [config: backend; default cpu].
    #[arg(long, value_enum)]
    backend: Option<BackendKind>,
    /// Physics of MuJoCo environments, mujoco2 or mujoco3 (builds with the `mujoco3` feature)
    /// [config: physics; default mujoco2].
    #[arg(long, value_parser = parse_physics)]
    physics: Option<Physics>,
    /// TOML config file (keys as in a run's config.toml or `apo config`; defaults fill the rest).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Settings layered over the defaults and --config, under --set: `paper` reproduces the
    /// paper's published code (`apo config --preset paper` shows them).
    #[arg(long, value_enum)]
    preset: Option<Preset>,
    /// Seed [config: seed; default 0; 0..=9223372036854775807].
    #[arg(long, value_parser = clap::value_parser!(u64).range(0..=i64::MAX as u64))]
    seed: Option<u64>,
    /// Number of epochs [config: epochs; default 200]; with --resume, the run's new target.
    #[arg(long)]
    epochs: Option<usize>,
    /// Environment steps per epoch [config: steps_per_epoch; default 30000].
    #[arg(long)]
    steps_per_epoch: Option<usize>,
    /// Environments stepped together [config: num_envs; default 1].
    #[arg(long)]
    num_envs: Option<usize>,
    /// Threads that step the environments (0: the cores available); results do not depend
    /// on it, so it may change on --resume.
    #[arg(long, default_value_t = 0, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=1024))]
    threads: usize,
    /// Write a checkpoint every N epochs [config: checkpoint_every; default 1].
    #[arg(long, value_name = "N")]
    checkpoint_every: Option<usize>,
    /// Run directory [default: runs/<env>-<algo>-s<seed>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Override a config key, e.g. --set algo.k=5 (repeatable; see `apo config`).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Continue the run in this directory from its last checkpoint (--epochs may extend it).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["algo", "env", "config", "preset", "out", "force"])]
    resume: Option<PathBuf>,
    /// Replace an existing run directory (only one apo made; other files in it are kept).
    #[arg(long)]
    force: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// The registered algorithms' names, comma-separated.
fn algorithm_names() -> String {
    Algorithm::ALL
        .iter()
        .map(|a| a.name())
        .collect::<Vec<_>>()
        .join(", ")
}

/// `--physics`: a MuJoCo physics by name (`mujoco2`, `mujoco3`).
fn parse_physics(name: &str) -> Result<Physics, String> {
    name.parse()
        .map_err(|e: apo_envs::mujoco::MujocoError| e.to_string())
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
        format!(
            "unknown algorithm `{s}`{best} (known: {})",
            names.join(", ")
        )
    })
}

/// Exit status of a run stopped by SIGINT (128 + 2) or SIGTERM (128 + 15).
fn interrupted_status(signal: usize) -> u8 {
    128u8.saturating_add(u8::try_from(signal).unwrap_or(0))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    #[cfg(feature = "atari")]
    if let Err(e) = apo_atari::register_games() {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Train(args) => train_on_ranks(args),
        Command::List => list().map(|()| ExitCode::SUCCESS),
        Command::Eval {
            run,
            episodes,
            deterministic,
            seed,
            checkpoint,
        } => eval(&run, &checkpoint, episodes as usize, deterministic, seed)
            .map(|()| ExitCode::SUCCESS),
        Command::Config {
            algo,
            env,
            config,
            preset,
            sets,
            run,
        } => print_config(algo, env, preset, config, &sets, run).map(|()| ExitCode::SUCCESS),
        Command::Plot {
            runs,
            out,
            smooth,
            column,
        } => apo_cli::plot::plot(&runs, &out, &apo_cli::plot::PlotOptions { smooth, column })
            .map(|()| println!("wrote {}", out.display()))
            .map(|()| ExitCode::SUCCESS),
        Command::Bench(command) => bench(command).map(|()| ExitCode::SUCCESS),
        Command::Sweep(args) => sweep(args),
        Command::Theory(args) => apo_cli::theory::run(&args).map(|()| ExitCode::SUCCESS),
        Command::Report {
            runs,
            last,
            out,
            random_episodes,
            image,
            smooth,
        } => report(
            &runs,
            last as usize,
            out.as_deref(),
            random_episodes as usize,
            &image,
            smooth,
        )
        .map(|()| ExitCode::SUCCESS),
        Command::Summary { runs, last, csv } => {
            summary(&runs, last as usize, csv).map(|()| ExitCode::SUCCESS)
        }
    };
    result.unwrap_or_else(|e| {
        eprintln!("error: {e:#}");
        if let Some(hint) = atari_hint(&e) {
            eprintln!("{hint}");
        }
        ExitCode::FAILURE
    })
}

/// For an unknown `ALE/…` environment in a build without the `atari` feature: how to get the
/// Atari games.
fn atari_hint(error: &anyhow::Error) -> Option<&'static str> {
    let unknown_game = error.chain().any(|cause| {
        matches!(cause.downcast_ref::<apo_envs::EnvError>(),
            Some(apo_envs::EnvError::Unknown { name, .. })
                if name.get(..4).is_some_and(|ns| ns.eq_ignore_ascii_case("ALE/")))
    });
    (unknown_game && cfg!(not(feature = "atari"))).then_some(
        "hint: the Atari games (`ALE/<Game>-v5`) are in builds with the `atari` feature \
         (GPL-2.0): cargo build --release -p apo-cli --features atari",
    )
}

fn eval(
    run: &Path,
    which: &Which,
    episodes: usize,
    deterministic: bool,
    seed: u64,
) -> anyhow::Result<()> {
    let (result, epoch) = apo_cli::eval::evaluate(run, which, episodes, deterministic, seed)?;
    let stats = apo_core::EpisodeStats::from_episodes(&result.returns, &result.lengths, 0.0)
        .context("no episode was run")?;
    let success = result
        .success_rate()
        .map_or_else(String::new, |rate| format!(" success_rate={rate:.3}"));
    println!(
        "checkpoint_epoch={epoch} episodes={} mean_return={:.3} std_return={:.3} min_return={:.3} max_return={:.3} mean_length={:.1}{success}",
        stats.count, stats.ret_mean, stats.ret_std, stats.ret_min, stats.ret_max, stats.len_mean
    );
    Ok(())
}

fn summary(runs: &[PathBuf], last: usize, csv: bool) -> anyhow::Result<()> {
    let rows = runs
        .iter()
        .map(|run| {
            Ok((
                run.display().to_string(),
                apo_cli::summary::summarize(run, last)?,
            ))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    if csv {
        print!("{}", apo_cli::summary::csv(&rows, last)?);
    } else {
        print!("{}", apo_cli::summary::table(&rows, last));
    }
    Ok(())
}

fn report(
    paths: &[PathBuf],
    last: usize,
    out: Option<&Path>,
    random_episodes: usize,
    image: &str,
    smooth: usize,
) -> anyhow::Result<()> {
    use apo_cli::report;
    let runs = report::find_runs(paths)?;
    let report = report::report(&runs, last, &mut |env, options| {
        report::random_baseline(env, options, random_episodes, 0)
    })?;
    print!("{}", report::markdown(&report));
    if let Some(out) = out {
        for path in report::write(&report, out, image, smooth)? {
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// Parses `--seeds`: `0,1,2` or `0..5`.
fn parse_seeds(text: &str) -> anyhow::Result<Vec<u64>> {
    let bad = || format!("--seeds expects a list (0,1,2) or a range (0..5), got `{text}`");
    let seeds: Vec<u64> = match text.split_once("..") {
        Some((a, b)) => {
            let (a, b): (u64, u64) = (
                a.trim().parse().with_context(bad)?,
                b.trim().parse().with_context(bad)?,
            );
            (a..b).collect()
        }
        None => text
            .split(',')
            .map(|s| s.trim().parse::<u64>())
            .collect::<Result<_, _>>()
            .with_context(bad)?,
    };
    if seeds.is_empty() || seeds.iter().any(|&s| s > i64::MAX as u64) {
        bail!("{}", bad());
    }
    Ok(seeds)
}

fn sweep(args: SweepArgs) -> anyhow::Result<ExitCode> {
    use apo_cli::sweep;
    let spec = sweep::SweepSpec {
        envs: args.env.clone(),
        algos: args.algo.clone(),
        seeds: parse_seeds(&args.seeds)?,
        grid: args
            .grid
            .iter()
            .map(|g| sweep::Axis::parse(g))
            .collect::<anyhow::Result<_>>()?,
        preset: args
            .preset
            .and_then(|p| clap::ValueEnum::to_possible_value(&p))
            .map(|v| v.get_name().to_string()),
        config: args.config.clone(),
        sets: args.sets.clone(),
        steps_per_epoch: args.steps_per_epoch,
    };
    let runs = sweep::expand(&spec)?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let options = sweep::SweepOptions {
        out: args.out.clone(),
        epochs: args.epochs as usize,
        jobs: args.jobs,
        threads: if args.threads == 0 {
            (cores / args.jobs).max(1)
        } else {
            args.threads
        },
    };
    let exe = std::env::current_exe().context("locating the apo executable")?;
    let signals = Signals::install()?;
    let total = runs.len() as u64 * args.epochs;
    let bar = (!args.quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = ProgressBar::new(total);
        bar.set_style(
            ProgressStyle::with_template(
                "{bar:40} {pos}/{len} epochs  runs {msg}  {elapsed_precise} (eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar
    });
    let run_count = runs.len();
    let mut tick = |epochs: usize, done: usize| {
        if let Some(bar) = &bar {
            bar.set_position(epochs as u64);
            bar.set_message(format!("{done}/{run_count}"));
        }
    };
    println!(
        "sweep: {} runs ({} environments, {} algorithms, {} seeds) in {}",
        runs.len(),
        spec.envs.len(),
        spec.algos.len(),
        spec.seeds.len(),
        args.out.display()
    );
    let outcome = sweep::run(&exe, &spec, &runs, &options, &signals.stop, &mut tick)?;
    if let Some(bar) = &bar {
        bar.abandon();
    }
    let results = sweep::cell_results(&args.out, &runs, args.metric, args.last as usize);
    let csv = sweep::cells_csv(&results);
    let csv_path = args.out.join("cells.csv");
    apo_cli::atomic::write(&csv_path, csv.as_bytes())?;
    let metric = clap::ValueEnum::to_possible_value(&args.metric)
        .map(|v| v.get_name().to_string())
        .unwrap_or_default();
    println!(
        "{metric} (last {}), mean ± std over seeds; best cell first:",
        args.last
    );
    let mut previous: Option<(&str, Algorithm)> = None;
    let width = algorithm_name_width();
    for r in &results {
        let best = previous != Some((r.env.as_str(), r.algo));
        previous = Some((r.env.as_str(), r.algo));
        println!(
            "{} {:<12} {:<width$} {:<40} {:>10.2} ± {:<8.2} ({} seeds)",
            if best { "*" } else { " " },
            r.env,
            r.algo.name(),
            r.cell,
            r.mean,
            r.std,
            r.seeds
        );
    }
    println!(
        "finished {} (skipped {} finished before), failed {}; cells: {}",
        outcome.finished,
        outcome.skipped,
        outcome.failed.len(),
        csv_path.display()
    );
    for (name, error) in &outcome.failed {
        eprintln!("failed: {name}: {error}");
    }
    if outcome.interrupted {
        println!("interrupted: run the same command again to resume");
        return Ok(ExitCode::from(interrupted_status(
            signals.which.load(Ordering::SeqCst),
        )));
    }
    Ok(if outcome.failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn print_config(
    algo: Algorithm,
    env: Option<String>,
    preset: Option<Preset>,
    file: Option<PathBuf>,
    sets: &[String],
    run: Option<PathBuf>,
) -> anyhow::Result<()> {
    let config = match run {
        Some(run) => RunConfig::load(&run.join(run_dir::CONFIG))
            .with_context(|| format!("{} is not a run directory", run.display()))?,
        None => {
            if let Some(env) = &env {
                apo_envs::registry::spec(env)?;
            }
            RunConfig::build_with_preset(
                algo,
                env.as_deref().unwrap_or(""),
                preset,
                file.as_deref(),
                sets,
            )?
        }
    };
    print!("{}", config.documented_toml());
    Ok(())
}

fn bench(command: BenchCommand) -> anyhow::Result<()> {
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
            sized
                .check_memory(obs, apo_core::ActionKind::Continuous { dim: act })
                .context("apo bench update --batch/--obs/--act")?;
            let t = match backend {
                BackendKind::Cpu => apo_cli::bench::update::<burn::backend::NdArray>(
                    &Default::default(),
                    batch,
                    obs,
                    act,
                    repeats,
                    kernels.resolve(backend),
                ),
                BackendKind::Wgpu => {
                    quiet_wgpu();
                    apo_cli::bench::update::<burn::backend::Wgpu>(
                        &Default::default(),
                        batch,
                        obs,
                        act,
                        repeats,
                        kernels.resolve(backend),
                    )
                }
            };
            println!(
                "backend={backend} kernels={kernels} batch={batch} obs={obs} act={act} params={} repeats={repeats}",
                t.params
            );
            println!("trpo_update_s={:.4} ({})", t.trpo_s, t.tries.0);
            println!("apo_update_s={:.4} ({})", t.apo_s, t.tries.1);
            println!("hvp_s={:.5}", t.hvp_s);
            println!("fvp_s_burn={:.5}", t.fvp_s[0]);
            println!("fvp_s_host={:.5}", t.fvp_s[1]);
            let (burn_step, host_step) = t.value_step_s;
            println!("value_step_s_burn={burn_step:.5}");
            println!("value_step_s_host={host_step:.5}");
            println!("apo_over_trpo={:.3}", t.apo_s / t.trpo_s);
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
            config.validate()?;
            config.check_memory(
                spec.observation_dim,
                apo_train::action_kind(&spec.action_space),
            )?;
            if backend == BackendKind::Wgpu {
                quiet_wgpu();
            }
            let split = apo_cli::bench::epoch(&config, threads)?;
            println!("algo={algo} env={env} steps_per_epoch={steps_per_epoch} num_envs={num_envs} backend={backend}");
            println!("epoch  total_s  rollout_s  policy_s  value_s  other_s  steps_per_s");
            for e in &split {
                println!(
                    "{:>5}  {:>7.3}  {:>9.3}  {:>8.3}  {:>7.3}  {:>7.3}  {:>11.0}",
                    e.epoch,
                    e.total_s,
                    e.rollout_s,
                    e.policy_s,
                    e.value_s,
                    e.other_s,
                    e.steps_per_s
                );
            }
            let later = split.get(1..).unwrap_or_default();
            let med = |f: fn(&apo_cli::bench::EpochSplit) -> f64| {
                apo_cli::bench::median_of(later.iter().map(f))
            };
            println!(
                "median_epochs_2_on: total_s={:.3} rollout_s={:.3} policy_s={:.3} value_s={:.3} other_s={:.3} steps_per_s={:.0}",
                med(|e| e.total_s),
                med(|e| e.rollout_s),
                med(|e| e.policy_s),
                med(|e| e.value_s),
                med(|e| e.other_s),
                med(|e| e.steps_per_s)
            );
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
                apo_envs::mujoco::steps_per_second(e.as_mut(), steps as usize, 0)
            } else {
                let mut envs = apo_envs::vector::VecEnv::make_with(&env, num_envs, &options)?
                    .with_threads(threads)?;
                println!("threads={}", envs.threads());
                apo_envs::mujoco::vector_steps_per_second(&mut envs, steps as usize, 0)
            };
            println!("env={env} steps={steps} num_envs={num_envs} physics={physics}");
            println!("steps_per_sec={rate:.1}");
        }
        BenchCommand::Policy {
            obs,
            act,
            batch,
            calls,
        } => {
            let (obs, act, batch, calls) =
                (obs as usize, act as usize, batch as usize, calls as usize);
            let us = apo_cli::bench::policy_call_us(
                obs,
                apo_core::ActionKind::Continuous { dim: act },
                batch,
                calls,
            );
            println!("obs={obs} act={act} batch={batch}");
            println!("policy_call_us={us:.3}");
        }
    }
    Ok(())
}

fn list() -> anyhow::Result<()> {
    println!(
        "{:<28} {:>8}  {:<14} {:>9}",
        "environment", "obs dim", "actions", "max steps"
    );
    for spec in apo_envs::list() {
        let actions = match &spec.action_space {
            apo_envs::Space::Discrete { n } => format!("discrete({n})"),
            apo_envs::Space::Box { low, .. } => format!("box({})", low.len()),
        };
        println!(
            "{:<28} {:>8}  {:<14} {:>9}",
            spec.name, spec.observation_dim, actions, spec.max_episode_steps
        );
    }
    println!();
    println!("algorithms:");
    let width = algorithm_name_width();
    for algo in Algorithm::ALL {
        println!("  {:<width$} {}", algo.name(), algo.about());
    }
    Ok(())
}

/// The width of the longest algorithm name, to align tables.
fn algorithm_name_width() -> usize {
    Algorithm::ALL
        .iter()
        .map(|a| a.name().len())
        .max()
        .unwrap_or(0)
}

/// The progress bar: environment steps of the whole run, with the epoch, speed, returns and ETA.
struct Bar {
    bar: Option<ProgressBar>,
    epochs: usize,
    epoch: usize,
    started: bool,
    last: String,
}

impl Bar {
    fn new(quiet: bool, config: &RunConfig) -> Self {
        let total = (config.train.steps_per_epoch.div_ceil(config.train.num_envs)
            * config.train.num_envs
            * config.train.epochs) as u64;
        let bar = (!quiet).then(|| {
            let bar = ProgressBar::new(total);
            bar.set_style(
                ProgressStyle::with_template("{bar:30} {human_pos}/{human_len} steps [{elapsed_precise}, ETA {eta_precise}] {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar
        });
        Self {
            bar,
            epochs: config.train.epochs,
            epoch: 0,
            started: false,
            last: String::new(),
        }
    }
}

impl Observer for Bar {
    fn steps(&mut self, env_steps: u64) {
        if let Some(bar) = &self.bar {
            bar.set_position(env_steps);
            if !self.started {
                // a resumed run starts part-way: measure the rate from here
                bar.reset_eta();
                self.started = true;
            }
            bar.set_message(format!(
                "epoch {}/{}{}",
                self.epoch + 1,
                self.epochs,
                self.last
            ));
        }
    }

    fn epoch(&mut self, row: &ProgressRow, epochs: usize) {
        self.epoch = row.epoch;
        self.epochs = epochs;
        let fmt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
        self.last = format!(
            " · {:.0} steps/s · return mean {} min {}",
            row.steps_per_s,
            fmt(row.ep_ret_mean),
            fmt(row.ep_ret_min)
        );
        if let Some(bar) = &self.bar {
            bar.set_position(row.env_steps);
            bar.set_message(format!("epoch {}/{}{}", row.epoch, epochs, self.last));
        }
    }
}

fn init_logging(run_dir: Option<&Path>) -> anyhow::Result<()> {
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    use tracing_subscriber::{fmt, EnvFilter, Layer};
    let file = match run_dir {
        Some(run_dir) => {
            let path = run_dir.join(run_dir::LOG);
            Some(
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(&path)
                    .with_context(|| format!("cannot open {}", path.display()))?,
            )
        }
        None => None,
    };
    let stderr_filter =
        EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("warn"));
    let ansi = std::io::stderr().is_terminal();
    tracing_subscriber::registry()
        .with(file.map(|file| {
            fmt::layer()
                .with_writer(std::sync::Mutex::new(file))
                .with_ansi(false)
                .with_filter(EnvFilter::new("info"))
        }))
        .with(
            fmt::layer()
                .with_writer(std::io::stderr)
                .with_ansi(ansi)
                .with_filter(stderr_filter),
        )
        .try_init()
        .ok();
    Ok(())
}

/// Silences the Wayland client's "XDG_RUNTIME_DIR is invalid or not set" line, which
/// `libwayland-client` prints when the Vulkan driver probes for a display and the variable is
/// unset: apo never draws to a window, so it points the probe at a private, empty directory
/// of its own (`<tmp>/apo-runtime-<uid>`, mode 0700, reused by later runs).
fn quiet_wgpu() {
    #[cfg(unix)]
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
        let Ok(uid) = std::fs::metadata("/proc/self").map(|m| m.uid()) else {
            return;
        };
        let dir = std::env::temp_dir().join(format!("apo-runtime-{uid}"));
        let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
        let private = std::fs::symlink_metadata(&dir)
            .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.permissions().mode() & 0o077 == 0);
        if private {
            // SAFETY: called on the main thread before any other thread is started.
            std::env::set_var("XDG_RUNTIME_DIR", &dir);
        }
    }
}

/// Stop flags raised by SIGINT and SIGTERM: the first raises `stop` (the run checkpoints and
/// ends), a second exits at once with 128 + the signal's number.
struct Signals {
    stop: Arc<AtomicBool>,
    which: Arc<AtomicUsize>,
}

impl Signals {
    fn install() -> anyhow::Result<Self> {
        use signal_hook::consts::{SIGINT, SIGTERM};
        use signal_hook::flag;
        let (stop, which) = (
            Arc::new(AtomicBool::new(false)),
            Arc::new(AtomicUsize::new(0)),
        );
        for signal in [SIGINT, SIGTERM] {
            // registered first, so it sees `stop` as the previous signal left it
            flag::register_conditional_shutdown(signal, 128 + signal, Arc::clone(&stop))
                .and_then(|_| flag::register_usize(signal, Arc::clone(&which), signal as usize))
                .and_then(|_| flag::register(signal, Arc::clone(&stop)))
                .context("installing the signal handlers")?;
        }
        Ok(Self { stop, which })
    }
}

/// `apo train`, as one rank of an MPI job when started by `mpirun` (feature `mpi`). An error
/// on any rank ends the whole job.
#[cfg(feature = "mpi")]
fn train_on_ranks(args: TrainArgs) -> anyhow::Result<ExitCode> {
    let mpi = apo_cli::mpi::Mpi::init()?;
    let comm = mpi.comm();
    let result = train(args, &comm);
    if comm.is_distributed() {
        let traffic = mpi.traffic();
        tracing::info!(
            rank = comm.rank(),
            calls = traffic.calls,
            bytes = traffic.bytes,
            seconds = traffic.seconds,
            "MPI collectives of this rank"
        );
        if comm.rank() == 0 && result.is_ok() {
            println!(
                "MPI: {} ranks; rank 0 made {} collective calls, sent {:.1} MB, spent {:.2} s in them",
                comm.size(),
                traffic.calls,
                traffic.bytes as f64 / 1e6,
                traffic.seconds
            );
        }
        if let Err(e) = &result {
            eprintln!("error (MPI rank {} of {}): {e:#}", comm.rank(), comm.size());
            eprintln!("ending every rank of the job");
            mpi.abort(1);
        }
    }
    result
}

/// `apo train` in one process (built without the `mpi` feature).
#[cfg(not(feature = "mpi"))]
fn train_on_ranks(args: TrainArgs) -> anyhow::Result<ExitCode> {
    train(args, &apo_core::Comm::default())
}

/// `apo train` on rank `comm.rank()`: rank 0 creates (or locks) the run directory and writes
/// in it; the other ranks build the same configuration and only read.
fn train(args: TrainArgs, comm: &apo_core::Comm) -> anyhow::Result<ExitCode> {
    let writer = comm.rank() == 0;
    let mut fresh = None;
    let (config, run_dir, resume, _lock) = match &args.resume {
        Some(dir) => {
            if args.seed.is_some()
                || args.steps_per_epoch.is_some()
                || args.backend.is_some()
                || args.num_envs.is_some()
                || args.checkpoint_every.is_some()
                || !args.sets.is_empty()
            {
                bail!(
                    "--resume continues a run with its own config.toml; only --epochs may change"
                );
            }
            let config_path = dir.join(run_dir::CONFIG);
            let mut config = RunConfig::load(&config_path)
                .with_context(|| format!("{} is not a run directory", dir.display()))?;
            let lock = writer.then(|| RunLock::acquire(dir)).transpose()?;
            let spec = apo_envs::registry::spec(&config.train.env)?;
            if let Some(epochs) = args.epochs {
                config.train.epochs = epochs;
                config.validate()?;
            }
            config.check_memory(
                spec.observation_dim,
                apo_train::action_kind(&spec.action_space),
            )?;
            if args.epochs.is_some() && writer {
                // the new target is part of the run: a later plain --resume continues to it
                apo_cli::atomic::write(&config_path, config.to_toml().as_bytes())
                    .with_context(|| format!("cannot write {}", config_path.display()))?;
            }
            (config, dir.clone(), true, lock)
        }
        None => {
            let from_file = match &args.config {
                Some(path) => apo_cli::config::file_algorithm(path)?,
                None => None,
            };
            let algo = args.algo.or(from_file).with_context(|| {
                format!(
                    "--algo is required ({}), or a --config file with an [algo.<name>] section",
                    algorithm_names()
                )
            })?;
            let env = args
                .env
                .clone()
                .context("--env is required (see `apo list`)")?;
            let spec = apo_envs::registry::spec(&env)?;
            let mut sets = args.sets.clone();
            let flag = |k: &str, v: Option<String>| v.map(|v| format!("{k}={v}"));
            sets.extend(
                [
                    flag("env", Some(format!("{env:?}"))),
                    flag("seed", args.seed.map(|v| v.to_string())),
                    flag("epochs", args.epochs.map(|v| v.to_string())),
                    flag(
                        "steps_per_epoch",
                        args.steps_per_epoch.map(|v| v.to_string()),
                    ),
                    flag("num_envs", args.num_envs.map(|v| v.to_string())),
                    flag(
                        "checkpoint_every",
                        args.checkpoint_every.map(|v| v.to_string()),
                    ),
                    flag("backend", args.backend.map(|b| format!("\"{b}\""))),
                    flag("physics", args.physics.map(|p| format!("\"{p}\""))),
                ]
                .into_iter()
                .flatten(),
            );
            let config = RunConfig::build_with_preset(
                algo,
                &env,
                args.preset,
                args.config.as_deref(),
                &sets,
            )?;
            config.check_memory(
                spec.observation_dim,
                apo_train::action_kind(&spec.action_space),
            )?;
            let dir = args.out.clone().unwrap_or_else(|| {
                PathBuf::from(format!(
                    "runs/{}-{}-s{}",
                    apo_cli::run_dir::env_label(&config.train.env),
                    algo,
                    config.train.seed
                ))
            });
            if !writer {
                // rank 0 prepares the directory and writes its files
                return run_training(&config, &dir, false, args.threads, true, comm);
            }
            let mut prepared = NewRunDir::prepare(&dir, args.force)?;
            let lock = Some(prepared.take_lock().context("the run directory's lock")?);
            let config_path = dir.join(run_dir::CONFIG);
            if let Err(e) = apo_cli::atomic::write(&config_path, config.to_toml().as_bytes()) {
                prepared.discard();
                return Err(e).with_context(|| format!("cannot write {}", config_path.display()));
            }
            fresh = Some(prepared);
            (config, dir, false, lock)
        }
    };
    let quiet = args.quiet || !writer;
    let result = run_training(&config, &run_dir, resume, args.threads, quiet, comm);
    if result.is_err() && !run_dir.join(run_dir::PROGRESS).exists() {
        // a new run that failed before its first epoch leaves nothing behind
        if let Some(prepared) = fresh {
            prepared.discard();
        }
    }
    result
}

fn run_training(
    config: &RunConfig,
    run_dir: &Path,
    resume: bool,
    threads: usize,
    quiet: bool,
    comm: &apo_core::Comm,
) -> anyhow::Result<ExitCode> {
    // the run's log is rank 0's; the other ranks log to stderr only
    init_logging((comm.rank() == 0).then_some(run_dir))?;
    let signals = Signals::install()?;
    let mut bar = Bar::new(quiet, config);
    let launch = trainer::Launch {
        resume,
        threads,
        comm: comm.clone(),
    };
    let end = match config.backend {
        BackendKind::Cpu => trainer::train::<burn::backend::NdArray>(
            config,
            run_dir,
            &Default::default(),
            &launch,
            &signals.stop,
            &mut bar,
        ),
        BackendKind::Wgpu => {
            quiet_wgpu();
            trainer::train::<burn::backend::Wgpu>(
                config,
                run_dir,
                &Default::default(),
                &launch,
                &signals.stop,
                &mut bar,
            )
        }
    };
    if let Some(bar) = &bar.bar {
        bar.abandon();
    }
    match end? {
        TrainEnd::Finished => {
            if comm.rank() == 0 {
                println!("run finished: {}", run_dir.display());
            }
            Ok(ExitCode::SUCCESS)
        }
        TrainEnd::Interrupted { epoch } => {
            let signal = signals.which.load(Ordering::SeqCst);
            let name = match signal {
                s if s == signal_hook::consts::SIGTERM as usize => "SIGTERM",
                _ => "SIGINT",
            };
            if comm.rank() == 0 {
                let launcher = if comm.is_distributed() {
                    format!("mpirun -n {} ", comm.size())
                } else {
                    String::new()
                };
                println!(
                    "interrupted by {name} after epoch {epoch} of {}; checkpoint written. Continue with: {launcher}apo train --resume {}",
                    config.train.epochs,
                    run_dir.display()
                );
            }
            Ok(ExitCode::from(interrupted_status(signal)))
        }
    }
}
