//! `apo list`: the environments with their sizes, and the algorithms.

use apo_core::Algorithm;

pub fn run() -> anyhow::Result<()> {
    apo_cli::outln!(
        "{:<28} {:>8}  {:<14} {:>9}",
        "environment",
        "obs dim",
        "actions",
        "max steps"
    )?;
    for spec in apo_envs::list() {
        let actions = match &spec.action_space {
            apo_envs::Space::Discrete { n } => format!("discrete({n})"),
            apo_envs::Space::Box { low, .. } => format!("box({})", low.len()),
        };
        apo_cli::outln!(
            "{:<28} {:>8}  {:<14} {:>9}",
            spec.name,
            spec.observation_dim,
            actions,
            spec.max_episode_steps
        )?;
    }
    apo_cli::outln!()?;
    apo_cli::outln!("algorithms:")?;
    let width = crate::algorithm_name_width();
    for algo in Algorithm::ALL {
        apo_cli::outln!("  {:<width$} {}", algo.name(), algo.about())?;
    }
    Ok(())
}
