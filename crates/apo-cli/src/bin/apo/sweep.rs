//! `apo sweep`: a grid × seeds × algorithms × environments, each a child `apo train`.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::Ordering;

use anyhow::Context;
use apo_cli::sweep;
use apo_core::Algorithm;
use apo_train::run_config::Preset;
use indicatif::{ProgressBar, ProgressStyle};

use crate::signals::{interrupted_status, SweepSignals};

#[derive(clap::Args)]
pub struct SweepArgs {
    /// Algorithms, comma-separated (e.g. apo,trpo); each once.
    #[arg(long, value_delimiter = ',', required = true)]
    algo: Vec<String>,
    /// Environments, comma-separated; each once.
    #[arg(long, value_delimiter = ',', required = true)]
    env: Vec<String>,
    /// Seeds: a list (0,1,2) or a range (0..5, end excluded); each once.
    #[arg(long, default_value = "0..3")]
    seeds: String,
    /// A grid axis, key=v1,v2,… (repeatable, one per key; axes multiply). Values are TOML, so
    /// lists work: hidden=[32,32],[64,64]. An axis applies to the algorithms that have the
    /// key. The keys the sweep sets itself (env, seed, epochs, steps_per_epoch) are refused.
    #[arg(long = "grid", value_name = "KEY=V1,V2,…")]
    grid: Vec<String>,
    /// The sweep's directory (runs are <env>-<algo>[-<key>=<value>…]-s<seed> inside it).
    #[arg(long)]
    out: PathBuf,
    /// Epochs of every run; 1..=1000000000.
    #[arg(long, default_value_t = 200, value_parser = apo_cli::flags::count::<u64>(1, apo_train::config::MAX_EPOCHS as u64))]
    epochs: u64,
    /// Environment steps per epoch of every run [default: the config's]; 1..=100000000.
    #[arg(long, value_parser = apo_cli::flags::count::<usize>(1, apo_train::config::MAX_STEPS_PER_EPOCH as u64))]
    steps_per_epoch: Option<usize>,
    /// Preset of every run.
    #[arg(long, value_enum)]
    preset: Option<Preset>,
    /// Config file of every run. A file with an algorithm section ([algo.<name>]) is for a
    /// sweep of that algorithm only; for several algorithms, give a file without one.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Override a config key in every run (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Runs at once; 1..=256.
    #[arg(long, default_value_t = 1, value_parser = apo_cli::flags::count::<usize>(1, 256))]
    jobs: usize,
    /// Threads of each run (0: the cores available divided by --jobs); 0..=1024.
    #[arg(long, default_value_t = 0, value_parser = apo_cli::flags::count::<usize>(0, 1024))]
    threads: usize,
    /// Metric that ranks the cells.
    #[arg(long, value_enum, default_value_t = sweep::Metric::WorstLast)]
    metric: sweep::Metric,
    /// N of "the last N epochs"; 1..=1000000000.
    #[arg(long, default_value_t = 20, value_parser = apo_cli::flags::count::<u64>(1, 1_000_000_000))]
    last: u64,
    /// The most runs the sweep may have (counted before anything starts).
    #[arg(long, default_value_t = sweep::DEFAULT_MAX_RUNS, value_parser = clap::value_parser!(u64).range(1..))]
    max_runs: u64,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

pub fn run(args: SweepArgs) -> anyhow::Result<ExitCode> {
    let spec = sweep::SweepSpec {
        envs: args.env.clone(),
        algos: args.algo.clone(),
        seeds: sweep::parse_seeds(&args.seeds, args.max_runs)?,
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
        config_text: sweep::SweepSpec::config_text_of(args.config.as_deref())?,
        sets: {
            apo_train::run_config::check_repeated_sets(&args.sets)?;
            args.sets.clone()
        },
        steps_per_epoch: args.steps_per_epoch,
    };
    let epochs = args.epochs as usize;
    let runs = sweep::expand(&spec, epochs, args.max_runs)?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let options = sweep::SweepOptions {
        out: args.out.clone(),
        epochs,
        jobs: args.jobs,
        threads: if args.threads == 0 {
            (cores / args.jobs).max(1)
        } else {
            args.threads
        },
    };
    let exe = std::env::current_exe().context("locating the apo executable")?;
    let signals = SweepSignals::install()?;
    let total = (runs.len() as u64).saturating_mul(args.epochs);
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
    apo_cli::outln!(
        "sweep: {} runs ({} environments, {} algorithms, {} seeds) in {}",
        runs.len(),
        spec.envs.len(),
        spec.algos.len(),
        spec.seeds.len(),
        args.out.display()
    )?;
    let outcome = sweep::run(&exe, &spec, &runs, &options, &signals.received, &mut tick)?;
    if let Some(bar) = &bar {
        bar.abandon();
    }
    let results = sweep::cell_results(&args.out, &runs, epochs, args.metric, args.last as usize);
    let csv = sweep::cells_csv(&results);
    let csv_path = args.out.join("cells.csv");
    apo_train::atomic::write(&csv_path, csv.as_bytes())
        .with_context(|| format!("cannot write {}", csv_path.display()))?;
    let metric = clap::ValueEnum::to_possible_value(&args.metric)
        .map(|v| v.get_name().to_string())
        .unwrap_or_default();
    apo_cli::outln!(
        "{metric} (last {}), mean ± std over finished seeds; best cell first:",
        args.last
    )?;
    let mut previous: Option<(&str, Algorithm)> = None;
    let width = crate::algorithm_name_width();
    for r in &results {
        let best = r.mean.is_some() && previous != Some((r.env.as_str(), r.algo));
        if r.mean.is_some() {
            previous = Some((r.env.as_str(), r.algo));
        }
        let mut apart = Vec::new();
        for (n, what) in [
            (r.incomplete, "incomplete"),
            (r.other_target, "of another epoch target"),
            (r.unreadable, "without readable records"),
        ] {
            if n > 0 {
                apart.push(format!("{n} {what}"));
            }
        }
        let apart = if apart.is_empty() {
            String::new()
        } else {
            format!(", left out: {}", apart.join(", "))
        };
        let value = match (r.mean, r.std) {
            (Some(mean), Some(std)) => format!("{mean:>10.2} ± {std:<8.2}"),
            _ => format!("{:>10} ± {:<8}", "-", "-"),
        };
        apo_cli::outln!(
            "{} {:<12} {:<width$} {:<40} {value} ({} seeds{apart})",
            if best { "*" } else { " " },
            r.env,
            r.algo.name(),
            r.cell,
            r.seeds
        )?;
    }
    apo_cli::outln!(
        "finished {} (skipped {} finished before), failed {}; cells: {}",
        outcome.finished,
        outcome.skipped,
        outcome.failed.len(),
        csv_path.display()
    )?;
    for (name, error) in &outcome.failed {
        apo_train::warnln!("failed: {name}: {error}");
    }
    if outcome.interrupted {
        apo_cli::outln!(
            "interrupted: every running run was checkpointed; run the same command again to resume"
        )?;
        return Ok(ExitCode::from(interrupted_status(
            signals.received.which.load(Ordering::SeqCst),
        )));
    }
    Ok(if outcome.failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
