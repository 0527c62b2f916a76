//! `apo train`: a new run, or `--resume` of one, on one process or as a rank of an MPI job.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::Ordering;

use anyhow::Context;
use apo_core::Algorithm;
use apo_envs::mujoco::Physics;
use apo_train::backend::BackendKind;
use apo_train::progress_csv::ProgressRow;
use apo_train::run::Launch;
use apo_train::run_config::{Preset, RunConfig};
use apo_train::run_dir;
use apo_train::AnyRun;
use indicatif::{ProgressBar, ProgressStyle};

use crate::signals::{interrupted_status, Signals, STOP_GRACE};

#[derive(clap::Args)]
pub struct TrainArgs {
    /// Algorithm [default with --config: the file's section [algo.<name>]].
    #[arg(long, value_parser = crate::parse_algo)]
    algo: Option<Algorithm>,
    /// Environment name (see `apo list`) [default with --config: the file's env].
    #[arg(long)]
    env: Option<String>,
    /// Backend of the updates [config: backend; default cpu].
    #[arg(long, value_enum)]
    backend: Option<BackendKind>,
    /// Physics of MuJoCo environments, mujoco2 or mujoco3 (builds with the `mujoco3` feature)
    /// [config: physics; default mujoco2].
    #[arg(long, value_parser = crate::parse_physics)]
    physics: Option<Physics>,
    /// TOML config file (keys as in a run's config.toml or `apo config`; defaults fill the rest).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Settings layered over the defaults and --config, under --set: `paper` reproduces the
    /// paper's published code (`apo config --preset paper` shows them).
    #[arg(long, value_enum)]
    preset: Option<Preset>,
    /// Seed [config: seed; default 0; 0..=9223372036854775807].
    #[arg(long, value_parser = apo_cli::flags::count::<u64>(0, i64::MAX as u64))]
    seed: Option<u64>,
    /// Number of epochs [config: epochs; default 200]; with --resume, the run's new target; 1..=1000000000.
    #[arg(long, value_parser = apo_cli::flags::count::<usize>(1, apo_train::config::MAX_EPOCHS as u64))]
    epochs: Option<usize>,
    /// Environment steps per epoch [config: steps_per_epoch; default 30000]; 1..=100000000.
    #[arg(long, value_parser = apo_cli::flags::count::<usize>(1, apo_train::config::MAX_STEPS_PER_EPOCH as u64))]
    steps_per_epoch: Option<usize>,
    /// Environments stepped together [config: num_envs; default 1]; 1..=65536.
    #[arg(long, value_parser = apo_cli::flags::count::<usize>(1, apo_train::config::MAX_NUM_ENVS as u64))]
    num_envs: Option<usize>,
    /// Threads that step the environments (0: the cores available); results do not depend
    /// on it, so it may change on --resume; 0..=1024.
    #[arg(long, default_value_t = 0, value_parser = apo_cli::flags::count::<usize>(0, 1024))]
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
    /// Continue the run in this directory from its last checkpoint with its own config.toml
    /// (--epochs may extend it; the flags that would change what it learns are refused).
    #[arg(long, value_name = "DIR", conflicts_with_all = [
        "algo", "env", "config", "preset", "out", "force", "seed", "steps_per_epoch", "num_envs",
        "checkpoint_every", "backend", "physics", "sets",
    ])]
    resume: Option<PathBuf>,
    /// Replace an existing run directory that apo made, removing only the files apo created
    /// in it (anything else in it is kept).
    #[arg(long)]
    force: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

impl TrainArgs {
    /// The dedicated flags given, as `(config key, flag, value in TOML)`.
    fn flags(&self, env: &str) -> Vec<(&'static str, &'static str, String)> {
        let mut flags = vec![("env", "--env", format!("{env:?}"))];
        let mut add = |key, flag, value: Option<String>| {
            if let Some(v) = value {
                flags.push((key, flag, v));
            }
        };
        add("seed", "--seed", self.seed.map(|v| v.to_string()));
        add("epochs", "--epochs", self.epochs.map(|v| v.to_string()));
        add(
            "steps_per_epoch",
            "--steps-per-epoch",
            self.steps_per_epoch.map(|v| v.to_string()),
        );
        add(
            "num_envs",
            "--num-envs",
            self.num_envs.map(|v| v.to_string()),
        );
        add(
            "checkpoint_every",
            "--checkpoint-every",
            self.checkpoint_every.map(|v| v.to_string()),
        );
        add(
            "backend",
            "--backend",
            self.backend.map(|b| format!("\"{b}\"")),
        );
        add(
            "physics",
            "--physics",
            self.physics.map(|p| format!("\"{p}\"")),
        );
        flags
    }
}

