//! `apo`: train, evaluate, plot, report, sweep and benchmark APO, PAPO and the baselines.
//!
//! One module per subcommand, each owning its arguments; what they share — how user files
//! are read and output paths checked (`apo_train::input`), run-directory ownership
//! (`apo_train::run_dir`), signals (`signals`) — lives in one place.

use std::process::ExitCode;

use apo_core::Algorithm;
use apo_envs::mujoco::Physics;
use clap::{Parser, Subcommand};

mod bench;
mod config;
mod eval;
mod list;
mod plot;
mod render;
mod report;
mod signals;
mod stats;
mod summary;
mod sweep;
mod train;

const TRAIN_HELP: &str = "Defaults are the paper's (configs/<algo>.toml spells them out). Every config key with its \
meaning, default and range: `apo config --algo <ALGO>`; set any key with --set key=value or a --config file.

Example:
  apo train --algo apo --env Hopper --epochs 100 --out runs/hopper-apo
  apo train --config configs/guard/papo.toml --env Goal_Point --preset robust --out runs/gp";

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
    #[command(after_help = TRAIN_HELP)]
    Train(train::TrainArgs),
    /// Evaluate a run's policy: prints the mean, std, min and max return.
    #[command(
        after_help = "Example:\n  apo eval --run runs/hopper-apo --episodes 20 --deterministic"
    )]
    Eval(eval::EvalArgs),
    /// Record a video of a run's policy (GIF, or MP4 with ffmpeg): the episodes `apo eval`
    /// plays with the same seed, with step, reward and return written on each frame. MuJoCo
    /// tasks render headless through EGL or OSMesa (`APO_GL=egl|osmesa`).
    #[command(
        after_help = "Example:\n  apo render --run runs/hopper-apo --episodes 1 --out hopper.gif"
    )]
    Render(render::RenderArgs),
    /// Print the effective config with every key's meaning and range (TOML; usable as --config).
    #[command(
        after_help = "Example:\n  apo config --algo papo --env Goal_Point --preset robust > papo.toml"
    )]
    Config(config::ConfigArgs),
    /// List environments and algorithms.
    #[command(after_help = "Example:\n  apo list")]
    List,
    /// Plot learning curves of runs (mean return, min–max band, worst return).
    #[command(
        after_help = "Example:\n  apo plot runs/hopper-apo runs/hopper-trpo --smooth 5 --out hopper.png"
    )]
    Plot(plot::PlotArgs),
    /// The APO paper's Theorem 1 checked exactly on random tabular MDPs: (a) the surrogate
    /// M_k^j(π) ≤ B_k(π) = J − k·V, (b) equality at π_j, (c) B_k along exact APO iterations and
    /// along the practical trust-region surrogate, (d) Selberg's confidence (docs/theory.md).
    #[command(after_help = "Example:\n  apo theory")]
    Theory(apo_cli::theory::TheoryArgs),
    /// The paper's metrics of runs: average mean and worst return over all and the last N epochs.
    #[command(after_help = "Example:\n  apo summary runs/hopper-apo runs/hopper-trpo --last 20")]
    Summary(summary::SummaryArgs),
    /// The paper's metrics per environment and algorithm, mean ± std over seeds: average mean
    /// and worst return over all and the last N epochs, the bound and its confidence, the
    /// TRPO-normalized scores, the count of "best" per metric; then statistics over
    /// environments and runs of every metric (the paper's four, CVaR 10 %, 10 % quantile):
    /// mean, median, IQM, optimality gap with stratified-bootstrap 95 % intervals, the
    /// probability of improvement of each pair, performance profiles. Markdown on stdout, and
    /// with --out also report.md, report.csv, statistics.json, learning curves (mean ± std over
    /// seeds), and profile-<metric> and intervals-<metric> figures (PNG and SVG).
    #[command(
        after_help = "Example:\n  apo report runs/campaign --last 20 --out reports/campaign"
    )]
    Report(report::ReportArgs),
    /// Statistics of a score file (`algorithm,task,score` per run) as rliable computes them:
    /// mean, median, interquartile mean and optimality gap with stratified-bootstrap 95 %
    /// intervals, the probability of improvement of each pair, performance profiles.
    #[command(after_help = "Example:\n  apo stats scores.csv --reps 2000")]
    Stats(stats::StatsArgs),
    /// Run a grid of config values × seeds × algorithms × environments, each a separate run
    /// under one directory, several at once; run it again to resume (finished runs are
    /// skipped, interrupted ones resumed). Ends with each cell's metric over its seeds.
    /// SIGINT/SIGTERM are passed on to the running runs, which checkpoint; the sweep waits for them.
    #[command(
        after_help = "Example:\n  apo sweep --algo apo,trpo --env Hopper --seeds 0,1,2,3,4 --grid algo.omega1=0.001,0.01 --jobs 2 --out runs/sweep"
    )]
    Sweep(sweep::SweepArgs),
    /// One array task of a sweep submitted with `apo sweep --launcher slurm` (run by the job's
    /// script, not by hand): trains its run, passes signals on, requeues on the time-limit warning.
    #[command(hide = true)]
    SweepTask(sweep::SweepTaskArgs),
    /// Benchmarks.
    #[command(
        subcommand,
        after_help = "Example:\n  apo bench epoch --env Hopper --algo apo"
    )]
    Bench(bench::BenchCommand),
    /// Print a shell completion script: bash, zsh, fish, elvish or powershell.
    #[command(
        after_help = "Example:\n  apo completions bash > ~/.local/share/bash-completion/completions/apo\n  apo completions zsh > \"${fpath[1]}/_apo\""
    )]
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print this command-line reference as Markdown (docs/cli.md is its output).
    #[command(hide = true)]
    MarkdownHelp,
}

