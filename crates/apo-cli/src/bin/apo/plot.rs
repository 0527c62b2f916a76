//! `apo plot`: learning curves of runs.

use std::path::PathBuf;

#[derive(clap::Args)]
pub struct PlotArgs {
    /// Run directories, or folders of runs (a sweep's: each run directly inside it).
    #[arg(required = true)]
    runs: Vec<PathBuf>,
    /// Output image, .png or .svg.
    #[arg(long)]
    out: PathBuf,
    /// Replace --out if it exists.
    #[arg(long)]
    force: bool,
    /// Moving average over this many epochs (1: none); 1..=100000.
    #[arg(long, default_value_t = 1, value_parser = apo_cli::flags::count::<usize>(1, 100_000))]
    smooth: usize,
    /// Plot this numeric progress.csv column instead of the returns (e.g. kl,
    /// ls_rejected_objective, bias, min_j_sq_on).
    #[arg(long)]
    column: Option<String>,
}

pub fn run(args: &PlotArgs) -> anyhow::Result<()> {
    apo_train::input::check_output_file(&args.out, "--out", args.force)?;
    let runs = apo_cli::report::find_runs(&args.runs)?;
    apo_cli::plot::plot(
        &runs,
        &args.out,
        &apo_cli::plot::PlotOptions {
            smooth: args.smooth,
            column: args.column.clone(),
            place: if args.force {
                apo_train::atomic::Place::ReplacePlainFile
            } else {
                apo_train::atomic::Place::New
            },
        },
    )?;
    apo_cli::outln!("wrote {}", args.out.display())?;
    Ok(())
}