/// Warns when a flag overrides a different value given for the same key by `--set` or the
/// `--config` file (the flag wins; the warning says which value was dropped).
fn warn_overridden(flags: &[(&str, &str, String)], sets: &[String], file: Option<&Path>) {
    let file_table = file.and_then(|p| {
        apo_train::input::read_text(p, "config file", apo_train::input::SMALL_FILE)
            .ok()?
            .parse::<toml::Table>()
            .ok()
    });
    for (key, flag, value) in flags {
        let flagged = apo_train::run_config::parse_value(value);
        for set in sets {
            if let Some((k, v)) = set.split_once('=') {
                if k.trim() == *key && apo_train::run_config::parse_value(v.trim()) != flagged {
                    apo_train::warnln!("warning: {flag} {value} overrides --set {set}");
                }
            }
        }
        if let (Some(table), Some(path)) = (&file_table, file) {
            if let Some(v) = table.get(*key).filter(|v| Ok(*v) != flagged.as_ref()) {
                apo_train::warnln!(
                    "warning: {flag} {value} overrides {key} = {v} of --config {}",
                    path.display()
                );
            }
        }
    }
}

/// `apo train`, as one rank of an MPI job when started by `mpirun` (feature `mpi`). An error
/// on any rank ends the whole job.
#[cfg(feature = "mpi")]
pub fn train_on_ranks(args: TrainArgs) -> anyhow::Result<ExitCode> {
    let mpi = apo_train::mpi::Mpi::init()?;
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
            apo_cli::outln!(
                "MPI: {} ranks; rank 0 made {} collective calls, sent {:.1} MB, spent {:.2} s in them",
                comm.size(),
                traffic.calls,
                traffic.bytes as f64 / 1e6,
                traffic.seconds
            )?;
        }
        if let Err(e) = &result {
            apo_train::warnln!("error (MPI rank {} of {}): {e:#}", comm.rank(), comm.size());
            apo_train::warnln!("ending every rank of the job");
            mpi.abort(1);
        }
    }
    result
}

/// `apo train` in one process (built without the `mpi` feature).
#[cfg(not(feature = "mpi"))]
pub fn train_on_ranks(args: TrainArgs) -> anyhow::Result<ExitCode> {
    train(args, &apo_core::Comm::default())
}

/// `apo train` on rank `comm.rank()`: rank 0 creates (or locks) the run directory and writes
/// in it; the other ranks build the same configuration and only read.
fn train(args: TrainArgs, comm: &apo_core::Comm) -> anyhow::Result<ExitCode> {
    let launch = Launch {
        threads: args.threads,
        comm: comm.clone(),
    };
    let quiet = args.quiet || comm.rank() != 0;
    let signals = Signals::install()?;
    let (backend, create) = match &args.resume {
        Some(dir) => {
            let config = run_dir::check_resumable(dir)?;
            // before the log opens: a resume never fails half-way on an entry it cannot write
            if comm.rank() == 0 {
                run_dir::check_own_places(dir)?;
            }
            // the run's log is rank 0's; the other ranks log to stderr only
            init_logging((comm.rank() == 0).then_some(dir.as_path()))?;
            (config.backend, None)
        }
        None => {
            let from_file = match &args.config {
                Some(path) => apo_train::run_config::file_algorithm(path)?,
                None => None,
            };
            let algo = args.algo.or(from_file).with_context(|| {
                format!(
                    "--algo is required ({}), or a --config file with an [algo.<name>] section",
                    crate::algorithm_names()
                )
            })?;
            let file_env = match (&args.env, &args.config) {
                (None, Some(path)) => apo_train::run_config::file_env(path)?,
                _ => None,
            };
            let env = args.env.clone().or(file_env).context(
                "--env is required (see `apo list`), or a --config file with an env key",
            )?;
            apo_envs::registry::spec(&env)?;
            apo_train::run_config::check_repeated_sets(&args.sets)?;
            let flags = args.flags(&env);
            warn_overridden(&flags, &args.sets, args.config.as_deref());
            let mut sets = args.sets.clone();
            sets.extend(flags.iter().map(|(k, _, v)| format!("{k}={v}")));
            let config = RunConfig::build_with_preset(
                algo,
                &env,
                args.preset,
                args.config.as_deref(),
                &sets,
            )?;
            let dir = args.out.clone().unwrap_or_else(|| {
                PathBuf::from(format!(
                    "runs/{}-{}-s{}",
                    run_dir::env_label(&config.train.env),
                    algo,
                    config.train.seed
                ))
            });
            (config.backend, Some((config, dir)))
        }
    };
    Open {
        args: &args,
        create,
        launch: &launch,
        signals: &signals,
        quiet,
    }
    .train(backend)
}

