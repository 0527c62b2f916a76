//! `apo report`: the paper's metrics per environment and algorithm over seeds.

use std::path::PathBuf;

use apo_cli::report;

#[derive(clap::Args)]
pub struct ReportArgs {
    /// Run directories, or folders of runs (a sweep's); seeds of one setting are grouped
    /// by environment, algorithm and the directory name without `-s<seed>`. A run named twice
    /// (directly and through its folder) counts once.
    #[arg(required = true)]
    runs: Vec<PathBuf>,
    /// N of "the last N epochs" (paper: 20 continuous, 100 Atari); 1..=1000000000.
    #[arg(long, default_value_t = 20, value_parser = apo_cli::flags::count::<u64>(1, 1_000_000_000))]
    last: u64,
    /// Folder for report.md, report.csv and curves-<env>.<image>.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Episodes of the random policy that the scores are normalized by; 1..=100000.
    #[arg(long, default_value_t = 10, value_parser = apo_cli::flags::count::<u64>(1, 100_000))]
    random_episodes: u64,
    /// Image format of the curves.
    #[arg(long, value_parser = ["png", "svg"], default_value = "png")]
    image: String,
    /// Moving average of the curves over this many epochs (1: none); 1..=100000.
    #[arg(long, default_value_t = 1, value_parser = apo_cli::flags::count::<usize>(1, 100_000))]
    smooth: usize,
    /// Scores of the statistics section: `trpo` (the paper's TRPO-normalized score against
    /// the random policy) or `minmax` (per environment over the compared runs).
    #[arg(long, value_parser = ["trpo", "minmax"], default_value = "trpo")]
    normalize: String,
    /// Bootstrap resamples of each interval of the statistics section; 1..=10000000.
    #[arg(long, default_value_t = 2000, value_parser = apo_cli::flags::count::<usize>(1, 10_000_000))]
    reps: usize,
    /// Seed of the bootstrap (the same seed gives the same report); 0..=18446744073709551615.
    #[arg(long, default_value_t = 0, value_parser = apo_cli::flags::count::<u64>(0, u64::MAX))]
    ci_seed: u64,
}

/// A report that fails removes the `--out` folders it created (while empty): it leaves only
/// what was there.
pub fn run(args: &ReportArgs) -> anyhow::Result<()> {
    let created = match &args.out {
        Some(out) => apo_train::input::prepare_output_dir(out, "--out")?,
        None => apo_train::input::CreatedDirs::default(),
    };
    report_into(args).inspect_err(|_| created.remove_if_empty())
}

fn report_into(args: &ReportArgs) -> anyhow::Result<()> {
    // every option is checked before any work
    if let Some(out) = &args.out {
        apo_train::run_dir::check_outputs(out, report::REPORT_MARKER, &report::fixed_outputs())?;
    }
    // the profiles hold reps × thresholds values at once (the default thresholds: 101)
    apo_train::input::check_fits(
        apo_cli::stats::profile_memory(
            &apo_cli::stats::StratifiedBootstrap {
                reps: args.reps,
                level: 0.95,
                seed: args.ci_seed,
            },
            apo_cli::stats::DEFAULT_TAUS,
        ),
        &format!("--reps {}", args.reps),
    )?;
    let runs = report::find_runs(&args.runs)?;
    let episodes = args.random_episodes as usize;
    let mut report = report::report(&runs, args.last as usize, &mut |env, options| {
        report::random_baseline(env, options, episodes, 0)
    })?;
    // the statistics compare every ordered pair of settings: their count is bounded first
    let settings: std::collections::BTreeSet<String> = report
        .groups
        .iter()
        .map(report::GroupReport::label)
        .collect();
    if settings.len() > apo_cli::stats::MAX_ALGORITHMS {
        anyhow::bail!(
            "the runs form {} settings (algorithm and variant), more than the {} a comparison may have \
             (1..={}: every ordered pair is an estimate of its own); report fewer runs at once",
            settings.len(),
            apo_cli::stats::MAX_ALGORITHMS,
            apo_cli::stats::MAX_ALGORITHMS
        );
    }
    let options = report::StatsOptions {
        normalization: if args.normalize == "minmax" {
            report::Normalization::MinMax
        } else {
            report::Normalization::Trpo
        },
        bootstrap: apo_cli::stats::StratifiedBootstrap {
            reps: args.reps,
            level: 0.95,
            seed: args.ci_seed,
        },
    };
    let mut bar = None;
    report.statistics = report::statistics_with_progress(&report, &options, &mut |done, total| {
        let bar = bar.get_or_insert_with(|| crate::work_bar(total, "bootstrap"));
        if let Some(bar) = bar {
            bar.set_position(done);
        }
    });
    if let Some(Some(bar)) = bar {
        bar.finish_and_clear();
    }
    // the files first: a report that cannot be written is not printed as if it had been
    let written = match &args.out {
        Some(out) => report::write(&report, out, &args.image, args.smooth)?,
        None => Vec::new(),
    };
    apo_cli::out!("{}", report::markdown(&report))?;
    for path in written {
        apo_train::warnln!("wrote {}", path.display());
    }
    Ok(())
}
