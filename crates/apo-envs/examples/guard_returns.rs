//! The returns of one 1000-step episode of every GUARD suite with zero actions and with
//! N(0, 1) actions, seeds 0..n (default 1), as a Markdown table: the figures `docs/guard.md`
//! compares with GUARD's reference values.
//!
//! ```sh
//! cargo run --release -p apo-envs --example guard_returns -- 5
//! ```

use apo_envs::mujoco::guard::suites;
use apo_envs::{registry, Action};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// The return of one episode from `seed` with actions from `act`.
fn episode(
    name: &str,
    seed: u64,
    mut act: impl FnMut(&mut [f32]),
) -> Result<f64, apo_envs::EnvError> {
    let spec = registry::spec(name)?;
    let mut env = registry::make(name)?;
    let mut obs = vec![0.0; spec.observation_dim];
    let mut action = vec![0.0; spec.action_space.flat_dim()];
    env.reset(Some(seed), &mut obs);
    let mut total = 0.0;
    loop {
        act(&mut action);
        let t = env.step(Action::Continuous(&action), &mut obs);
        total += t.reward;
        if t.done() {
            return Ok(total);
        }
    }
}

fn main() -> Result<(), apo_envs::EnvError> {
    let seeds: u64 = match std::env::args().nth(1) {
        Some(n) => n.parse().map_err(|_| apo_envs::EnvError::Init {
            name: "guard_returns".into(),
            reason: format!("the number of seeds must be a positive integer, not `{n}`"),
        })?,
        None => 1,
    };
    println!("| suite | zero action (mean over seeds) | N(0, 1) actions (mean [min, max]) |");
    println!("|---|---|---|");
    for suite in suites() {
        let name = suite.name();
        let mut zero = 0.0;
        let mut random = Vec::new();
        for seed in 0..seeds.max(1) {
            zero += episode(&name, seed, |a| a.fill(0.0))?;
            let mut rng = StdRng::seed_from_u64(seed + 1);
            random.push(episode(&name, seed, |a| {
                a.iter_mut()
                    .for_each(|x| *x = StandardNormal.sample(&mut rng))
            })?);
        }
        let n = seeds.max(1) as f64;
        let mean = random.iter().sum::<f64>() / n;
        let (lo, hi) = random
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), &r| (lo.min(r), hi.max(r)));
        println!(
            "| {name} | {:.4} | {mean:.2} [{lo:.2}, {hi:.2}] |",
            zero / n
        );
    }
    Ok(())
}
