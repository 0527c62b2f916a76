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
//! Columns: `raw/fs` testspeed's steps/s over the frame skip; `env` our environment under
//! uniform random actions (`throughput::steps_per_second`); `env(ts)` our environment under
//! testspeed's controls; `wrap/fs` our `Data::step` under testspeed's controls, over the frame
//! skip; each with its ratio to `raw/fs`.
//!
//! Each measurement runs for about `APO_BENCH_SECONDS` (default 1) and is repeated in
//! `ROUNDS` interleaved rounds; `APO_BENCH_ONLY=Hopper,Ant` restricts the tasks. Rates are given per CPU second (`/proc` accounting, so other
//! processes on a shared machine barely move them) and, for our env, also per wall second.

use std::process::Command;
use std::sync::Arc;
use std::time::Instant;

use apo_envs::mujoco::tasks::{
    Ant, HalfCheetah, Hopper, Humanoid, HumanoidStandup, InvertedDoublePendulum, InvertedPendulum,
    Reacher, Swimmer, Walker2d,
};
use apo_envs::mujoco::{Data, Model, MujocoEnv, Task};
use apo_envs::throughput::steps_per_second;
use apo_envs::{Action, Env};

/// Linux reports CPU times in `/proc` in ticks of 1/100 s (`USER_HZ`).
const TICKS_PER_SECOND: f64 = 100.0;

/// Interleaved rounds per task; the best round is kept.
const ROUNDS: u64 = 3;

/// The fields of a `/proc/.../stat` line after the command name, as numbers
/// (index 0 is field 3, `state`, which parses as NaN).
fn stat_fields(line: &str) -> Vec<f64> {
    let rest = line.rsplit_once(')').map_or("", |(_, r)| r);
    rest.split_whitespace()
        .map(|f| f.parse().unwrap_or(f64::NAN))
        .collect()
}

/// CPU seconds (user + system) used by this thread so far.
fn thread_cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").expect("/proc/thread-self/stat");
    let f = stat_fields(&stat);
    (f[11] + f[12]) / TICKS_PER_SECOND
}

/// Runs `f`, which does `n` steps, and returns (steps per wall second, steps per CPU second).
fn rates(n: usize, f: impl FnOnce()) -> (f64, f64) {
    let (wall, cpu) = (Instant::now(), thread_cpu_seconds());
    f();
    let cpu = (thread_cpu_seconds() - cpu).max(1.0 / TICKS_PER_SECOND);
    (n as f64 / wall.elapsed().as_secs_f64(), n as f64 / cpu)
}

/// `mujoco-testspeed` on `file` for `nstep` simulator steps on one thread: its own steps per
/// (wall) second, and steps per CPU second from the CPU time of the process, read as the
/// children's time of the shell that waited for it.
fn testspeed(file: &str, nstep: usize) -> Option<(f64, f64)> {
    let script = format!("mujoco-testspeed '{file}' {nstep} 1 0.01 && cat /proc/$$/stat");
    let out = Command::new("sh").args(["-c", &script]).output().ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("Steps per second"))?;
    let wall: f64 = line.split(':').nth(1)?.trim().parse().ok()?;
    let f = stat_fields(text.lines().last()?);
    let cpu = (f[13] + f[14]) / TICKS_PER_SECOND;
    Some((wall, nstep as f64 / cpu))
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
fn wrapper_loop<T: Task>(nstep: usize) {
    let model = Arc::new(Model::from_xml_str(T::MJCF).expect("model"));
    let ranges: Vec<[f64; 2]> = model.actuator_ctrlrange().to_vec();
    let mut data = Data::new(model).expect("data");
    for i in 0..nstep {
        for (j, (c, [lo, hi])) in data.ctrl_mut().iter_mut().zip(&ranges).enumerate() {
            *c = (hi + lo) / 2.0 + 0.01 * (hi - lo) / 2.0 * (2.0 * halton(i, j + 2) - 1.0);
        }
        data.step();
    }
}