/// A run to create (its config and directory) or to resume (`--resume`), trained on a backend.
struct Open<'a> {
    args: &'a TrainArgs,
    create: Option<(RunConfig, PathBuf)>,
    launch: &'a Launch,
    signals: &'a Signals,
    quiet: bool,
}

impl Open<'_> {
    /// Creates or resumes the run on `backend` and trains it to its target.
    fn train(self, backend: BackendKind) -> anyhow::Result<ExitCode> {
        let comm = &self.launch.comm;
        let dir = match (&self.create, &self.args.resume) {
            (Some((_, dir)), _) | (None, Some(dir)) => dir.clone(),
            (None, None) => anyhow::bail!("neither a new run nor --resume"),
        };
        let _deadline = self.signals.deadline(
            STOP_GRACE,
            Box::new(move || {
                let kept = match apo_train::checkpoint::latest_epoch(&dir) {
                    Ok(Some(epoch)) if epoch > 0 => format!(
                        "the run keeps its checkpoint of epoch {epoch}; continue it with `apo train --resume {}`",
                        dir.display()
                    ),
                    _ => format!(
                        "no epoch had completed, so there is nothing to resume; start again with `--force --out {}`",
                        dir.display()
                    ),
                };
                format!(
                    "apo: the epoch did not end within {} s of the signal, so the run stopped now; {kept}",
                    STOP_GRACE.as_secs()
                )
            }),
        );
        let mut run = match self.create {
            Some((config, dir)) => {
                let run = AnyRun::create(&dir, config, self.launch, self.args.force)?;
                init_logging((comm.rank() == 0).then_some(dir.as_path()))?;
                run
            }
            None => {
                let dir = self.args.resume.as_deref().context("--resume")?;
                AnyRun::resume(backend, dir, self.launch, self.args.epochs)?
            }
        };
        let mut bar = Bar::new(self.quiet, run.config());
        let epochs = run.config().train.epochs;
        loop {
            let row = run.epoch(&self.signals.stop, &mut |steps| bar.steps(steps));
            match row {
                Ok(Some(row)) => bar.epoch(&row, epochs),
                Ok(None) => break,
                Err(e) => {
                    bar.abandon();
                    return Err(e);
                }
            }
        }
        bar.abandon();
        let run_dir = run.dir();
        if !run.interrupted() {
            if comm.rank() == 0 {
                apo_cli::outln!("run finished: {}", run_dir.display())?;
            }
            return Ok(ExitCode::SUCCESS);
        }
        let signal = self.signals.which.load(Ordering::SeqCst);
        let name = crate::signals::signal_name(signal);
        if comm.rank() == 0 {
            let launcher = if comm.is_distributed() {
                format!("mpirun -n {} ", comm.size())
            } else {
                String::new()
            };
            apo_cli::outln!(
                "interrupted by {name} after epoch {} of {epochs}; checkpoint written. Continue with: {launcher}apo train --resume {}",
                run.epochs_done(),
                run_dir.display()
            )?;
        }
        Ok(ExitCode::from(interrupted_status(signal)))
    }
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
        let total = (config.train.steps_per_epoch.div_ceil(config.train.num_envs) as u64)
            .saturating_mul(config.train.num_envs as u64)
            .saturating_mul(config.train.epochs as u64);
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

impl Bar {
    fn abandon(&self) {
        if let Some(bar) = &self.bar {
            bar.abandon();
        }
    }

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
                run_dir::open_own(std::fs::OpenOptions::new().create(true).append(true), &path)
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
