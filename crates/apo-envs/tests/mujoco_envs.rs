//! The MuJoCo tasks: sizes, observation layouts, rewards and termination on constructed
//! states (expected values computed here by hand), determinism, instability handling and
//! registration. Needs Debian's `libmujoco-dev` (MuJoCo 2.2.2).

use apo_envs::mujoco::tasks::{
    Ant, HalfCheetah, Hopper, Humanoid, HumanoidStandup, InvertedDoublePendulum, InvertedPendulum,
    Reacher, Swimmer, Walker2d,
};
use apo_envs::mujoco::{MujocoEnv, ObjKind, Task};
use apo_envs::throughput::steps_per_second;
use apo_envs::{registry, Action, Env, Space, Transition};
use rand::{Rng, SeedableRng};

fn make<T: Task>() -> MujocoEnv<T> {
    MujocoEnv::<T>::make().unwrap_or_else(|e| panic!("{}: {e}", T::NAME))
}

fn obs_of<T: Task>(env: &MujocoEnv<T>) -> Vec<f32> {
    let mut obs = vec![0.0; T::OBS_DIM];
    env.observe(&mut obs);
    obs
}

fn step<T: Task>(env: &mut MujocoEnv<T>, action: &[f32]) -> (Transition, Vec<f32>) {
    let mut obs = vec![0.0; T::OBS_DIM];
    let t = env.step(Action::Continuous(action), &mut obs);
    (t, obs)
}

