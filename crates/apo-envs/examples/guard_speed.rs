//! Speed of the GUARD suites against the bare simulator, one environment on one thread.
//!
//! For each suite: (1) environment steps per second of `GuardEnv` under uniform random
//! actions (reset every 1 000 steps); (2) the same actions on the bare simulator — the suite's
//! model stepped 10 times per action with nothing else — so (1)/(2) is what the engine
//! (observation, reward, robbers, layouts) costs; (3) simulator steps per second of the bare
//! model from its reference state with controls `0.01 · N(0, 1)` drawn every step, the regime of
//! `mujoco-testspeed MODEL N 1 0.01`, to compare the Rust bindings with MuJoCo's own loop.
//!
//! Each figure is the median of `REPEATS` measurements (default 5).
//!
//! ```sh
//! cargo run --release -p apo-envs --example guard_speed -- 20000 5
//! ```

use std::sync::Arc;
use std::time::Instant;

use apo_envs::mujoco::guard::{suites, GuardEnv, Robot, SUBSTEPS};
use apo_envs::mujoco::{Data, Model, MujocoError};
use apo_envs::{Action, Env};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

const EPISODE: usize = 1000;

/// The median of `values`.
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

fn main() -> Result<(), MujocoError> {
    let arg = |i: usize, default: usize| {
        std::env::args()
            .nth(i)
            .and_then(|n| n.parse().ok())
            .unwrap_or(default)
            .max(1)
    };
    let (steps, repeats) = (arg(1, 20_000), arg(2, 5));
    println!("| suite | env steps/s | bare simulator, same actions (env steps/s) | engine share of the time | mj_step/s, testspeed regime |");
    println!("|---|---|---|---|---|");
    for suite in suites() {
        let mut runs = Vec::new();
        for _ in 0..repeats {
            runs.push(measure(suite, steps)?);
        }
        let col = |k: usize| median(runs.iter().map(|r: &[f64; 3]| r[k]).collect());
        let (env_rate, bare_rate, sim_rate) = (col(0), col(1), col(2));
        println!(
            "| {} | {env_rate:.0} | {bare_rate:.0} | {:.0}% | {sim_rate:.0} |",
            suite.name(),
            100.0 * (1.0 - env_rate / bare_rate)
        );
    }
    Ok(())
}

/// One measurement of `suite`: environment steps/s, bare-simulator env steps/s, mj_step/s in
/// the testspeed regime.
fn measure(suite: apo_envs::mujoco::guard::Suite, steps: usize) -> Result<[f64; 3], MujocoError> {
    {
        let mut rng = StdRng::seed_from_u64(0);
        let dim = suite.robot.action_dim();
        let pool: Vec<Vec<f32>> = (0..1024)
            .map(|_| (0..dim).map(|_| rng.random_range(-1.0..=1.0)).collect())
            .collect();
        // (1) the environment.
        let mut env = GuardEnv::new(suite)?;
        let mut obs = vec![0.0; suite.observation_dim()];
        env.reset(Some(0), &mut obs);
        let start = Instant::now();
        for (t, a) in pool.iter().cycle().take(steps).enumerate() {
            env.step(Action::Continuous(a), &mut obs);
            if t % EPISODE == EPISODE - 1 {
                env.reset(None, &mut obs);
            }
        }
        let env_rate = steps as f64 / start.elapsed().as_secs_f64();
        // (2) the bare simulator with the same actions.
        let model = Arc::new(Model::from_xml_str(&suite.mjcf())?);
        let mut data = Data::new(Arc::clone(&model))?;
        let rotors: Vec<usize> = if suite.robot == Robot::Drone {
            ["p1", "p2", "p3", "p4"]
                .iter()
                .map(|b| model.id(apo_envs::mujoco::ObjKind::Body, b))
                .collect::<Result<_, _>>()?
        } else {
            Vec::new()
        };
        let hover = 9.81 * model.body_mass().iter().sum::<f64>() / 4.0;
        let start = Instant::now();
        for (t, a) in pool.iter().cycle().take(steps).enumerate() {
            if rotors.is_empty() {
                for (c, &x) in data.ctrl_mut().iter_mut().zip(a) {
                    *c = f64::from(x);
                }
            } else {
                let f = data.xfrc_applied_mut();
                for (&b, &x) in rotors.iter().zip(a) {
                    f[b][2] = hover + 0.1 * f64::from(x);
                }
            }
            for _ in 0..SUBSTEPS {
                data.step();
            }
            if t % EPISODE == EPISODE - 1 {
                data.reset();
            }
        }
        let bare_rate = steps as f64 / start.elapsed().as_secs_f64();
        // (3) the testspeed regime.
        let mut data = Data::new(model)?;
        let noise: Vec<f64> = (0..4096)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                0.01 * z
            })
            .collect();
        let n = steps * SUBSTEPS;
        let mut k = 0;
        let start = Instant::now();
        for _ in 0..n {
            for c in data.ctrl_mut() {
                *c = noise[k % noise.len()];
                k += 1;
            }
            data.step();
        }
        let sim_rate = n as f64 / start.elapsed().as_secs_f64();
        Ok([env_rate, bare_rate, sim_rate])
    }
}
