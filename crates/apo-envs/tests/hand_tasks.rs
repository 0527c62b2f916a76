//! The Shadow-hand tasks (HandReach, HandManipulateBlock, HandManipulateEgg, dense rewards):
//! sizes against Gymnasium-Robotics', observation layouts, rewards and success on constructed
//! states (expected values computed here by hand), goal sampling over many resets, a scripted
//! hand that holds its pose reaching its own fingertips, determinism, stability and instability
//! handling, and registration. Needs Debian's `libmujoco-dev` (MuJoCo 2.2.2). Facts: docs/hand.md.

use std::f64::consts::{FRAC_1_SQRT_2, FRAC_PI_2, TAU};

use apo_envs::mujoco::hand::{
    HandEnv, HandObservation, HandTask, ACTUATORS, JOINTS, MEETING_GAP, MEETING_OFFSET,
    PALM_HEIGHT, REACH_INITIAL_QPOS, TARGET_POSITION_RANGE,
};
use apo_envs::{registry, Action, Env, Space, Transition};
use rand::{Rng, SeedableRng};

/// Gymnasium-Robotics' observation widths (`observation`, then `observation ‖ desired_goal`)
/// and registered time limits.
const SIZES: [(&str, HandTask, HandObservation, usize, usize); 6] = [
    (
        "HandReachDense-v3",
        HandTask::Reach,
        HandObservation::Paper,
        63,
        50,
    ),
    (
        "HandReachDenseGoal-v3",
        HandTask::Reach,
        HandObservation::GoalConditioned,
        78,
        50,
    ),
    (
        "HandManipulateBlockDense-v1",
        HandTask::Block,
        HandObservation::Paper,
        61,
        100,
    ),
    (
        "HandManipulateBlockDenseGoal-v1",
        HandTask::Block,
        HandObservation::GoalConditioned,
        68,
        100,
    ),
    (
        "HandManipulateEggDense-v1",
        HandTask::Egg,
        HandObservation::Paper,
        61,
        100,
    ),
    (
        "HandManipulateEggDenseGoal-v1",
        HandTask::Egg,
        HandObservation::GoalConditioned,
        68,
        100,
    ),
];

/// The `qpos` (and `qvel`) address of `object:joint` in the manipulate scenes.
const OBJECT: usize = 24;

fn make(task: HandTask, observation: HandObservation) -> HandEnv {
    HandEnv::new(task, observation)
        .unwrap_or_else(|e| panic!("{}: {e}", task.registered_name(observation)))
}

fn obs_dim(env: &HandEnv) -> usize {
    env.observation_space().flat_dim()
}

fn reset(env: &mut HandEnv, seed: u64) -> Vec<f32> {
    let mut obs = vec![0.0; obs_dim(env)];
    env.reset(Some(seed), &mut obs);
    obs
}

