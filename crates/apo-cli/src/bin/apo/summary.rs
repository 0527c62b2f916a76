//! `apo summary`: the paper's metrics of each run.

use std::path::PathBuf;

#[derive(clap::Args)]
pub struct SummaryArgs {
    /// Run directories, or folders of runs (a sweep's: each run directly inside it).
    #[arg(required = true)]
    runs: Vec<PathBuf>,
    /// N of "the last N epochs" (paper: 20 continuous, 100 Atari); 1..=1000000000.
    #[arg(long, default_value_t = 20, value_parser = apo_cli::flags::count::<u64>(1, 1_000_000_000))]
    last: u64,
    /// CSV instead of an aligned table.
    #[arg(long)]
    csv: bool,
}

pub fn run(args: &SummaryArgs) -> anyhow::Result<()> {
    let last = args.last as usize;
    let rows = apo_cli::report::find_runs(&args.runs)?
        .iter()
        .map(|run| {
            Ok((
                run.display().to_string(),
                apo_cli::summary::summarize(run, last)?,
            ))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    if args.csv {
        apo_cli::out!("{}", apo_cli::summary::csv(&rows, last)?)?;
    } else {
        apo_cli::out!("{}", apo_cli::summary::table(&rows, last))?;
    }
    Ok(())
}
