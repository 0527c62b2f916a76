//! `apo config`: the effective configuration, every key documented.

use std::path::PathBuf;

use apo_core::Algorithm;
use apo_train::run_config::{Preset, RunConfig};
use apo_train::run_dir;

#[derive(clap::Args)]
pub struct ConfigArgs {
    /// Algorithm whose defaults to start from [default: apo; with --config: the file's
    /// section [algo.<name>]].
    #[arg(long, value_parser = crate::parse_algo)]
    algo: Option<Algorithm>,
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
    #[arg(long, conflicts_with_all = ["algo", "env", "config", "preset", "sets"])]
    run: Option<PathBuf>,
}

pub fn run(args: ConfigArgs) -> anyhow::Result<()> {
    apo_train::run_config::check_repeated_sets(&args.sets)?;
    let config = match &args.run {
        Some(run) => run_dir::load_config(run)?,
        None => {
            let algo = match &args.config {
                Some(path) => args
                    .algo
                    .or(apo_train::run_config::file_algorithm(path)?)
                    .unwrap_or(Algorithm::Apo),
                None => args.algo.unwrap_or(Algorithm::Apo),
            };
            if let Some(env) = &args.env {
                apo_envs::registry::spec(env)?;
            }
            RunConfig::build_with_preset(
                algo,
                args.env.as_deref().unwrap_or(""),
                args.preset,
                args.config.as_deref(),
                &args.sets,
            )?
        }
    };
    apo_cli::out!("{}", config.documented_toml())?;
    Ok(())
}