/// Sets `qpos`, `qvel` (both from the initial configuration with the given overrides).
fn set<T: Task>(env: &mut MujocoEnv<T>, qpos: &[(usize, f64)], qvel: &[(usize, f64)]) {
    let model = env.data().model();
    let mut q = model.qpos0().to_vec();
    let mut v = vec![0.0; model.nv()];
    for &(i, x) in qpos {
        q[i] = x;
    }
    for &(i, x) in qvel {
        v[i] = x;
    }
    env.set_state(&q, &v);
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

fn sum_sq(a: &[f32]) -> f64 {
    a.iter().map(|&x| f64::from(x).powi(2)).sum()
}

fn assert_prefix(obs: &[f32], values: &[f64], what: &str) {
    for (i, (o, v)) in obs.iter().zip(values).enumerate() {
        assert!(
            (f64::from(*o) - v).abs() <= 1e-6 * (1.0 + v.abs()),
            "{what}[{i}]: {o} vs {v}"
        );
    }
}

/// Checks the documented sizes of task `T`: model sizes, observation and action dimension,
/// action bounds and step duration.
fn check_sizes<T: Task>(nq: usize, nv: usize, nu: usize, obs: usize, ctrl: (f32, f32), dt: f64) {
    let mut env = make::<T>();
    let model = env.data().model();
    assert_eq!(
        (model.nq(), model.nv(), model.nu()),
        (nq, nv, nu),
        "{}",
        T::NAME
    );
    assert_eq!(env.observation_space().flat_dim(), obs, "{}", T::NAME);
    assert_eq!(
        env.action_space(),
        &Space::uniform_box(nu, ctrl.0, ctrl.1),
        "{}",
        T::NAME
    );
    assert!(
        close(env.dt(), dt, 1e-12),
        "{}: dt {} vs {dt}",
        T::NAME,
        env.dt()
    );
    let mut o = vec![0.0; obs];
    env.reset(Some(0), &mut o);
    assert!(o.iter().all(|x| x.is_finite()), "{}", T::NAME);
}

#[test]
fn every_task_has_the_documented_sizes() {
    check_sizes::<InvertedPendulum>(2, 2, 1, 4, (-3.0, 3.0), 0.04);
    check_sizes::<InvertedDoublePendulum>(3, 3, 1, 11, (-1.0, 1.0), 0.05);
    check_sizes::<Reacher>(4, 4, 2, 11, (-1.0, 1.0), 0.02);
    check_sizes::<Swimmer>(5, 5, 2, 8, (-1.0, 1.0), 0.04);
    check_sizes::<Hopper>(6, 6, 3, 11, (-1.0, 1.0), 0.008);
    check_sizes::<HalfCheetah>(9, 9, 6, 17, (-1.0, 1.0), 0.05);
    check_sizes::<Walker2d>(9, 9, 6, 17, (-1.0, 1.0), 0.008);
    check_sizes::<Ant>(15, 14, 8, 27, (-1.0, 1.0), 0.05);
    check_sizes::<Humanoid>(24, 23, 17, 376, (-0.4, 0.4), 0.015);
    check_sizes::<HumanoidStandup>(24, 23, 17, 376, (-0.4, 0.4), 0.015);
}

#[test]
fn the_suite_is_registered_with_time_limits_and_unit_actions() {
    let expected = [
        ("InvertedPendulum-v4", 4, 1, 1000),
        ("InvertedDoublePendulum-v4", 11, 1, 1000),
        ("Reacher-v4", 11, 2, 50),
        ("Swimmer-v4", 8, 2, 1000),
        ("Hopper-v4", 11, 3, 1000),
        ("HalfCheetah-v4", 17, 6, 1000),
        ("Walker2d-v4", 17, 6, 1000),
        ("Ant-v4", 27, 8, 1000),
        ("Humanoid-v4", 376, 17, 1000),
        ("HumanoidStandup-v4", 376, 17, 1000),
    ];
    for (name, obs, act, limit) in expected {
        let spec = registry::spec(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            (
                spec.observation_dim,
                spec.action_space.clone(),
                spec.max_episode_steps
            ),
            (obs, Space::uniform_box(act, -1.0, 1.0), limit),
            "{name}"
        );
        // The short name resolves too.
        let short = name.trim_end_matches("-v4");
        assert_eq!(registry::spec(short).unwrap().name, name);
    }
    // HalfCheetah never terminates: the registered env is cut at 1000 steps.
    let mut env = registry::make("HalfCheetah").unwrap();
    let mut obs = vec![0.0; 17];
    env.reset(Some(3), &mut obs);
    let mut steps = 0;
    loop {
        steps += 1;
        let t = env.step(
            Action::Continuous(&[1.0, -1.0, 0.5, -0.5, 0.0, 1.0]),
            &mut obs,
        );
        if t.done() {
            assert!(t.truncated && !t.terminated, "{t:?}");
            break;
        }
    }
    assert_eq!(steps, 1000);
}

#[test]
fn inverted_pendulum_reward_and_termination() {
    let mut env = make::<InvertedPendulum>();
    set(&mut env, &[(0, 0.1), (1, 0.05)], &[(0, -0.2), (1, 0.3)]);
    assert_eq!(obs_of(&env), vec![0.1, 0.05, -0.2, 0.3]);
    let (t, obs) = step(&mut env, &[0.0]);
    assert_eq!(
        (t.reward, t.terminated, t.truncated, t.info.unstable),
        (1.0, false, false, false)
    );
    assert_prefix(&obs, env.data().qpos(), "qpos");
    // A pole leaning 0.3 rad only falls further: terminated.
    set(&mut env, &[(1, 0.3)], &[]);
    let (t, _) = step(&mut env, &[0.0]);
    assert!(t.terminated && !t.info.unstable, "{t:?}");
    assert_eq!(t.reward, 1.0);
}

#[test]
fn inverted_double_pendulum_reward_and_termination() {
    let mut env = make::<InvertedDoublePendulum>();
    let tip = env.data().model().id(ObjKind::Site, "tip").unwrap();
    // Upright and still: the tip is 2 × 0.6 m above the cart.
    set(&mut env, &[], &[]);
    assert_eq!(env.data().site_xpos()[tip], [0.0, 0.0, 1.2]);
    // Angles 0.3 and -0.5: the tip is at (0.6 sin 0.3 + 0.6 sin(-0.2), 0.6 cos 0.3 + 0.6 cos(-0.2)).
    set(
        &mut env,
        &[(0, 0.25), (1, 0.3), (2, -0.5)],
        &[(1, 2.0), (2, 20.0)],
    );
    let [x, _, z] = env.data().site_xpos()[tip];
    assert!(
        close(x, 0.25 + 0.6 * 0.3f64.sin() + 0.6 * (-0.2f64).sin(), 1e-12),
        "{x}"
    );
    assert!(
        close(z, 0.6 * 0.3f64.cos() + 0.6 * (-0.2f64).cos(), 1e-12),
        "{z}"
    );
    let obs = obs_of(&env);
    let qfrc = env.data().qfrc_constraint().to_vec();
    let expected = [
        0.25,
        0.3f64.sin(),
        (-0.5f64).sin(),
        0.3f64.cos(),
        (-0.5f64).cos(),
        0.0,
        2.0,
        10.0, // clipped from 20
        qfrc[0].clamp(-10.0, 10.0),
        qfrc[1].clamp(-10.0, 10.0),
        qfrc[2].clamp(-10.0, 10.0),
    ];
    assert_prefix(&obs, &expected, "obs");
    // The reward of a step, from the state after it.
    let (t, _) = step(&mut env, &[0.3]);
    let [x, _, y] = env.data().site_xpos()[tip];
    let (v1, v2) = (env.data().qvel()[1], env.data().qvel()[2]);
    let expected = 10.0 - (0.01 * x * x + (y - 2.0).powi(2)) - (1e-3 * v1 * v1 + 5e-3 * v2 * v2);
    assert!(
        close(t.reward, expected, 1e-12),
        "{} vs {expected}",
        t.reward
    );
    assert_eq!(t.terminated, y <= 1.0);
    assert!(
        t.terminated,
        "the poles at 0.3 and -0.2 rad put the tip at {y} <= 1"
    );
    // Upright and still: 10 - (1.2 - 2)² = 9.36, not terminated.
    set(&mut env, &[], &[]);
    let (t, _) = step(&mut env, &[0.0]);
    assert!(close(t.reward, 9.36, 1e-4) && !t.terminated, "{t:?}");
}

#[test]
fn reacher_reward_uses_the_distance_before_the_step() {
    let mut env = make::<Reacher>();
    // Arm straight along x: fingertip at (0.1 + 0.11, 0); target at (0.1, 0.1).
    set(
        &mut env,
        &[(0, 0.0), (1, 0.0), (2, 0.1), (3, 0.1)],
        &[(0, 0.5), (1, -0.25)],
    );
    let obs = obs_of(&env);
    assert_prefix(
        &obs,
        &[1.0, 1.0, 0.0, 0.0, 0.1, 0.1, 0.5, -0.25, 0.11, -0.1, 0.0],
        "obs",
    );
    let action = [0.5f32, -0.5];
    let (t, _) = step(&mut env, &action);
    let expected = -(0.11f64.powi(2) + 0.1f64.powi(2)).sqrt() - 0.5;
    assert!(
        close(t.reward, expected, 1e-9),
        "{} vs {expected}",
        t.reward
    );
    assert!(!t.terminated);
    // Bent arm: fingertip at (0.1 cos a + 0.11 cos(a + b), 0.1 sin a + 0.11 sin(a + b)).
    let (a, b) = (0.3f64, -0.9f64);
    set(&mut env, &[(0, a), (1, b), (2, -0.05), (3, 0.12)], &[]);
    let tip = [
        0.1 * a.cos() + 0.11 * (a + b).cos(),
        0.1 * a.sin() + 0.11 * (a + b).sin(),
    ];
    let obs = obs_of(&env);
    let expected = [
        a.cos(),
        b.cos(),
        a.sin(),
        b.sin(),
        -0.05,
        0.12,
        0.0,
        0.0,
        tip[0] + 0.05,
        tip[1] - 0.12,
        0.0,
    ];
    assert_prefix(&obs, &expected, "obs");
}

#[test]
fn reacher_targets_lie_in_the_disc_of_radius_0_2() {
    let mut env = make::<Reacher>();
    let mut obs = vec![0.0; 11];
    for seed in 0..50 {
        env.reset(Some(seed), &mut obs);
        let q = env.data().qpos();
        assert!(q[2].hypot(q[3]) < 0.2, "seed {seed}: target {:?}", &q[2..]);
        assert_eq!(
            &env.data().qvel()[2..],
            &[0.0, 0.0],
            "the target does not move"
        );
        assert!(q[0].abs() <= 0.1 && q[1].abs() <= 0.1);
    }
}

/// Checks `reward = weight·Δx/dt + alive − ctrl_weight·Σa²` for a planar runner whose
/// progress is `qpos[0]`, from a reset state.
fn check_forward_reward<T: Task>(weight: f64, alive: f64, ctrl_weight: f64, seed: u64) {
    let mut env = make::<T>();
    let mut obs = vec![0.0; T::OBS_DIM];
    env.reset(Some(seed), &mut obs);
    let nu = env.data().model().nu();
    let action: Vec<f32> = (0..nu).map(|i| 0.8 - 0.3 * i as f32).collect();
    for _ in 0..5 {
        let x0 = env.data().qpos()[0];
        let (t, _) = step(&mut env, &action);
        let dx = env.data().qpos()[0] - x0;
        let expected = weight * dx / env.dt() + alive - ctrl_weight * sum_sq(&action);
        assert!(
            close(t.reward, expected, 1e-9),
            "{}: {} vs {expected}",
            T::NAME,
            t.reward
        );
        assert!(dx != 0.0, "{}: the body moved", T::NAME);
    }
}

#[test]
fn planar_runners_reward_forward_progress_minus_control_cost() {
    check_forward_reward::<Swimmer>(1.0, 0.0, 1e-4, 1);
    check_forward_reward::<HalfCheetah>(1.0, 0.0, 0.1, 2);
    check_forward_reward::<Hopper>(1.0, 1.0, 1e-3, 3);
    check_forward_reward::<Walker2d>(1.0, 1.0, 1e-3, 4);
}

#[test]
fn planar_runner_observations_drop_x_and_clip_velocities() {
    let mut env = make::<Hopper>();
    set(
        &mut env,
        &[(0, 3.0), (1, 1.1), (2, 0.1), (3, -0.4)],
        &[(0, 1.0), (1, -20.0), (5, 15.0)],
    );
    let obs = obs_of(&env);
    assert_prefix(
        &obs,
        &[1.1, 0.1, -0.4, 0.0, 0.0, 1.0, -10.0, 0.0, 0.0, 0.0, 10.0],
        "hopper obs",
    );

    let mut env = make::<Walker2d>();
    set(
        &mut env,
        &[(0, 3.0), (1, 1.2), (8, 0.3)],
        &[(2, 11.0), (8, -1.0)],
    );
    let obs = obs_of(&env);
    let expected = [
        1.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 10.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0,
    ];
    assert_prefix(&obs, &expected, "walker obs");

    let mut env = make::<HalfCheetah>();
    set(&mut env, &[(0, 3.0), (1, 0.1)], &[(0, 25.0)]);
    let obs = obs_of(&env);
    assert_prefix(
        &obs,
        &[0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25.0],
        "cheetah obs (no clipping)",
    );

    let mut env = make::<Swimmer>();
    set(
        &mut env,
        &[(0, 3.0), (1, 2.0), (2, 0.5), (3, 0.2)],
        &[(1, 0.7)],
    );
    let obs = obs_of(&env);
    assert_prefix(
        &obs,
        &[0.5, 0.2, 0.0, 0.0, 0.7, 0.0, 0.0, 0.0],
        "swimmer obs",
    );
}

#[test]
fn hopper_health_follows_the_published_ranges() {
    let mut env = make::<Hopper>();
    type Overrides = &'static [(usize, f64)];
    let cases: [(Overrides, Overrides, bool); 8] = [
        (&[], &[], true),
        (&[(1, 0.71)], &[], true),
        (&[(1, 0.69)], &[], false),
        (&[(2, 0.19)], &[], true),
        (&[(2, -0.21)], &[], false),
        (&[(4, 99.0)], &[], true),
        (&[], &[(3, 100.5)], false),
        (&[], &[(0, 200.0)], false), // qvel[0] is part of state_vector()[2..]
    ];
    for (qpos, qvel, healthy) in cases {
        set(&mut env, qpos, qvel);
        assert_eq!(
            Hopper::is_healthy(env.data()),
            healthy,
            "qpos {qpos:?} qvel {qvel:?}"
        );
    }
    // A step from a tilted torso ends the episode (and still pays the healthy reward).
    set(&mut env, &[(2, 0.25)], &[]);
    let (t, _) = step(&mut env, &[0.0; 3]);
    assert!(t.terminated && !t.info.unstable && t.reward > 0.0, "{t:?}");
}

#[test]
fn walker_health_follows_the_published_ranges() {
    let mut env = make::<Walker2d>();
    for (z, angle, healthy) in [
        (1.25, 0.0, true),
        (0.81, 0.0, true),
        (0.79, 0.0, false),
        (2.01, 0.0, false),
        (1.25, 0.99, true),
        (1.25, -1.01, false),
    ] {
        set(&mut env, &[(1, z), (2, angle)], &[]);
        assert_eq!(
            Walker2d::is_healthy(env.data()),
            healthy,
            "z {z} angle {angle}"
        );
    }
    set(&mut env, &[(2, 1.2)], &[]);
    assert!(step(&mut env, &[0.0; 6]).0.terminated);
    set(&mut env, &[], &[]);
    assert!(!step(&mut env, &[0.0; 6]).0.terminated);
}

#[test]
fn ant_reward_and_termination() {
    let mut env = make::<Ant>();
    let torso = env.data().model().id(ObjKind::Body, "torso").unwrap();
    set(&mut env, &[(0, 0.3)], &[(0, 1.0), (1, 0.5)]);
    let obs = obs_of(&env);
    let q = env.data().qpos().to_vec();
    assert_prefix(&obs, &q[2..], "qpos[2..]");
    assert_prefix(&obs[13..], &[1.0, 0.5], "qvel");
    let x0 = env.data().xpos()[torso][0];
    assert_eq!(x0, 0.3);
    let action = [0.2f32, -0.4, 0.6, -0.8, 1.0, 0.0, 0.1, -0.1];
    let (t, _) = step(&mut env, &action);
    let x1 = env.data().xpos()[torso][0];
    let expected = (x1 - x0) / 0.05 + 1.0 - 0.5 * sum_sq(&action);
    assert!(
        close(t.reward, expected, 1e-9),
        "{} vs {expected}",
        t.reward
    );
    assert!(!t.terminated);
    // Above the healthy range (z > 1 after the step): terminated.
    set(&mut env, &[(2, 1.3)], &[]);
    let (t, _) = step(&mut env, &[0.0; 8]);
    assert!(t.terminated && env.data().qpos()[2] > 1.0, "{t:?}");
}

fn mass_center_x<T: Task>(env: &MujocoEnv<T>) -> f64 {
    let model = env.data().model();
    let total: f64 = model.body_mass().iter().sum();
    model
        .body_mass()
        .iter()
        .zip(env.data().xipos())
        .map(|(m, p)| m * p[0])
        .sum::<f64>()
        / total
}

#[test]
fn humanoid_reward_observation_and_termination() {
    let mut env = make::<Humanoid>();
    let mut obs = vec![0.0; 376];
    env.reset(Some(7), &mut obs);
    let data = env.data();
    assert_prefix(&obs, &data.qpos()[2..], "qpos[2..]");
    assert_prefix(&obs[22..], data.qvel(), "qvel");
    let cinert: Vec<f64> = data.cinert().iter().flatten().copied().collect();
    assert_prefix(&obs[45..], &cinert, "cinert");
    let cvel: Vec<f64> = data.cvel().iter().flatten().copied().collect();
    assert_prefix(&obs[185..], &cvel, "cvel");
    assert_prefix(&obs[269..], data.qfrc_actuator(), "qfrc_actuator");
    let action: Vec<f32> = (0..17).map(|i| 0.4 * ((i % 3) as f32 - 1.0)).collect();
    let x0 = mass_center_x(&env);
    let (t, obs) = step(&mut env, &action);
    let x1 = mass_center_x(&env);
    let expected = 1.25 * (x1 - x0) / 0.015 + 5.0 - 0.1 * sum_sq(&action);
    assert!(
        close(t.reward, expected, 1e-9),
        "{} vs {expected}",
        t.reward
    );
    assert!(!t.terminated);
    // Once the feet land, the contact forces are computed and observed.
    let mut obs = obs;
    for _ in 0..20 {
        obs = step(&mut env, &[0.0; 17]).1;
    }
    let cfrc: Vec<f64> = env.data().cfrc_ext().iter().flatten().copied().collect();
    assert_prefix(&obs[292..], &cfrc, "cfrc_ext");
    assert!(
        cfrc.iter().any(|&f| f.abs() > 1.0),
        "the feet touch the floor: {cfrc:?}"
    );
    // Torso below 1 m: terminated.
    set(&mut env, &[(2, 0.9)], &[]);
    assert!(step(&mut env, &[0.0; 17]).0.terminated);
}

#[test]
fn humanoid_standup_starts_lying_and_rewards_height() {
    let mut env = make::<HumanoidStandup>();
    let mut obs = vec![0.0; 376];
    env.reset(Some(5), &mut obs);
    let q = env.data().qpos();
    assert!((q[2] - 0.105).abs() <= 0.01, "torso height {}", q[2]);
    let s = std::f64::consts::FRAC_1_SQRT_2;
    for (i, want) in [(3, s), (4, 0.0), (5, -s), (6, 0.0)] {
        assert!(
            (q[i] - want).abs() <= 0.011,
            "lying quaternion {:?}",
            &q[3..7]
        );
    }
    let action = [0.3f32; 17];
    for _ in 0..10 {
        let (t, _) = step(&mut env, &action);
        let data = env.data();
        let impact: f64 = data.cfrc_ext().iter().flatten().map(|f| f * f).sum::<f64>() * 0.5e-6;
        let expected = data.qpos()[2] / 0.003 - 0.1 * sum_sq(&action) - impact.min(10.0) + 1.0;
        assert!(
            close(t.reward, expected, 1e-9),
            "{} vs {expected}",
            t.reward
        );
        assert!(!t.terminated);
    }
}

fn rollout(name: &str, seed: u64, steps: usize) -> (Vec<Vec<f32>>, Vec<f64>) {
    let mut env = registry::make(name).unwrap();
    let dim = env.observation_space().flat_dim();
    let Space::Box { low, .. } = env.action_space().clone() else {
        panic!("{name}: box actions")
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(99);
    let mut obs = vec![0.0; dim];
    env.reset(Some(seed), &mut obs);
    let (mut observations, mut rewards) = (vec![obs.clone()], vec![]);
    for _ in 0..steps {
        let action: Vec<f32> = low.iter().map(|_| rng.random_range(-1.0..=1.0)).collect();
        let t = env.step(Action::Continuous(&action), &mut obs);
        observations.push(obs.clone());
        rewards.push(t.reward);
        if t.done() {
            env.reset(None, &mut obs);
            observations.push(obs.clone());
        }
    }
    (observations, rewards)
}

#[test]
fn the_same_seed_gives_the_same_trajectory() {
    for name in [
        "InvertedPendulum",
        "InvertedDoublePendulum",
        "Reacher",
        "Swimmer",
        "Hopper",
        "HalfCheetah",
        "Walker2d",
        "Ant",
        "Humanoid",
        "HumanoidStandup",
    ] {
        let a = rollout(name, 11, 120);
        let b = rollout(name, 11, 120);
        assert_eq!(a, b, "{name}: same seed, same trajectory");
        let c = rollout(name, 12, 1);
        assert_ne!(a.0[0], c.0[0], "{name}: another seed, another start");
    }
}

#[test]
fn unseeded_resets_continue_the_random_stream() {
    let mut env = make::<Hopper>();
    let mut first = vec![0.0; 11];
    let mut second = vec![0.0; 11];
    env.reset(Some(1), &mut first);
    env.reset(None, &mut second);
    assert_ne!(first, second);
    env.reset(Some(1), &mut second);
    assert_eq!(first, second);
}

#[test]
fn a_nan_state_ends_the_episode_as_unstable_without_panicking() {
    let mut env = make::<Hopper>();
    let mut obs = vec![0.0; 11];
    env.reset(Some(0), &mut obs);
    set(&mut env, &[], &[(0, f64::NAN)]);
    let (t, obs) = step(&mut env, &[0.0; 3]);
    assert!(t.terminated && t.info.unstable && !t.truncated, "{t:?}");
    assert_eq!(t.reward, 0.0);
    assert!(obs.iter().all(|x| x.is_finite()), "{obs:?}");
    // The next episode is normal.
    let mut obs = vec![0.0; 11];
    env.reset(Some(0), &mut obs);
    let (t, _) = step(&mut env, &[0.0; 3]);
    assert!(!t.done() && !t.info.unstable, "{t:?}");
}

#[test]
fn huge_velocities_and_nan_actions_are_unstable_too() {
    let mut env = make::<Humanoid>();
    set(&mut env, &[], &[(6, 1e12)]);
    let (t, obs) = step(&mut env, &[0.0; 17]);
    assert!(t.terminated && t.info.unstable, "{t:?}");
    assert!(obs.iter().all(|x| x.is_finite()));

    let mut env = make::<HalfCheetah>();
    let mut obs = vec![0.0; 17];
    env.reset(Some(0), &mut obs);
    let (t, obs) = step(&mut env, &[f32::NAN, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert!(t.terminated && t.info.unstable, "{t:?}");
    assert_eq!(t.reward, 0.0);
    assert!(obs.iter().all(|x| x.is_finite()));
}

#[test]
fn random_play_is_stable_in_every_task() {
    for spec in registry::list()
        .into_iter()
        .filter(|s| s.name.ends_with("-v4"))
    {
        let mut env = registry::make(&spec.name).unwrap();
        let mut obs = vec![0.0; spec.observation_dim];
        let mut rng = rand::rngs::StdRng::seed_from_u64(0);
        env.reset(Some(0), &mut obs);
        for _ in 0..1500 {
            let action: Vec<f32> = (0..spec.action_space.flat_dim())
                .map(|_| rng.random_range(-1.0..=1.0))
                .collect();
            let t = env.step(Action::Continuous(&action), &mut obs);
            assert!(
                !t.info.unstable,
                "{}: unstable under random actions",
                spec.name
            );
            assert!(
                t.reward.is_finite() && obs.iter().all(|x| x.is_finite()),
                "{}",
                spec.name
            );
            if t.done() {
                env.reset(None, &mut obs);
            }
        }
    }
}

#[test]
fn the_benchmark_helper_counts_steps_per_second() {
    let mut env = registry::make("InvertedPendulum").unwrap();
    let rate = steps_per_second(env.as_mut(), 2000, 0);
    assert!(rate.is_finite() && rate > 100.0, "{rate}");
    assert_eq!(steps_per_second(env.as_mut(), 0, 0), 0.0);
}

/// Mean return and length over 20 episodes of the uniform random policy (actions in [-1, 1]).
fn random_policy_score(name: &str) -> (f64, f64) {
    let mut env = registry::make(name).unwrap();
    let dim = env.action_space().flat_dim();
    let mut obs = vec![0.0; env.observation_space().flat_dim()];
    let mut rng = rand::rngs::StdRng::seed_from_u64(0);
    let (mut ret, mut len) = (0.0, 0.0);
    for episode in 0..20 {
        env.reset(Some(episode), &mut obs);
        loop {
            let action: Vec<f32> = (0..dim).map(|_| rng.random_range(-1.0..=1.0)).collect();
            let t = env.step(Action::Continuous(&action), &mut obs);
            ret += t.reward;
            len += 1.0;
            if t.done() {
                break;
            }
        }
    }
    (ret / 20.0, len / 20.0)
}

/// The models are ours, not Gymnasium's: a uniform random policy must still score what it
/// scores on Gymnasium's versions (HalfCheetah ≈ −280, Hopper ≈ 18 in ≈ 20 steps,
/// Walker2d ≈ 2, Humanoid ≈ 120 in ≈ 23 steps, Reacher ≈ −43, InvertedPendulum ≈ 6 steps).
#[test]
fn random_policy_scores_match_gymnasiums() {
    let bands = [
        ("InvertedPendulum", (3.0, 12.0), (3.0, 12.0)),
        ("Reacher", (-50.0, -38.0), (50.0, 50.0)),
        ("Hopper", (8.0, 30.0), (10.0, 35.0)),
        ("Walker2d", (-8.0, 12.0), (8.0, 40.0)),
        ("HalfCheetah", (-350.0, -220.0), (1000.0, 1000.0)),
        ("Humanoid", (80.0, 160.0), (16.0, 32.0)),
    ];
    for (name, (r_lo, r_hi), (l_lo, l_hi)) in bands {
        let (ret, len) = random_policy_score(name);
        assert!(
            (r_lo..=r_hi).contains(&ret),
            "{name}: mean random return {ret} outside [{r_lo}, {r_hi}]"
        );
        assert!(
            (l_lo..=l_hi).contains(&len),
            "{name}: mean random episode length {len} outside [{l_lo}, {l_hi}]"
        );
    }
}