fn step(env: &mut HandEnv, action: &[f32]) -> (Transition, Vec<f32>) {
    let mut obs = vec![0.0; obs_dim(env)];
    let t = env.step(Action::Continuous(action), &mut obs);
    (t, obs)
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

fn assert_block(obs: &[f32], values: &[f64], what: &str) {
    assert_eq!(obs.len(), values.len(), "{what}");
    for (i, (o, v)) in obs.iter().zip(values).enumerate() {
        assert!(
            (f64::from(*o) - v).abs() <= 1e-6 * (1.0 + v.abs()),
            "{what}[{i}]: {o} vs {v}"
        );
    }
}

/// The absolute-control action whose servo targets are the hand joint positions `qpos`
/// (`[24]`): `a = 2·(q − lo)/(hi − lo) − 1` per actuator.
fn hold_action(env: &HandEnv, qpos: &[f64]) -> Vec<f32> {
    let ranges = env.data().model().actuator_ctrlrange();
    ACTUATORS
        .iter()
        .zip(ranges)
        .map(|(name, &[lo, hi])| {
            let j = JOINTS
                .iter()
                .position(|j| j == name)
                .expect("actuated joint");
            (2.0 * (qpos[j] - lo) / (hi - lo) - 1.0).clamp(-1.0, 1.0) as f32
        })
        .collect()
}

/// The manipulate scene at rest with the hand at 0 and the object at `pose` (position,
/// quaternion).
fn place_object(env: &mut HandEnv, pose: [f64; 7]) {
    let model = env.data().model();
    let mut qpos = model.qpos0().to_vec();
    let qvel = vec![0.0; model.nv()];
    qpos[OBJECT..OBJECT + 7].copy_from_slice(&pose);
    env.set_state(&qpos, &qvel).unwrap();
}

#[test]
fn observation_and_action_widths_are_gymnasium_roboticss() {
    for (name, task, observation, width, steps) in SIZES {
        assert_eq!(task.registered_name(observation), name);
        assert_eq!(task.observation_dim(observation), width, "{name}");
        assert_eq!(task.max_episode_steps(), steps, "{name}");
        let mut env = make(task, observation);
        assert_eq!(obs_dim(&env), width, "{name}");
        assert_eq!(
            *env.action_space(),
            Space::uniform_box(20, -1.0, 1.0),
            "{name}"
        );
        assert_eq!(
            env.goal().len(),
            if task == HandTask::Reach { 15 } else { 7 }
        );
        let obs = reset(&mut env, 0);
        assert!(obs.iter().all(|x| x.is_finite()), "{name}");
    }
}

#[test]
fn the_registry_has_the_six_tasks_with_their_sizes_and_limits() {
    for (name, _, _, width, steps) in SIZES {
        let spec = registry::spec(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(spec.family, "hand", "{name}");
        assert_eq!(spec.max_episode_steps, steps, "{name}");
        assert_eq!(spec.observation_dim, width, "{name}");
        assert_eq!(
            spec.action_space,
            Space::uniform_box(20, -1.0, 1.0),
            "{name}"
        );
        // The registered environment (time limit and action rescaling around it) builds and steps.
        let mut env = registry::make(name).unwrap();
        let mut obs = vec![0.0; width];
        env.reset(Some(0), &mut obs);
        let t = env.step(Action::Continuous(&[0.5; 20]), &mut obs);
        assert!(!t.done(), "{name}: {t:?}");
        assert!(obs.iter().all(|x| x.is_finite()), "{name}");
    }
}

/// Checks Reach's goal-conditioned observation `obs` against the current state.
fn check_reach_observation(env: &HandEnv, obs: &[f32]) {
    let d = env.data();
    assert_block(&obs[..24], &d.qpos()[..24], "qpos");
    assert_block(&obs[24..48], &d.qvel()[..24], "qvel");
    let tips: Vec<f64> = env.fingertips().into_iter().flatten().collect();
    assert_block(&obs[48..63], &tips, "fingertips");
    assert_block(&obs[48..63], &env.achieved_goal(), "achieved goal");
    assert_block(&obs[63..78], env.goal(), "desired goal");
}

#[test]
fn observations_are_robot_state_object_velocity_achieved_and_desired_goal() {
    let mut env = make(HandTask::Reach, HandObservation::GoalConditioned);
    let obs = reset(&mut env, 3);
    assert_eq!(&env.data().qpos()[..24], &REACH_INITIAL_QPOS[..]);
    assert!(env.data().qvel().iter().all(|&v| v == 0.0));
    check_reach_observation(&env, &obs);
    let (_, obs) = step(&mut env, &[0.2; 20]);
    check_reach_observation(&env, &obs);

    for task in [HandTask::Block, HandTask::Egg] {
        let mut env = make(task, HandObservation::GoalConditioned);
        reset(&mut env, 5);
        let (_, obs) = step(&mut env, &[-0.3; 20]);
        let d = env.data();
        assert_block(&obs[..24], &d.qpos()[..24], "qpos");
        assert_block(&obs[24..48], &d.qvel()[..24], "qvel");
        assert_block(&obs[48..54], &d.qvel()[OBJECT..OBJECT + 6], "object qvel");
        assert_block(&obs[54..61], &d.qpos()[OBJECT..OBJECT + 7], "object pose");
        assert_block(&obs[54..61], &env.achieved_goal(), "achieved goal");
        assert_block(&obs[61..68], env.goal(), "desired goal");
        // The paper's observation is the same without the desired goal.
        let mut paper = make(task, HandObservation::Paper);
        reset(&mut paper, 5);
        let (_, short) = step(&mut paper, &[-0.3; 20]);
        assert_eq!(short[..], obs[..61], "{task:?}");
    }
}

#[test]
fn reach_rewards_the_negative_fingertip_distance() {
    let mut env = make(HandTask::Reach, HandObservation::Paper);
    env.set_state(&REACH_INITIAL_QPOS, &[0.0; 24]).unwrap();
    let tips: Vec<f64> = env.fingertips().into_iter().flatten().collect();
    assert_eq!(tips, env.initial_fingertips());
    // The fingertips exactly at the goal.
    env.set_goal(&tips).unwrap();
    assert_eq!(env.dense_reward(), 0.0);
    assert!(env.is_success());
    // FF 3 cm off in x and TH 4 cm off in z: 5 cm in the 15-vector.
    let mut goal = tips.clone();
    goal[0] += 0.03;
    goal[14] -= 0.04;
    env.set_goal(&goal).unwrap();
    assert!(
        (env.dense_reward() + 0.05).abs() < 1e-12,
        "{}",
        env.dense_reward()
    );
    assert!(!env.is_success());
    // 6 mm off is a success, with reward −0.006.
    let mut goal = tips.clone();
    goal[7] += 0.006;
    env.set_goal(&goal).unwrap();
    assert!((env.dense_reward() + 0.006).abs() < 1e-12);
    assert!(env.is_success());
    // A goal of the wrong length is refused.
    assert!(env.set_goal(&tips[..14]).is_err());
}

#[test]
fn manipulate_rewards_ten_times_the_position_distance_plus_the_angle() {
    for task in [HandTask::Block, HandTask::Egg] {
        let mut env = make(task, HandObservation::Paper);
        place_object(&mut env, [1.0, 0.87, 0.2, 1.0, 0.0, 0.0, 0.0]);
        assert_eq!(env.achieved_goal(), [1.0, 0.87, 0.2, 1.0, 0.0, 0.0, 0.0]);
        // The goal is the object's pose: reward 0, success.
        env.set_goal(&[1.0, 0.87, 0.2, 1.0, 0.0, 0.0, 0.0]).unwrap();
        assert!(env.dense_reward().abs() < 1e-6);
        assert!(env.is_success());
        // 5 cm away (3, 0, 4) and a quarter turn about z: −(10·0.05 + π/2).
        let quarter_z = [FRAC_1_SQRT_2, 0.0, 0.0, FRAC_1_SQRT_2];
        let goal = [1.03, 0.87, 0.24, quarter_z[0], 0.0, 0.0, quarter_z[3]];
        env.set_goal(&goal).unwrap();
        let (d_pos, d_rot) = env.goal_distances();
        assert!((d_pos - 0.05).abs() < 1e-12, "{d_pos}");
        assert!((d_rot - FRAC_PI_2).abs() < 1e-9, "{d_rot}");
        assert!((env.dense_reward() + 0.5 + FRAC_PI_2).abs() < 1e-9);
        assert!(!env.is_success());
        // Within both thresholds: 5 mm and a turn of 0.05 rad about x.
        let (s, c) = (0.025f64).sin_cos();
        env.set_goal(&[1.0, 0.875, 0.2, c, s, 0.0, 0.0]).unwrap();
        let (d_pos, d_rot) = env.goal_distances();
        assert!((d_pos - 0.005).abs() < 1e-12 && (d_rot - 0.05).abs() < 1e-9);
        assert!((env.dense_reward() + 0.1).abs() < 1e-9);
        assert!(env.is_success());
        // Position alone is not enough: 0.2 rad off fails.
        let (s, c) = (0.1f64).sin_cos();
        env.set_goal(&[1.0, 0.87, 0.2, c, 0.0, s, 0.0]).unwrap();
        assert!(!env.is_success());
        // No abs on w: the same rotation written −q is 2π away (as in Gymnasium-Robotics).
        env.set_goal(&[1.0, 0.87, 0.2, -1.0, 0.0, 0.0, 0.0])
            .unwrap();
        assert!((env.goal_distances().1 - TAU).abs() < 1e-6);
        assert!((env.dense_reward() + TAU).abs() < 1e-6);
    }
}

#[test]
fn reach_goals_bring_the_thumb_and_one_finger_together_above_the_palm() {
    let mut env = make(HandTask::Reach, HandObservation::Paper);
    let palm = env.palm_position();
    for (got, want) in palm.iter().zip([1.0056, 0.9605, 0.1400]) {
        assert!((got - want).abs() < 1e-3, "palm at {palm:?}");
    }
    let centre: Vec<f64> = palm
        .iter()
        .zip(MEETING_OFFSET)
        .map(|(p, o)| p + o)
        .collect();
    let start = env.initial_fingertips().to_vec();
    let resets = 400;
    let (mut unchanged, mut chosen) = (0, [0; 4]);
    for seed in 0..resets {
        reset(&mut env, seed);
        let goal = env.goal().to_vec();
        let moved: Vec<usize> = (0..5)
            .filter(|&k| dist(&goal[3 * k..3 * k + 3], &start[3 * k..3 * k + 3]) > 1e-12)
            .collect();
        if moved.is_empty() {
            unchanged += 1;
            continue;
        }
        assert_eq!(moved.len(), 2, "seed {seed}: moved {moved:?}");
        assert_eq!(moved[1], 4, "seed {seed}: the thumb moves");
        chosen[moved[0]] += 1;
        for &k in &moved {
            let tip = &goal[3 * k..3 * k + 3];
            // Within 0.005 of a meeting point N(0, 0.005²) away from the centre: 6σ of its
            // 3D noise is 0.03.
            let off = dist(tip, &centre);
            assert!(
                off < MEETING_GAP + 0.03,
                "seed {seed}: tip {k} is {off} from the centre"
            );
        }
        let (a, b) = (&goal[3 * moved[0]..3 * moved[0] + 3], &goal[12..15]);
        assert!(
            dist(a, b) <= 2.0 * MEETING_GAP + 1e-12,
            "seed {seed}: {}",
            dist(a, b)
        );
    }
    // The start pose is the goal with probability 0.1 (40 of 400 expected; 5σ ≈ 30).
    assert!((10..=70).contains(&unchanged), "{unchanged} of {resets}");
    // The finger is uniform over FF, MF, RF, LF (90 each expected).
    assert!(chosen.iter().all(|&n| n > 40), "{chosen:?}");
}

#[test]
fn manipulate_resets_settle_the_object_on_the_palm_and_draw_goals_in_range() {
    for task in [HandTask::Block, HandTask::Egg] {
        let mut env = make(task, HandObservation::Paper);
        let mut angles = Vec::new();
        for seed in 0..15 {
            reset(&mut env, seed);
            let (achieved, goal) = (env.achieved_goal(), env.goal().to_vec());
            assert!(
                achieved[2] > PALM_HEIGHT,
                "{task:?} seed {seed}: fell, {achieved:?}"
            );
            let qnorm = |q: &[f64]| q.iter().map(|x| x * x).sum::<f64>().sqrt();
            assert!((qnorm(&goal[3..]) - 1.0).abs() < 1e-12, "{goal:?}");
            assert!((qnorm(&achieved[3..]) - 1.0).abs() < 1e-6, "{achieved:?}");
            for (k, [lo, hi]) in TARGET_POSITION_RANGE.into_iter().enumerate() {
                let offset = goal[k] - achieved[k];
                assert!(
                    lo - 1e-12 <= offset && offset < hi + 1e-12,
                    "{task:?} seed {seed}: goal offset {offset} outside [{lo}, {hi})"
                );
            }
            // The object starts still-ish after settling, and its velocity is observed.
            assert!(env.data().qvel()[OBJECT..OBJECT + 6]
                .iter()
                .all(|v| v.is_finite()));
            angles.push(env.goal_distances().1);
        }
        // Goal orientations vary.
        let spread = angles.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - angles.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!(spread > 0.5, "{task:?}: {angles:?}");
        assert!(angles.iter().all(|a| (0.0..=TAU + 1e-9).contains(a)));
    }
}

#[test]
fn a_hand_holding_its_pose_reaches_its_own_fingertips() {
    let mut env = make(HandTask::Reach, HandObservation::Paper);
    reset(&mut env, 0);
    let hold = hold_action(&env, &REACH_INITIAL_QPOS);
    // Let the servos settle against gravity (1 s).
    for _ in 0..25 {
        let (t, _) = step(&mut env, &hold);
        assert!(!t.done() && !t.info.unstable, "{t:?}");
    }
    let here = env.achieved_goal();
    env.set_goal(&here).unwrap();
    let (t, obs) = step(&mut env, &hold);
    assert!(!t.done(), "{t:?}");
    assert!(t.reward.abs() < 1e-3, "reward {}", t.reward);
    assert!(env.is_success());
    assert_eq!(t.info.success, Some(true), "the step reports the success");
    assert_eq!(t.reward, env.dense_reward());
    assert_block(&obs[48..63], &env.achieved_goal(), "achieved goal");
    // The same pose with the goal 2 cm away in one coordinate is not a success.
    let mut away = env.achieved_goal();
    away[1] += 0.02;
    env.set_goal(&away).unwrap();
    let (t, _) = step(&mut env, &hold);
    assert!((t.reward + 0.02).abs() < 1e-3 && !env.is_success(), "{t:?}");
    assert_eq!(t.info.success, Some(false));
}

#[test]
fn the_absolute_action_maps_onto_the_control_ranges() {
    let mut env = make(HandTask::Reach, HandObservation::Paper);
    reset(&mut env, 1);
    let ranges = env.data().model().actuator_ctrlrange().to_vec();
    // −1 → lo, 1 → hi, 0 → the middle; beyond ±1 is clipped.
    let mut action = vec![0.0f32; 20];
    action[0] = -1.0;
    action[1] = 1.0;
    action[2] = 7.0;
    action[3] = -0.5;
    step(&mut env, &action);
    let ctrl = env.data().ctrl();
    let [lo0, _] = ranges[0];
    let [_, hi1] = ranges[1];
    let [_, hi2] = ranges[2];
    let [lo3, hi3] = ranges[3];
    assert!((ctrl[0] - lo0).abs() < 1e-12);
    assert!((ctrl[1] - hi1).abs() < 1e-12);
    assert!((ctrl[2] - hi2).abs() < 1e-12);
    assert!((ctrl[3] - (lo3 + 0.25 * (hi3 - lo3))).abs() < 1e-7);
    for (c, [lo, hi]) in ctrl.iter().zip(&ranges).skip(4) {
        assert!((c - (lo + hi) / 2.0).abs() < 1e-12);
    }
    // Relative control: 0 holds each actuator's joint where it is (J1 plus J0 for FF..LF).
    env.set_relative_control(true);
    let q = env.data().qpos().to_vec();
    step(&mut env, &[0.0; 20]);
    let ctrl = env.data().ctrl();
    let ff_j1 = ACTUATORS.iter().position(|a| *a == "FFJ1").unwrap();
    let [lo, hi] = ranges[ff_j1];
    assert!((ctrl[ff_j1] - (q[4] + q[5]).clamp(lo, hi)).abs() < 1e-12);
    let wr = ACTUATORS.iter().position(|a| *a == "WRJ0").unwrap();
    assert!((ctrl[wr] - q[1]).abs() < 1e-12);
}

#[test]
fn seeded_episodes_are_reproducible() {
    for task in HandTask::ALL {
        let run = || {
            let mut env = make(task, HandObservation::GoalConditioned);
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
            let mut trace = reset(&mut env, 42);
            for _ in 0..10 {
                let action: Vec<f32> = (0..20).map(|_| rng.random_range(-1.0..1.0)).collect();
                let (t, obs) = step(&mut env, &action);
                trace.extend(obs);
                trace.push(t.reward as f32);
            }
            trace
        };
        assert_eq!(run(), run(), "{task:?}");
        // Different seeds give different starts or goals (Reach keeps its start goal with
        // probability 0.1, so compare several seeds).
        let mut env = make(task, HandObservation::GoalConditioned);
        let first = reset(&mut env, 1);
        assert!(
            (2..6).any(|seed| reset(&mut env, seed) != first),
            "{task:?}"
        );
    }
}

#[test]
fn random_actions_run_stably_with_finite_non_positive_rewards() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for task in HandTask::ALL {
        let mut env = make(task, HandObservation::GoalConditioned);
        for episode in 0..2 {
            reset(&mut env, episode);
            for _ in 0..task.max_episode_steps() {
                let action: Vec<f32> = (0..20).map(|_| rng.random_range(-1.0..1.0)).collect();
                let (t, obs) = step(&mut env, &action);
                assert!(
                    !t.info.unstable && !t.done(),
                    "{task:?}: unstable under random actions"
                );
                assert!(
                    t.reward.is_finite() && t.reward <= 0.0,
                    "{task:?}: {}",
                    t.reward
                );
                assert!(obs.iter().all(|x| x.is_finite()), "{task:?}");
            }
        }
    }
}

#[test]
fn nan_actions_and_states_end_the_episode_as_unstable() {
    for task in HandTask::ALL {
        let mut env = make(task, HandObservation::Paper);
        reset(&mut env, 0);
        let mut action = [0.0f32; 20];
        action[3] = f32::NAN;
        let (t, obs) = step(&mut env, &action);
        assert!(
            t.terminated && t.info.unstable && t.reward == 0.0 && t.info.success.is_none(),
            "{task:?}: {t:?}"
        );
        assert!(obs.iter().all(|x| x.is_finite()), "{task:?}");
        // A reset recovers.
        reset(&mut env, 0);
        let (t, _) = step(&mut env, &[0.0; 20]);
        assert!(!t.done() && !t.info.unstable, "{task:?}: {t:?}");
        // A non-finite velocity too.
        let model = env.data().model();
        let (q, mut v) = (env.data().qpos().to_vec(), vec![0.0; model.nv()]);
        v[2] = f64::NAN;
        env.set_state(&q, &v).unwrap();
        let (t, obs) = step(&mut env, &[0.0; 20]);
        assert!(t.terminated && t.info.unstable, "{task:?}: {t:?}");
        assert!(obs.iter().all(|x| x.is_finite()), "{task:?}");
    }
}

#[test]
fn the_start_rotation_noise_turns_the_object_and_the_target_marks_the_goal() {
    let mut env = make(HandTask::Block, HandObservation::Paper);
    let mut turned = 0;
    for seed in 0..5 {
        reset(&mut env, seed);
        let q = &env.data().qpos()[OBJECT + 3..OBJECT + 7];
        // Identity is the model's start orientation; a random turn (and settling) moves it.
        if (q[0].abs() - 1.0).abs() > 1e-3 {
            turned += 1;
        }
        // The target marker (target:joint, after the object's 7 coordinates) sits at the goal.
        let target = &env.data().qpos()[OBJECT + 7..OBJECT + 14];
        assert_eq!(target, env.goal(), "seed {seed}");
    }
    assert!(turned >= 4, "{turned}");
}