/// `apo completions SHELL`: the completion script on stdout.
fn completions(shell: clap_complete::Shell) -> anyhow::Result<()> {
    use clap::CommandFactory;
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut Cli::command(), "apo", &mut script);
    apo_cli::out!("{}", String::from_utf8_lossy(&script))?;
    Ok(())
}

/// The registered algorithms' names, comma-separated.
fn algorithm_names() -> String {
    Algorithm::ALL
        .iter()
        .map(|a| a.name())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The width of the longest algorithm name, to align tables.
fn algorithm_name_width() -> usize {
    Algorithm::ALL
        .iter()
        .map(|a| a.name().len())
        .max()
        .unwrap_or(0)
}

/// `--physics`: a MuJoCo physics by name (`mujoco2`, `mujoco3`).
/// Bootstrap resamples (in `stats::analysis_work`'s units) from which a computation shows a
/// progress bar: about a second of work or more.
const BAR_FROM_RESAMPLES: u64 = 200_000;

/// A progress bar with the elapsed time and an estimate of the time left, on stderr, for
/// `total` units of work named `what`: only on a terminal and for work of at least
/// [`BAR_FROM_RESAMPLES`].
fn work_bar(total: u64, what: &str) -> Option<indicatif::ProgressBar> {
    use std::io::IsTerminal;
    (total >= BAR_FROM_RESAMPLES && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(total);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{msg} {bar:40} {percent:>3}%  {elapsed_precise} (about {eta} left)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar.set_message(what.to_string());
        bar
    })
}

fn parse_physics(name: &str) -> Result<Physics, String> {
    name.parse()
        .map_err(|e: apo_envs::mujoco::MujocoError| e.to_string())
}

/// `--algo`: an algorithm by name, with the closest name suggested.
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

