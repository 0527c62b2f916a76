//! `apo sweep`: a grid × seeds × algorithms × environments, each a child `apo train`.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;
use apo_cli::sweep;
use apo_core::Algorithm;
use apo_train::run_config::Preset;
use indicatif::{ProgressBar, ProgressStyle};

use crate::signals::{interrupted_status, SweepSignals};

#[derive(clap::Args)]
pub struct SweepArgs {
    /// Algorithms, comma-separated (e.g. apo,trpo); each once.
    #[arg(long, value_delimiter = ',', required_unless_present = "status")]
    algo: Vec<String>,
    /// Environments, comma-separated; each once.
    #[arg(long, value_delimiter = ',', required_unless_present = "status")]
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
    /// Epochs of every run [default: 200; with --status: the target of the latest submission
    /// to Slurm, else the largest of the runs' config.toml]; 1..=1000000000.
    #[arg(long, value_parser = apo_cli::flags::count::<u64>(1, apo_train::config::MAX_EPOCHS as u64))]
    epochs: Option<u64>,
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
    /// Runs at once [default: 1; with --launcher slurm: as many as Slurm allows]; 1..=10000.
    #[arg(long, value_parser = apo_cli::flags::count::<usize>(1, 10_000))]
    jobs: Option<usize>,
    /// Threads of each run (0: the cores available divided by --jobs; with --launcher slurm:
    /// 1), also each Slurm task's --cpus-per-task; 0..=1024.
    #[arg(long, default_value_t = 0, value_parser = apo_cli::flags::count::<usize>(0, 1024))]
    threads: usize,
    /// Where the runs run: `local` (children of this command, --jobs at once) or `slurm` (one
    /// job array submitted with sbatch, one task per run not finished, queued or running;
    /// the command returns once it is submitted: docs/cluster.md).
    #[arg(long, value_enum, default_value_t = Launcher::Local)]
    launcher: Launcher,
    /// An sbatch option for --launcher slurm, e.g. --sbatch=--partition=gpu
    /// --sbatch=--time=04:00:00 (repeatable; given after apo's own, so it wins).
    #[arg(long = "sbatch", value_name = "OPTION", allow_hyphen_values = true)]
    sbatch: Vec<String>,
    /// With --launcher slurm: seconds before a task's time limit at which Slurm warns it
    /// (SIGUSR1): its run checkpoints and the task requeues itself; 10..=86400.
    #[arg(long, default_value_t = 300, value_parser = apo_cli::flags::count::<u64>(10, 86_400))]
    slurm_warn: u64,
    /// Print where each run of the sweep in --out stands (finished, running, queued,
    /// interrupted, failed with its reason, not started) and what a new submission would
    /// launch; the runs are the ones the sweep recorded (sweep.toml), their target --epochs
    /// (default: the latest Slurm submission's).
    #[arg(long, conflicts_with_all = ["grid", "sets", "config", "preset", "steps_per_epoch", "seeds", "sbatch"])]
    status: bool,
    /// Metric that ranks the cells.
    #[arg(long, value_enum, default_value_t = sweep::Metric::WorstLast)]
    metric: sweep::Metric,
    /// N of "the last N epochs"; 1..=1000000000.
    #[arg(long, default_value_t = 20, value_parser = apo_cli::flags::count::<u64>(1, 1_000_000_000))]
    last: u64,
    /// The most runs the sweep may have (counted before anything starts); 1..=1000000.
    #[arg(long, default_value_t = sweep::DEFAULT_MAX_RUNS, value_parser = apo_cli::flags::count::<u64>(1, sweep::MAX_RUNS))]
    max_runs: u64,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Epochs of every run when `--epochs` is not given (the paper's).
const DEFAULT_EPOCHS: usize = 200;

/// Where a sweep's runs run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Launcher {
    /// Children of `apo sweep` on this machine.
    Local,
    /// A Slurm job array.
    Slurm,
}

#[derive(clap::Args)]
pub struct SweepTaskArgs {
    /// The sweep's directory.
    #[arg(long)]
    out: PathBuf,
    /// The run this task trains.
    #[arg(long)]
    run: String,
    /// Its epoch target; 1..=1000000000.
    #[arg(long, value_parser = apo_cli::flags::count::<u64>(1, apo_train::config::MAX_EPOCHS as u64))]
    epochs: u64,
    /// Its threads; 1..=1024.
    #[arg(long, value_parser = apo_cli::flags::count::<usize>(1, 1024))]
    threads: usize,
}

/// `apo sweep-task`: one array task of a Slurm sweep.
pub fn task(args: &SweepTaskArgs) -> anyhow::Result<ExitCode> {
    let signals = SweepSignals::install()?;
    let warned = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGUSR1, Arc::clone(&warned))
        .context("installing the SIGUSR1 handler")?;
    let exe = std::env::current_exe().context("locating the apo executable")?;
    let end = apo_cli::slurm::task(
        &exe,
        &args.out,
        &args.run,
        args.epochs as usize,
        args.threads,
        &signals.received,
        &warned,
    )?;
    Ok(match end.status {
        None => ExitCode::SUCCESS,
        Some(_) if end.requeued => ExitCode::SUCCESS,
        Some(status) => match status.code() {
            Some(0) => ExitCode::SUCCESS,
            Some(code) => ExitCode::from(u8::try_from(code).unwrap_or(1)),
            None => ExitCode::FAILURE,
        },
    })
}

