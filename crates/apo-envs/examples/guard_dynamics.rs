//! How lively each GUARD robot is under random actions, next to GUARD's own engine.
//!
//! For every suite (or those named after the episode count): `episodes` episodes (default 20)
//! of 1000 steps with i.i.d. N(0, 1) actions, each from its own seed (a new layout every
//! episode; actions from `StdRng::seed_from_u64(1000 + episode)`). Per episode it takes the
//! mean |reward| per step, which measures how far the robot moves, and the largest
//! |observation| component; it prints their means over episodes with 95 % percentile-bootstrap
//! intervals (10 000 resamples, fixed seed) beside GUARD's figures from `docs/guard.md`
//! ("Dynamics under random actions"), measured the same way on GUARD's engine over
//! `GUARD_EPISODES` episodes, and `z`, the difference of the means in standard errors, taking
//! the spread between GUARD's episodes to be ours (GUARD's per-episode values are not kept).
//!
//! ```sh
//! cargo run --release -p apo-envs --example guard_dynamics            # all 17 suites, 20 episodes
//! cargo run --release -p apo-envs --example guard_dynamics -- 20 Goal_Swimmer Goal_Hopper
//! ```

use apo_envs::mujoco::guard::suites;
use apo_envs::{registry, Action, EnvError};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// GUARD's engine (MuJoCo 2.2.2, gym 0.26), 20 episodes of 1000 steps with N(0, 1) actions:
/// mean |reward| per step and the largest |observation| over all episodes (docs/guard.md).
const GUARD: [(&str, f64, f64); 9] = [
    ("Goal_Point", 0.00232, 18.6),
    ("Goal_Swimmer", 0.0953, 630.0),
    ("Chase_Swimmer", 0.0945, 603.0),
    ("Goal_Hopper", 0.0104, 4244.0),
    ("Push_Hopper", 0.0089, 4244.0),
    ("Goal_Arm3", 0.0077, 2.1),
    ("Goal_Drone", 0.0079, 61.0),
    ("Push_Point", 0.0024, 18.6),
    ("Chase_Point", 0.0028, 18.6),
];

/// Episodes behind each of GUARD's figures.
const GUARD_EPISODES: f64 = 20.0;

/// One episode of `name` from `seed`: (mean |reward| per step, largest |observation|, whether
/// the simulator became unstable, which ends the episode early).
fn episode(name: &str, seed: u64) -> Result<(f64, f64, bool), EnvError> {
    let spec = registry::spec(name)?;
    let mut env = registry::make(name)?;
    let mut obs = vec![0.0; spec.observation_dim];
    let mut action = vec![0.0; spec.action_space.flat_dim()];
    let mut rng = StdRng::seed_from_u64(1000 + seed);
    env.reset(Some(seed), &mut obs);
    let max_abs = |obs: &[f32], m: f64| obs.iter().fold(m, |m, &x| m.max(f64::from(x.abs())));
    let mut largest = max_abs(&obs, 0.0);
    let (mut total, mut steps) = (0.0, 0usize);
    loop {
        action
            .iter_mut()
            .for_each(|a| *a = StandardNormal.sample(&mut rng));
        let t = env.step(Action::Continuous(&action), &mut obs);
        total += t.reward.abs();
        steps += 1;
        largest = max_abs(&obs, largest);
        if t.done() {
            return Ok((total / steps as f64, largest, t.info.unstable));
        }
    }
}

/// The sample standard deviation of `xs` around `mean`.
fn std_dev(xs: &[f64], mean: f64) -> f64 {
    let n = xs.len() as f64;
    (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
}

/// The mean of `xs` and its 95 % percentile-bootstrap interval.
fn mean_ci(xs: &[f64]) -> (f64, f64, f64) {
    let mean = |v: &mut dyn Iterator<Item = f64>, n: usize| v.sum::<f64>() / n as f64;
    let n = xs.len();
    let mut rng = StdRng::seed_from_u64(7);
    let mut means: Vec<f64> = (0..10_000)
        .map(|_| mean(&mut (0..n).map(|_| xs[rng.random_range(0..n)]), n))
        .collect();
    means.sort_by(f64::total_cmp);
    (mean(&mut xs.iter().copied(), n), means[250], means[9_749])
}

fn main() -> Result<(), EnvError> {
    let mut args = std::env::args().skip(1);
    let episodes: u64 = match args.next() {
        None => 20,
        Some(n) => match n.parse() {
            Ok(n) if n >= 2 => n,
            _ => {
                return Err(EnvError::Init {
                    name: "guard_dynamics".into(),
                    reason: format!(
                        "the episode count must be an integer of at least 2, not `{n}`"
                    ),
                })
            }
        },
    };
    let only: Vec<String> = args.collect();
    for name in &only {
        registry::spec(name)?;
    }
    println!(
        "| suite | mean \\|reward\\| per step: GUARD | ours [95 % CI] | ratio | z | largest \\|obs\\|: GUARD | ours (mean per episode [95 % CI]) | unstable episodes |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for suite in suites() {
        let name = suite.name();
        if !only.is_empty() && !only.contains(&name) {
            continue;
        }
        let mut per_step = Vec::new();
        let mut largest = Vec::new();
        let mut unstable = 0;
        for seed in 0..episodes {
            let (r, o, u) = episode(&name, seed)?;
            per_step.push(r);
            largest.push(o);
            unstable += usize::from(u);
        }
        let (r, r_lo, r_hi) = mean_ci(&per_step);
        let (o, o_lo, o_hi) = mean_ci(&largest);
        let o_max = largest.iter().copied().fold(0.0, f64::max);
        let guard = GUARD.iter().find(|g| g.0 == name);
        let (g_r, ratio, z, g_o) = match guard {
            Some(&(_, g_r, g_o)) => {
                let sd = std_dev(&per_step, r);
                let se = (sd * sd / per_step.len() as f64 + sd * sd / GUARD_EPISODES).sqrt();
                (
                    format!("{g_r}"),
                    format!("{:.2}", r / g_r),
                    format!("{:+.1}", (r - g_r) / se),
                    format!("{g_o}"),
                )
            }
            None => ("–".into(), "–".into(), "–".into(), "–".into()),
        };
        println!(
            "| {name} | {g_r} | {r:.4} [{r_lo:.4}, {r_hi:.4}] | {ratio} | {z} | {g_o} | {o_max:.1} ({o:.1} [{o_lo:.1}, {o_hi:.1}]) | {unstable} |"
        );
    }
    Ok(())
}