/// The most characters of an error printed (a longer one ends `… (N bytes)`).
const ERROR_CHARS: usize = 2_000;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // --help and --version go to stdout through the one writer, so that a full disk or a
        // closed pipe is said (or ends as SIGPIPE would) as for every other output
        Err(e)
            if matches!(
                e.kind(),
                clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion
            ) =>
        {
            return match apo_cli::out!("{}", e.render()) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) if apo_cli::terminal::is_closed_pipe(&e) => ExitCode::from(141),
                Err(e) => {
                    apo_train::warnln!("error: {e:#}");
                    ExitCode::FAILURE
                }
            };
        }
        Err(e) => e.exit(),
    };
    #[cfg(feature = "atari")]
    if let Err(e) = apo_atari::register_games() {
        apo_train::warnln!("error: {e}");
        return ExitCode::FAILURE;
    }
    let done = |r: anyhow::Result<()>| r.map(|()| ExitCode::SUCCESS);
    let result = match cli.command {
        Command::Train(args) => train::train_on_ranks(args),
        Command::List => done(list::run()),
        Command::Eval(args) => done(eval::run(&args)),
        Command::Render(args) => render::run(&args),
        Command::Config(args) => done(config::run(args)),
        Command::Plot(args) => done(plot::run(&args)),
        Command::Bench(command) => done(bench::run(command)),
        Command::Sweep(args) => sweep::run(args),
        Command::SweepTask(args) => sweep::task(&args),
        Command::Theory(args) => done(apo_cli::theory::run(&args)),
        Command::Report(args) => done(report::run(&args)),
        Command::Summary(args) => done(summary::run(&args)),
        Command::Stats(args) => done(stats::run(&args)),
        Command::Completions { shell } => done(completions(shell)),
        Command::MarkdownHelp => done(apo_cli::out!("{}", clap_markdown::help_markdown::<Cli>())),
    };
    result.unwrap_or_else(|e| {
        if apo_cli::terminal::is_closed_pipe(&e) {
            // the reader went away (`apo list | head -1`): end as a process killed by SIGPIPE
            return ExitCode::from(141);
        }
        // an error quotes at most a short excerpt of what it found (the readers cut theirs;
        // this bounds any other)
        apo_train::warnln!(
            "error: {}",
            apo_train::input::clip(&format!("{e:#}"), ERROR_CHARS)
        );
        if let Some(hint) = atari_hint(&e, cfg!(feature = "atari")) {
            apo_train::warnln!("{hint}");
        }
        ExitCode::FAILURE
    })
}

/// For an unknown `ALE/…` environment in a build without the `atari` feature
/// (`built_with_atari` false): how to get the Atari games.
fn atari_hint(error: &anyhow::Error, built_with_atari: bool) -> Option<&'static str> {
    let unknown_game = error.chain().any(|cause| {
        matches!(cause.downcast_ref::<apo_envs::EnvError>(),
            Some(apo_envs::EnvError::Unknown { name, .. })
                if name.get(..4).is_some_and(|ns| ns.eq_ignore_ascii_case("ALE/")))
    });
    (unknown_game && !built_with_atari).then_some(
        "hint: the Atari games (`ALE/<Game>-v5`) are in builds with the `atari` feature \
         (GPL-2.0): cargo build --release -p apo-cli --features atari",
    )
}

#[cfg(test)]
mod tests {
    use super::atari_hint;

    fn unknown(name: &str) -> anyhow::Error {
        let error = apo_envs::EnvError::Unknown {
            name: name.to_string(),
            suggestions: Vec::new(),
            registered: Vec::new(),
        };
        anyhow::Error::new(error).context("cannot build the environment")
    }

    #[test]
    fn atari_hint_only_for_unknown_ale_names_in_builds_without_atari() {
        let hint = atari_hint(&unknown("ALE/Pong-v5"), false).expect("a hint");
        assert!(hint.contains("--features atari"), "{hint}");
        assert!(atari_hint(&unknown("ale/pong-v5"), false).is_some());
        // with the games built in, an unknown ALE name is a typo, not a missing feature
        assert_eq!(atari_hint(&unknown("ALE/Pong-v5"), true), None);
        assert_eq!(atari_hint(&unknown("CartPol-v1"), false), None);
        assert_eq!(atari_hint(&anyhow::anyhow!("ALE/Pong-v5"), false), None);
    }
}