/// `apo sweep --status`: where each run of the sweep in `--out` stands.
fn status(args: &SweepArgs) -> anyhow::Result<ExitCode> {
    let spec = sweep::read_record(&args.out)?;
    let submitted = apo_cli::slurm::submissions(&args.out)?;
    let named = match (args.epochs, submitted.last()) {
        (Some(e), _) => Some((e as usize, "--epochs")),
        (None, Some(s)) => Some((s.epochs, "the latest submission's")),
        (None, None) => None,
    };
    let runs = sweep::expand(
        &spec,
        named.map_or(DEFAULT_EPOCHS, |(e, _)| e),
        args.max_runs,
    )?;
    // a local sweep records no target: its runs' own
    let (epochs, from) = match named {
        Some(found) => found,
        None => runs
            .iter()
            .filter_map(|r| {
                apo_train::run_config::RunConfig::load(&args.out.join(&r.name).join("config.toml"))
                    .ok()
                    .map(|c| c.train.epochs)
            })
            .max()
            .map(|e| (e, "the runs' config.toml"))
            .with_context(|| {
                format!(
                    "no run of {} has started and no submission records the target: pass --epochs",
                    args.out.display()
                )
            })?,
    };
    apo_cli::outln!("target: {epochs} epochs ({from})")?;
    let standings = apo_cli::slurm::standings(&args.out, &runs, epochs)?;
    let width = standings.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
    let mut launch = Vec::new();
    for (name, standing) in &standings {
        use apo_cli::slurm::Standing as S;
        let said = match standing {
            S::Finished => format!("finished ({epochs} epochs)"),
            S::Running { id } => format!("running (task {id})"),
            S::Training { holder } if holder.is_empty() => {
                "training (its run is locked)".to_string()
            }
            S::Training { holder } => format!("training ({holder} holds its lock)"),
            S::Queued { id, reason } if reason == "None" || reason.is_empty() => {
                format!("queued (task {id})")
            }
            S::Queued { id, reason } => format!("queued (task {id}, {reason})"),
            S::Interrupted { done } => format!("interrupted at epoch {done} of {epochs}"),
            S::Failed { reason } => format!("failed: {reason}"),
            S::New => "not started".to_string(),
            S::Blocked { reason } => format!("blocked: {reason}"),
        };
        if standing.would_launch() {
            launch.push(name.as_str());
        }
        apo_cli::outln!("{name:<width$}  {said}")?;
    }
    let failed = standings
        .iter()
        .filter(|(_, s)| matches!(s, apo_cli::slurm::Standing::Failed { .. }))
        .count();
    if launch.is_empty() {
        apo_cli::outln!("a new submission would launch nothing")?;
    } else {
        apo_cli::outln!(
            "a new submission would launch {} run(s): {}",
            launch.len(),
            launch.join(", ")
        )?;
    }
    if failed > 0 {
        apo_cli::outln!(
            "{failed} run(s) failed: mend what their error says before submitting again (each task's \
             output is in {})",
            args.out.join(apo_cli::slurm::FOLDER).display()
        )?;
    }
    Ok(ExitCode::SUCCESS)
}

pub fn run(args: SweepArgs) -> anyhow::Result<ExitCode> {
    if args.status {
        return status(&args);
    }
    if args.launcher == Launcher::Local && !args.sbatch.is_empty() {
        anyhow::bail!("--sbatch is for --launcher slurm");
    }
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
    let epochs = args.epochs.map_or(DEFAULT_EPOCHS, |e| e as usize);
    let runs = sweep::expand(&spec, epochs, args.max_runs)?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let jobs = args.jobs.unwrap_or(1);
    let options = sweep::SweepOptions {
        out: args.out.clone(),
        epochs,
        jobs,
        threads: match (args.threads, args.launcher) {
            (0, Launcher::Slurm) => 1,
            (0, Launcher::Local) => (cores / jobs).max(1),
            (threads, _) => threads,
        },
    };
    let exe = std::env::current_exe().context("locating the apo executable")?;
    if args.launcher == Launcher::Slurm {
        let slurm = apo_cli::slurm::SlurmOptions {
            sbatch: args.sbatch.clone(),
            warn_s: args.slurm_warn,
            limit: args.jobs,
        };
        let outcome = apo_cli::slurm::submit(&exe, &spec, &runs, &options, &slurm)?;
        apo_cli::outln!(
            "sweep: {} runs in {}: {} finished, {} queued or running",
            runs.len(),
            args.out.display(),
            outcome.finished,
            outcome.in_queue
        )?;
        match &outcome.job {
            Some(job) => apo_cli::outln!(
                "submitted job {job}: {} run(s), one array task each; follow it with `squeue -j {job}` and \
                 `apo sweep --status --out {}`; run this command again to resubmit what is unfinished",
                outcome.submitted.len(),
                args.out.display()
            )?,
            None => apo_cli::outln!("nothing to submit")?,
        }
        if outcome.job.is_some() || outcome.in_queue > 0 {
            return Ok(ExitCode::SUCCESS);
        }
        // every run finished: the cells, as a local sweep ends
        let all_finished = sweep::SweepOutcome {
            skipped: outcome.finished,
            ..Default::default()
        };
        return cells(&args, &runs, epochs, &all_finished).map(|()| ExitCode::SUCCESS);
    }
    let signals = SweepSignals::install()?;
    let total = (runs.len() as u64).saturating_mul(epochs as u64);
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
    cells(&args, &runs, epochs, &outcome)?;
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

/// Writes `cells.csv` and prints each cell's metric over its seeds, then what `outcome` did.
fn cells(
    args: &SweepArgs,
    runs: &[sweep::SweepRun],
    epochs: usize,
    outcome: &sweep::SweepOutcome,
) -> anyhow::Result<()> {
    let results = sweep::cell_results(&args.out, runs, epochs, args.metric, args.last as usize);
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
    Ok(())
}