/// Our environment driven with testspeed's controls (as in [`wrapper_loop`], one control
/// per env step), resetting when an episode ends: the env layer on the states testspeed visits.
fn env_testspeed_controls<T: Task>(env: &mut MujocoEnv<T>, steps: usize) {
    let ranges: Vec<[f64; 2]> = env.data().model().actuator_ctrlrange().to_vec();
    let mut obs = vec![0.0; T::OBS_DIM];
    let mut action = vec![0.0f32; ranges.len()];
    env.reset(Some(0), &mut obs);
    for i in 0..steps {
        for (j, (a, [lo, hi])) in action.iter_mut().zip(&ranges).enumerate() {
            *a = ((hi + lo) / 2.0 + 0.01 * (hi - lo) / 2.0 * (2.0 * halton(i, j + 2) - 1.0)) as f32;
        }
        if env.step(Action::Continuous(&action), &mut obs).done() {
            env.reset(None, &mut obs);
        }
    }
}

fn bench<T: Task>(file: &str, seconds: f64) {
    if std::env::var("APO_BENCH_ONLY").is_ok_and(|only| !only.split(',').any(|n| n == T::NAME)) {
        return;
    }
    let path = format!("{}/assets/{file}", env!("CARGO_MANIFEST_DIR"));
    // Calibrate: env steps that take about `seconds` of CPU.
    let mut env = MujocoEnv::<T>::make().expect("MuJoCo env");
    let (_, probe) = rates(2000, || {
        steps_per_second(&mut env, 2000, 0);
    });
    let steps = ((probe * seconds) as usize).max(2000);
    let nstep = steps * T::FRAME_SKIP;
    let fs = T::FRAME_SKIP as f64;
    let (mut env_wall, mut env_cpu, mut raw_wall, mut raw_cpu, mut wrapper_cpu, mut env_ts_cpu) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for round in 0..ROUNDS {
        let mut wall = 0.0;
        let (_, cpu) = rates(steps, || wall = steps_per_second(&mut env, steps, round));
        (env_wall, env_cpu) = (env_wall.max(wall), env_cpu.max(cpu));
        let (w, c) = testspeed(&path, nstep).unwrap_or((f64::NAN, f64::NAN));
        (raw_wall, raw_cpu) = (raw_wall.max(w / fs), raw_cpu.max(c / fs));
        let (_, c) = rates(nstep, || wrapper_loop::<T>(nstep));
        wrapper_cpu = wrapper_cpu.max(c / fs);
        let (_, c) = rates(steps, || env_testspeed_controls(&mut env, steps));
        env_ts_cpu = env_ts_cpu.max(c);
    }
    let r = |x: f64| x / raw_cpu;
    println!(
        "{:24} {:>3} {:>7} | {:>8.0} {:>8.0} {:>5.2} | {:>8.0} {:>5.2} | {:>8.0} {:>5.2} | {:>8.0} {:>8.0} {:>5.2}",
        T::NAME,
        T::FRAME_SKIP,
        steps,
        raw_cpu,
        env_cpu,
        r(env_cpu),
        env_ts_cpu,
        r(env_ts_cpu),
        wrapper_cpu,
        r(wrapper_cpu),
        raw_wall,
        env_wall,
        env_wall / raw_wall,
    );
}

#[test]
#[ignore = "benchmark: run explicitly with --ignored --nocapture in release mode"]
fn env_steps_per_second_vs_raw_mujoco() {
    let seconds = std::env::var("APO_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.0);
    println!("about {seconds} s per measurement, best of {ROUNDS} interleaved rounds; rates in env steps/s");
    println!(
        "{:24} {:>3} {:>7} | {:^66} | {:^23}",
        "", "", "", "per CPU second", "per wall second"
    );
    println!(
        "{:24} {:>3} {:>7} | {:>8} {:>8} {:>5} | {:>8} {:>5} | {:>8} {:>5} | {:>8} {:>8} {:>5}",
        "env",
        "fs",
        "steps",
        "raw/fs",
        "env",
        "ratio",
        "env(ts)",
        "ratio",
        "wrap/fs",
        "ratio",
        "raw/fs",
        "env",
        "ratio"
    );
    bench::<InvertedPendulum>("inverted_pendulum.xml", seconds);
    bench::<InvertedDoublePendulum>("inverted_double_pendulum.xml", seconds);
    bench::<Reacher>("reacher.xml", seconds);
    bench::<Swimmer>("swimmer.xml", seconds);
    bench::<Hopper>("hopper.xml", seconds);
    bench::<HalfCheetah>("half_cheetah.xml", seconds);
    bench::<Walker2d>("walker2d.xml", seconds);
    bench::<Ant>("ant.xml", seconds);
    bench::<Humanoid>("humanoid.xml", seconds);
    bench::<HumanoidStandup>("humanoid.xml", seconds);
}
