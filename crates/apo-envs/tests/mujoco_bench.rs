//! Benchmark, not a timed test (ignored by default): env steps per second of each MuJoCo task
//! under random actions, against the raw simulator (`mujoco-testspeed` from Debian's
//! `libmujoco-samples`, same model file) divided by the frame skip, and our `Data::step`
//! driven the way testspeed drives MuJoCo (which isolates the cost of the wrapper from the
//! differences between the states that random play and testspeed visit). Run with
//!
//! ```text
//! CARGO_TARGET_DIR=/tmp/target-mujoco cargo test --release -p apo-envs --test mujoco_bench -- --ignored --nocapture
//! ```
//!
//! `APO_BENCH_STEPS` sets the env steps per task (default 20000).

use std::process::Command;
use std::sync::Arc;
use std::time::Instant;

use apo_envs::mujoco::tasks::{
    Ant, HalfCheetah, Hopper, Humanoid, HumanoidStandup, InvertedDoublePendulum, InvertedPendulum,
    Reacher, Swimmer, Walker2d,
};
use apo_envs::mujoco::{steps_per_second, Data, Model, MujocoEnv, Task};

/// `mujoco-testspeed` on `file` for `nstep` simulator steps, one thread: its steps per second.
fn testspeed(file: &str, nstep: usize) -> Option<f64> {
    let out = Command::new("mujoco-testspeed")
        .args([file, &nstep.to_string(), "1", "0.01"])
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("Steps per second"))?;
    line.split(':').nth(1)?.trim().parse().ok()
}

/// MuJoCo's `mju_Halton`: the radical inverse of `index` in `base`.
fn halton(mut index: usize, base: usize) -> f64 {
    let (mut f, mut h) = (1.0 / base as f64, 0.0);
    while index > 0 {
        h += f * (index % base) as f64;
        index /= base;
        f /= base as f64;
    }
    h
}

/// Our wrapper driven exactly as `mujoco-testspeed` drives MuJoCo: from `qpos0`, `nstep`
/// calls of `Data::step` with control `j` at step `i` set to
/// `center_j + 0.01 · radius_j · (2 · halton(i, j + 2) − 1)`, no resets.
fn wrapper_loop<T: Task>(nstep: usize) -> f64 {
    let model = Arc::new(Model::from_xml_str(T::MJCF).expect("model"));
    let ranges: Vec<[f64; 2]> = model.actuator_ctrlrange().to_vec();
    let mut data = Data::new(model).expect("data");
    let start = Instant::now();
    for i in 0..nstep {
        for (j, (c, [lo, hi])) in data.ctrl_mut().iter_mut().zip(&ranges).enumerate() {
            *c = (hi + lo) / 2.0 + 0.01 * (hi - lo) / 2.0 * (2.0 * halton(i, j + 2) - 1.0);
        }
        data.step();
    }
    nstep as f64 / start.elapsed().as_secs_f64()
}

/// The best of `ROUNDS` interleaved rounds: the machine is shared, so the fastest round is
/// the one least disturbed by other processes.
const ROUNDS: u64 = 5;

fn bench<T: Task>(file: &str, steps: usize) {
    let path = format!("{}/assets/{file}", env!("CARGO_MANIFEST_DIR"));
    let nstep = steps * T::FRAME_SKIP;
    let (mut ours, mut raw, mut wrapper) = (0.0f64, 0.0f64, 0.0f64);
    for round in 0..ROUNDS {
        let mut env = MujocoEnv::<T>::make().expect("MuJoCo env");
        ours = ours.max(steps_per_second(&mut env, steps, round));
        raw = raw.max(testspeed(&path, nstep).unwrap_or(f64::NAN) / T::FRAME_SKIP as f64);
        wrapper = wrapper.max(wrapper_loop::<T>(nstep) / T::FRAME_SKIP as f64);
    }
    println!(
        "{:24} {:>10} {:>12.0} {:>14.0} {:>6.2} {:>14.0} {:>6.2}",
        T::NAME,
        T::FRAME_SKIP,
        ours,
        raw,
        ours / raw,
        wrapper,
        wrapper / raw
    );
}

#[test]
#[ignore = "benchmark: run explicitly with --ignored --nocapture in release mode"]
fn env_steps_per_second_vs_raw_mujoco() {
    let steps = std::env::var("APO_BENCH_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20_000);
    println!("{steps} env steps per task, best of {ROUNDS} interleaved rounds");
    println!(
        "{:24} {:>10} {:>12} {:>14} {:>6} {:>14} {:>6}",
        "env", "frame_skip", "env steps/s", "testspeed/fs", "ratio", "wrapper/fs", "ratio"
    );
    bench::<InvertedPendulum>("inverted_pendulum.xml", steps);
    bench::<InvertedDoublePendulum>("inverted_double_pendulum.xml", steps);
    bench::<Reacher>("reacher.xml", steps);
    bench::<Swimmer>("swimmer.xml", steps);
    bench::<Hopper>("hopper.xml", steps);
    bench::<HalfCheetah>("half_cheetah.xml", steps);
    bench::<Walker2d>("walker2d.xml", steps);
    bench::<Ant>("ant.xml", steps);
    bench::<Humanoid>("humanoid.xml", steps);
    bench::<HumanoidStandup>("humanoid.xml", steps);
}
