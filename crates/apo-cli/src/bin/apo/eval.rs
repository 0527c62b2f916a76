//! `apo eval`: a run's policy on fresh episodes.

use std::path::PathBuf;

use anyhow::Context;
use apo_train::checkpoint::Which;

#[derive(clap::Args)]
pub struct EvalArgs {
    /// The run directory.
    #[arg(long)]
    run: PathBuf,
    /// Number of episodes; 1..=1000000.
    #[arg(long, default_value_t = 10, value_parser = apo_cli::flags::count::<u64>(1, 1_000_000))]
    episodes: u64,
    /// Act with the mean (Gaussian) or most likely (categorical) action.
    #[arg(long)]
    deterministic: bool,
    /// Seed of the evaluation episodes; 0..=18446744073709551615.
    #[arg(long, default_value_t = 12345, value_parser = apo_cli::flags::count::<u64>(0, u64::MAX))]
    seed: u64,
    /// Which checkpoint: `latest`, `best` (the best evaluation of a run with eval_every), or an
    /// epoch kept by keep_checkpoint_every.
    #[arg(long, default_value = "latest")]
    checkpoint: Which,
}

pub fn run(args: &EvalArgs) -> anyhow::Result<()> {
    let (result, epoch) = apo_train::playback::evaluate(
        &args.run,
        &args.checkpoint,
        args.episodes as usize,
        args.deterministic,
        args.seed,
    )?;
    let stats = apo_core::EpisodeStats::from_episodes(&result.returns, &result.lengths, 0.0)
        .context("no episode was run")?;
    let success = result
        .success_rate()
        .map_or_else(String::new, |rate| format!(" success_rate={rate:.3}"));
    // every episode counts; those a simulator failure ended are counted and flagged
    let unstable = result.unstable.iter().filter(|&&u| u).count();
    let unstable = if unstable > 0 {
        format!(" unstable_episodes={unstable}")
    } else {
        String::new()
    };
    apo_cli::outln!(
        "checkpoint_epoch={epoch} episodes={} mean_return={:.3} std_return={:.3} min_return={:.3} max_return={:.3} mean_length={:.1}{success}{unstable}",
        stats.count, stats.ret_mean, stats.ret_std, stats.ret_min, stats.ret_max, stats.len_mean
    )?;
    Ok(())
}
