//! `apo stats`: aggregate scores with confidence intervals, probabilities of improvement and
//! performance profiles of a score file (`apo_cli::stats`).

use std::path::PathBuf;

use anyhow::Context;
use apo_cli::stats;

#[derive(clap::Args)]
pub struct StatsArgs {
    /// CSV with the columns `algorithm,task,score`, one row per run (e.g. normalized scores).
    scores: PathBuf,
    /// Bootstrap resamples of each interval; 1..=10000000.
    #[arg(long, default_value_t = 2000, value_parser = apo_cli::flags::count::<usize>(1, 10_000_000))]
    reps: usize,
    /// Seed of the bootstrap (the same seed gives the same intervals); 0..=18446744073709551615.
    #[arg(long, default_value_t = 0, value_parser = apo_cli::flags::count::<u64>(0, u64::MAX))]
    ci_seed: u64,
    /// Thresholds of the performance profiles, `LOW:HIGH:N` (N evenly spaced values; default:
    /// 101 from the lowest to the highest score).
    #[arg(long)]
    taus: Option<String>,
    /// Print JSON (aggregates, probabilities of improvement, profiles) instead of Markdown.
    #[arg(long)]
    json: bool,
}

/// `LOW:HIGH:N`.
fn parse_taus(text: &str) -> anyhow::Result<Vec<f64>> {
    let parts: Vec<&str> = text.split(':').collect();
    let parsed = match parts[..] {
        [low, high, n] => low
            .parse::<f64>()
            .ok()
            .zip(high.parse::<f64>().ok())
            .zip(n.parse::<usize>().ok()),
        _ => None,
    };
    match parsed {
        Some(((low, high), n))
            if low.is_finite()
                && high.is_finite()
                && (high - low).is_finite()
                && low <= high
                && (1..=100_000).contains(&n) =>
        {
            Ok(stats::linspace(low, high, n))
        }
        _ => anyhow::bail!(
            "--taus expects LOW:HIGH:N with LOW ≤ HIGH finite, HIGH − LOW finite (|LOW|, |HIGH| < 8.9e307) and 1 ≤ N ≤ 100000, got `{text}`"
        ),
    }
}

pub fn run(args: &StatsArgs) -> anyhow::Result<()> {
    let taus = args.taus.as_deref().map(parse_taus).transpose()?;
    let text =
        apo_train::input::read_text(&args.scores, "score file", apo_train::input::PROGRESS_FILE)?;
    let comparison =
        stats::read_scores(&text).with_context(|| format!("{}", args.scores.display()))?;
    let taus = taus.unwrap_or_else(|| stats::default_taus(&comparison));
    let bootstrap = stats::StratifiedBootstrap {
        reps: args.reps,
        level: 0.95,
        seed: args.ci_seed,
    };
    apo_train::input::check_fits(
        stats::profile_memory(&bootstrap, taus.len()),
        &format!(
            "--reps {} with {} thresholds (--taus)",
            args.reps,
            taus.len()
        ),
    )?;
    let bar = crate::work_bar(
        stats::analysis_work(comparison.algorithms.len(), &bootstrap),
        "bootstrap",
    );
    let analysis = stats::analyze_with_progress(&comparison, &bootstrap, &taus, &mut |n| {
        if let Some(bar) = &bar {
            bar.inc(n);
        }
    });
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    if args.json {
        apo_cli::outln!("{}", serde_json::to_string_pretty(&analysis)?)?;
    } else {
        apo_cli::out!("{}", stats::markdown(&analysis))?;
    }
    Ok(())
}
