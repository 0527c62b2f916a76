//! Classic-control environments against hand derivations of their equations and against
//! reference trajectories.
//!
//! The reference literals were produced by Gymnasium 1.4.0 (NumPy 2.4) by setting
//! `env.unwrapped.state` to the initial state below and stepping with the listed actions.

mod common;

use std::f64::consts::PI;

use apo_envs::classic::{Acrobot, CartPole, MountainCarContinuous, Pendulum};
use apo_envs::{Action, Env, Space};
use common::close;

// ---------------------------------------------------------------- CartPole

#[test]
fn cartpole_one_euler_step_by_hand() {
    let mut env = CartPole::new();
    env.set_state([0.01, -0.02, 0.03, 0.04]);
    let mut obs = [0.0f32; 4];
    let t = env.step(Action::Discrete(1), &mut obs);

    // Re-derived from the equations of Florian (2007) with Gymnasium's constants:
    // g 9.8, cart 1.0, pole 0.1, half-length 0.5, force +10 (action 1), tau 0.02.
    let (x, x_dot, th, th_dot) = (0.01f64, -0.02f64, 0.03f64, 0.04f64);
    let temp = (10.0 + 0.1 * 0.5 * th_dot * th_dot * th.sin()) / 1.1;
    let th_acc =
        (9.8 * th.sin() - th.cos() * temp) / (0.5 * (4.0 / 3.0 - 0.1 * th.cos() * th.cos() / 1.1));
    let x_acc = temp - 0.1 * 0.5 * th_acc * th.cos() / 1.1;
    let expected = [
        x + 0.02 * x_dot,
        x_dot + 0.02 * x_acc,
        th + 0.02 * th_dot,
        th_dot + 0.02 * th_acc,
    ];

    for (i, (s, e)) in env.state().iter().zip(expected).enumerate() {
        close(*s, e, 1e-14, &format!("state[{i}]"));
        close(f64::from(obs[i]), e, 1e-7, &format!("obs[{i}]"));
    }
    assert_eq!(t.reward, 1.0);
    assert!(!t.terminated && !t.truncated && !t.info.unstable);
}

#[test]
fn cartpole_trajectory_matches_reference() {
    let mut env = CartPole::new();
    env.set_state([0.01, -0.02, 0.03, 0.04]);
    let expected: [(usize, [f64; 4]); 5] = [
        (
            1,
            [
                0.009600000000000001,
                0.17467919574755525,
                0.030799999999999998,
                -0.2430687179600081,
            ],
        ),
        (
            0,
            [
                0.013093583914951107,
                -0.020868848948191993,
                0.025938625640799837,
                0.0591679999394166,
            ],
        ),
        (
            0,
            [
                0.012676206935987267,
                -0.21635292104612766,
                0.02712198563958817,
                0.3599205713784138,
            ],
        ),
        (
            1,
            [
                0.008349148515064714,
                -0.021626799199488206,
                0.03432039706715644,
                0.0759116989474441,
            ],
        ),
        (
            1,
            [
                0.00791661253107495,
                0.17298676004769037,
                0.035838631046105324,
                -0.20574851582677406,
            ],
        ),
    ];
    let mut obs = [0.0f32; 4];
    for (step, (a, state)) in expected.iter().enumerate() {
        let t = env.step(Action::Discrete(*a), &mut obs);
        assert_eq!((t.reward, t.terminated), (1.0, false), "step {step}");
        for i in 0..4 {
            close(
                env.state()[i],
                state[i],
                1e-13,
                &format!("step {step} state[{i}]"),
            );
            assert_eq!(obs[i], state[i] as f32, "step {step} obs[{i}]");
        }
    }
}

#[test]
fn cartpole_terminates_on_position_and_angle_and_pays_the_terminating_step() {
    let mut obs = [0.0f32; 4];
    let mut env = CartPole::new();
    // x = 2.39 + 0.02 * 1.0 = 2.41 > 2.4.
    env.set_state([2.39, 1.0, 0.0, 0.0]);
    let t = env.step(Action::Discrete(1), &mut obs);
    assert!(t.terminated && !t.truncated);
    assert_eq!(t.reward, 1.0, "the terminating step is paid");
    close(env.state()[0], 2.41, 1e-15, "x");
    // Stepping on after termination (a contract violation) pays 0, as in Gymnasium.
    let t = env.step(Action::Discrete(1), &mut obs);
    assert!(t.terminated);
    assert_eq!(t.reward, 0.0);

    // Angle: 12 degrees = 0.20943951 rad. θ = 0.2094 + 0.02 * 0.1 = 0.2114 > threshold.
    env.set_state([0.0, 0.0, 0.2094, 0.1]);
    assert!(env.step(Action::Discrete(0), &mut obs).terminated);
    env.set_state([0.0, 0.0, -0.2094, -0.1]);
    assert!(env.step(Action::Discrete(1), &mut obs).terminated);
    // θ = 0.2 stays under the threshold (θ̇ = 0): not terminated.
    env.set_state([0.0, 0.0, 0.2, 0.0]);
    let t = env.step(Action::Discrete(0), &mut obs);
    assert!(!t.terminated);
    assert_eq!(t.reward, 1.0);
    // x = -2.39 - 0.02 = -2.41 < -2.4.
    env.set_state([-2.39, -1.0, 0.0, 0.0]);
    assert!(env.step(Action::Discrete(0), &mut obs).terminated);
}

#[test]
fn cartpole_spaces() {
    let env = CartPole::new();
    assert_eq!(env.action_space(), &Space::Discrete { n: 2 });
    let Space::Box { low, high, shape } = env.observation_space() else {
        panic!("box expected")
    };
    let theta_limit = (24.0 * PI / 180.0) as f32;
    assert_eq!(high, &vec![4.8, f32::MAX, theta_limit, f32::MAX]);
    assert_eq!(low, &vec![-4.8, -f32::MAX, -theta_limit, -f32::MAX]);
    assert_eq!(shape, &vec![4]);
}

#[test]
#[should_panic(expected = "discrete action")]
fn cartpole_rejects_an_action_outside_its_space() {
    let mut env = CartPole::new();
    let mut obs = [0.0f32; 4];
    env.reset(Some(0), &mut obs);
    env.step(Action::Discrete(2), &mut obs);
}

// ---------------------------------------------------------------- Acrobot

#[test]
fn acrobot_trajectory_matches_reference() {
    let mut env = Acrobot::new();
    env.set_state([0.05, -0.03, 0.1, -0.2]);
    let expected: [(usize, [f64; 4]); 5] = [
        (
            0,
            [
                0.07554717015953656,
                -0.0945375159211389,
                0.14812655958803767,
                -0.4299859771598119,
            ],
        ),
        (
            2,
            [
                0.07927888763502637,
                -0.12574487766741257,
                -0.1120399144359372,
                0.12294248310223843,
            ],
        ),
        (
            1,
            [
                0.04603927036278734,
                -0.0825264933539499,
                -0.21220350716788716,
                0.29659898632375015,
            ],
        ),
        (
            2,
            [
                -0.014635907235186527,
                0.020402166651509887,
                -0.3788212182013664,
                0.7051142544822984,
            ],
        ),
        (
            2,
            [
                -0.09738115829341518,
                0.18467221356818703,
                -0.4263045163419967,
                0.8954967018965365,
            ],
        ),
    ];
    let mut obs = [0.0f32; 6];
    for (step, (a, s)) in expected.iter().enumerate() {
        let t = env.step(Action::Discrete(*a), &mut obs);
        assert_eq!(
            (t.reward, t.terminated, t.truncated),
            (-1.0, false, false),
            "step {step}"
        );
        for (i, (got, want)) in env.state().iter().zip(s).enumerate() {
            close(*got, *want, 1e-12, &format!("step {step} state[{i}]"));
        }
        let layout = [s[0].cos(), s[0].sin(), s[1].cos(), s[1].sin(), s[2], s[3]];
        for (i, v) in layout.iter().enumerate() {
            close(
                f64::from(obs[i]),
                *v,
                1e-6,
                &format!("step {step} obs[{i}]"),
            );
        }
    }
}

#[test]
fn acrobot_rests_hanging_down_without_torque() {
    // Hanging straight down is an equilibrium: every derivative is 0 with torque 0.
    let mut env = Acrobot::new();
    env.set_state([0.0; 4]);
    let mut obs = [0.0f32; 6];
    let t = env.step(Action::Discrete(1), &mut obs);
    // Up to the rounding of cos(−π/2) ≈ 6e-17 in the gravity terms.
    for (i, s) in env.state().iter().enumerate() {
        close(*s, 0.0, 1e-15, &format!("state[{i}]"));
    }
    for (i, (o, e)) in obs.iter().zip([1.0, 0.0, 1.0, 0.0, 0.0, 0.0]).enumerate() {
        close(f64::from(*o), e, 1e-15, &format!("obs[{i}]"));
    }
    assert_eq!((t.reward, t.terminated), (-1.0, false));
    // With torque +1 the elbow accelerates positively, the shoulder negatively (reaction).
    env.step(Action::Discrete(2), &mut obs);
    let [_, _, d1, d2] = env.state();
    assert!(d2 > 0.0 && d1 < 0.0, "θ̇1 = {d1}, θ̇2 = {d2}");
}

#[test]
fn acrobot_terminates_when_the_tip_is_above_the_bar() {
    let mut env = Acrobot::new();
    env.set_state([3.0, 0.1, 0.0, 0.0]);
    let mut obs = [0.0f32; 6];
    let t = env.step(Action::Discrete(1), &mut obs);
    let expected = [
        2.9801010644913126,
        0.12460838080578891,
        -0.20368049965045298,
        0.25311378017408265,
    ];
    for (i, (got, want)) in env.state().iter().zip(expected).enumerate() {
        close(*got, want, 1e-12, &format!("state[{i}]"));
    }
    // -cos(2.980) - cos(3.105) = 0.987 + 0.9993 > 1.
    assert!(t.terminated && !t.truncated);
    assert_eq!(t.reward, 0.0);
}

#[test]
fn acrobot_wraps_angles_and_bounds_velocities() {
    let mut env = Acrobot::new();
    // Just below +π, spinning fast: the angle wraps to near -π, the velocity is clipped.
    env.set_state([PI - 0.01, 0.0, 20.0, 40.0]);
    let mut obs = [0.0f32; 6];
    env.step(Action::Discrete(1), &mut obs);
    let [t1, t2, d1, d2] = env.state();
    assert!(
        (-PI..=PI).contains(&t1) && (-PI..=PI).contains(&t2),
        "{t1} {t2}"
    );
    assert!(d1.abs() <= 4.0 * PI && d2.abs() <= 9.0 * PI, "{d1} {d2}");
    assert!(env.observation_space().contains(&obs), "{obs:?}");
}

// ---------------------------------------------------------------- Pendulum

#[test]
fn pendulum_one_step_by_hand() {
    let mut env = Pendulum::new();
    env.set_state([1.0, 0.5]);
    let mut obs = [0.0f32; 3];
    let t = env.step(Action::Continuous(&[0.5]), &mut obs);
    // θ̇' = 0.5 + (3·10/2 · sin 1 + 3 · 0.5) · 0.05, θ' = 1 + θ̇' · 0.05.
    let thdot = 0.5 + (15.0 * 1.0f64.sin() + 1.5) * 0.05;
    let th = 1.0 + thdot * 0.05;
    close(env.state()[0], th, 1e-15, "θ");
    close(env.state()[1], thdot, 1e-15, "θ̇");
    // Reward on the state before the step: −(1² + 0.1·0.5² + 0.001·0.5²).
    close(t.reward, -1.02525, 1e-12, "reward");
    close(f64::from(obs[0]), th.cos(), 1e-7, "cos θ");
    close(f64::from(obs[1]), th.sin(), 1e-7, "sin θ");
    close(f64::from(obs[2]), thdot, 1e-6, "θ̇");
    assert!(!t.terminated && !t.truncated);
}

#[test]
fn pendulum_trajectory_matches_reference_with_torque_and_speed_clipping() {
    let mut env = Pendulum::new();
    env.set_state([1.0, 0.5]);
    // The action -3 is clipped to -2, in the dynamics and in the reward.
    let expected = [
        (
            0.5,
            -1.0252500000118743,
            [1.0603051619302961, 1.2061032386059223],
        ),
        (
            -3.0,
            -1.2737155388235912,
            [1.1383292473683038, 1.5604817087601541],
        ),
        (
            2.0,
            -1.5433037919415806,
            [1.265400877723987, 2.5414326071136606],
        ),
        (
            0.0,
            -2.2471273509946914,
            [1.4282373128546353, 3.2567287026129668],
        ),
    ];
    let mut obs = [0.0f32; 3];
    for (step, (a, r, s)) in expected.iter().enumerate() {
        let t = env.step(Action::Continuous(&[*a]), &mut obs);
        close(t.reward, *r, 1e-9, &format!("step {step} reward"));
        close(env.state()[0], s[0], 1e-13, &format!("step {step} θ"));
        close(env.state()[1], s[1], 1e-13, &format!("step {step} θ̇"));
    }

    // Speed clipped to 8; the angle in the cost is normalized into [-π, π).
    env.set_state([3.0, 7.9]);
    let t = env.step(Action::Continuous(&[2.0]), &mut obs);
    assert_eq!(env.state()[1], 8.0);
    close(env.state()[0], 3.4, 1e-15, "θ");
    close(t.reward, -(9.0 + 0.1 * 7.9 * 7.9 + 0.004), 1e-12, "reward");
    let t = env.step(Action::Continuous(&[2.0]), &mut obs);
    let wrapped = 3.4 - 2.0 * PI;
    close(
        t.reward,
        -(wrapped * wrapped + 6.4 + 0.004),
        1e-12,
        "reward with wrapped angle",
    );
    close(t.reward, -14.716757515726233, 1e-9, "reference reward");
    assert_eq!(obs[2], 8.0);
}

#[test]
fn pendulum_never_terminates_but_flags_a_non_finite_action() {
    let mut env = Pendulum::new();
    let mut obs = [0.0f32; 3];
    env.reset(Some(3), &mut obs);
    for _ in 0..1000 {
        let t = env.step(Action::Continuous(&[2.0]), &mut obs);
        assert!(!t.done() && !t.info.unstable);
        assert!(env.observation_space().contains(&obs), "{obs:?}");
    }
    let t = env.step(Action::Continuous(&[f32::NAN]), &mut obs);
    assert!(t.terminated && t.info.unstable);
}

// ---------------------------------------------------------------- MountainCarContinuous

#[test]
fn mountain_car_one_step_by_hand() {
    let mut env = MountainCarContinuous::new();
    env.set_state([-0.5, 0.0]);
    let mut obs = [0.0f32; 2];
    let t = env.step(Action::Continuous(&[1.0]), &mut obs);
    // v' = 0 + 1·0.0015 − 0.0025·cos(3·(−0.5)), x' = −0.5 + v'; stored as f32.
    let v = 0.0015 - 0.0025 * (-1.5f64).cos();
    let x = -0.5 + v;
    assert_eq!(env.state(), [f64::from(x as f32), f64::from(v as f32)]);
    assert_eq!(obs, [x as f32, v as f32]);
    close(t.reward, -0.1, 1e-15, "reward −0.1·1²");
    assert!(!t.terminated);
}

#[test]
fn mountain_car_trajectory_matches_reference() {
    let mut env = MountainCarContinuous::new();
    env.set_state([-0.5, 0.0]);
    // The action −2 moves the car like −1 but costs 0.1·(−2)² = 0.4 (unclipped, as in Gymnasium).
    let expected = [
        (1.0, -0.1, [-0.4986768364906311, 0.0013231569901108742]),
        (0.5, -0.025, [-0.49679040908813477, 0.0018864166922867298]),
        (-2.0, -0.4, [-0.4966048300266266, 0.00018557067960500717]),
    ];
    let mut obs = [0.0f32; 2];
    for (step, (a, r, s)) in expected.iter().enumerate() {
        let t = env.step(Action::Continuous(&[*a]), &mut obs);
        close(t.reward, *r, 1e-12, &format!("step {step} reward"));
        close(env.state()[0], s[0], 1e-7, &format!("step {step} x"));
        close(env.state()[1], s[1], 1e-8, &format!("step {step} v"));
    }
}

#[test]
fn mountain_car_goal_wall_and_velocity_rule() {
    let mut obs = [0.0f32; 2];
    let mut env = MountainCarContinuous::new();
    // Reaches 0.50 moving right: terminated, 100 − 0.1.
    env.set_state([f64::from(0.44f32), f64::from(0.06f32)]);
    let t = env.step(Action::Continuous(&[1.0]), &mut obs);
    assert!(t.terminated && !t.truncated);
    close(t.reward, 99.9, 1e-12, "reward");
    close(env.state()[0], 0.5008795261383057, 1e-7, "x");
    close(env.state()[1], 0.06087955832481384, 1e-8, "v");

    // Past the goal but moving left: v' = −0.01 + 0.0015 − 0.0025·cos(1.5) < 0, not terminated.
    env.set_state([0.5, -0.01]);
    let t = env.step(Action::Continuous(&[1.0]), &mut obs);
    assert!(env.state()[0] >= 0.45 && env.state()[1] < 0.0);
    assert!(!t.terminated);

    // Hitting the left wall moving left stops the car at −1.2.
    env.set_state([f64::from(-1.19f32), f64::from(-0.07f32)]);
    let t = env.step(Action::Continuous(&[-1.0]), &mut obs);
    assert_eq!(env.state(), [f64::from(-1.2f32), 0.0]);
    assert_eq!(obs, [-1.2, 0.0]);
    close(t.reward, -0.1, 1e-15, "reward");
    assert!(!t.terminated);

    // Velocity is clipped to 0.07: 0.07 + 0.0015 − 0.0025·cos(1.5) > 0.07.
    env.set_state([0.5, 0.07]);
    env.step(Action::Continuous(&[1.0]), &mut obs);
    assert_eq!(env.state()[1], f64::from(0.07f32));

    let t = env.step(Action::Continuous(&[f32::NAN]), &mut obs);
    assert!(t.terminated && t.info.unstable);
}

// ---------------------------------------------------------------- all four

fn classic_envs() -> Vec<(&'static str, Box<dyn Env>)> {
    vec![
        ("CartPole", Box::new(CartPole::new())),
        ("Acrobot", Box::new(Acrobot::new())),
        ("Pendulum", Box::new(Pendulum::new())),
        (
            "MountainCarContinuous",
            Box::new(MountainCarContinuous::new()),
        ),
    ]
}

/// A fixed, varied action for step `k`.
fn action_buf<'a>(space: &Space, k: usize, buf: &'a mut [f32; 1]) -> Action<'a> {
    match space {
        Space::Discrete { n } => Action::Discrete((k * 7 + k / 3) % n),
        Space::Box { .. } => {
            buf[0] = (k as f32 * 0.37).sin() * 1.5;
            Action::Continuous(&buf[..])
        }
    }
}

/// Observations and rewards of `steps` steps (or until done) after `reset(seed)`.
fn rollout(env: &mut dyn Env, seed: Option<u64>, steps: usize) -> Vec<f64> {
    let mut obs = vec![0.0f32; env.observation_space().flat_dim()];
    env.reset(seed, &mut obs);
    let mut out: Vec<f64> = obs.iter().map(|x| f64::from(*x)).collect();
    let space = env.action_space().clone();
    let mut buf = [0.0f32];
    for k in 0..steps {
        let t = env.step(action_buf(&space, k, &mut buf), &mut obs);
        out.extend(obs.iter().map(|x| f64::from(*x)));
        out.push(t.reward);
        if t.done() {
            break;
        }
    }
    out
}

#[test]
fn same_seed_same_episode_different_seed_different_episode() {
    for ((name, mut a), (_, mut b)) in classic_envs().into_iter().zip(classic_envs()) {
        let first = rollout(a.as_mut(), Some(42), 50);
        assert_eq!(
            first,
            rollout(b.as_mut(), Some(42), 50),
            "{name}: same seed, other instance"
        );
        assert_eq!(
            first,
            rollout(a.as_mut(), Some(42), 50),
            "{name}: same seed, same instance"
        );
        assert_ne!(
            first,
            rollout(b.as_mut(), Some(43), 50),
            "{name}: another seed"
        );
        // With None, the RNG stream continues: the next episode starts elsewhere.
        rollout(a.as_mut(), Some(42), 0);
        assert_ne!(
            first[..2],
            rollout(a.as_mut(), None, 0)[..2],
            "{name}: reset(None) after reset(42)"
        );
    }
}

#[test]
fn observations_stay_in_their_space_until_done() {
    for (name, mut env) in classic_envs() {
        let space = env.observation_space().clone();
        let action_space = env.action_space().clone();
        let mut obs = vec![0.0f32; space.flat_dim()];
        let mut buf = [0.0f32];
        for episode in 0..20 {
            env.reset(Some(episode), &mut obs);
            assert!(space.contains(&obs), "{name}: reset obs {obs:?}");
            for k in 0..300 {
                let t = env.step(
                    action_buf(&action_space, k + episode as usize, &mut buf),
                    &mut obs,
                );
                assert!(space.contains(&obs), "{name}: obs {obs:?}");
                if t.done() {
                    break;
                }
            }
        }
    }
}

/// Resets `env` `n` times from one seed and returns the state components sampled.
fn reset_samples<E: Env>(env: &mut E, n: usize, state: impl Fn(&E) -> Vec<f64>) -> Vec<Vec<f64>> {
    let mut obs = vec![0.0f32; env.observation_space().flat_dim()];
    let mut samples = vec![Vec::new(); state(env).len()];
    for k in 0..n {
        env.reset(if k == 0 { Some(7) } else { None }, &mut obs);
        for (column, v) in samples.iter_mut().zip(state(env)) {
            column.push(v);
        }
    }
    samples
}

/// Asserts every sample lies in `[low, high]` and that the samples fill the interval
/// (min and max within 2% of the ends, mean near the middle).
fn assert_uniform(name: &str, samples: &[f64], low: f64, high: f64) {
    let width = high - low;
    let min = samples.iter().copied().fold(f64::INFINITY, f64::min);
    let max = samples.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mean = samples.iter().sum::<f64>() / samples.len() as f64;
    assert!(
        min >= low && max <= high,
        "{name}: samples in [{min}, {max}], expected [{low}, {high}]"
    );
    assert!(
        min < low + 0.02 * width && max > high - 0.02 * width,
        "{name}: [{min}, {max}] does not fill [{low}, {high}]"
    );
    // Standard error of the mean of 2000 uniforms is width / sqrt(12 · 2000) ≈ 0.0065 width.
    close(
        mean,
        (low + high) / 2.0,
        0.03 * width,
        &format!("{name}: mean"),
    );
}

#[test]
fn reset_distributions() {
    let n = 2000;
    let cp = reset_samples(&mut CartPole::new(), n, |e| e.state().to_vec());
    for (i, s) in cp.iter().enumerate() {
        assert_uniform(&format!("CartPole state[{i}]"), s, -0.05, 0.05);
    }
    let ac = reset_samples(&mut Acrobot::new(), n, |e| e.state().to_vec());
    for (i, s) in ac.iter().enumerate() {
        assert_uniform(&format!("Acrobot state[{i}]"), s, -0.1, 0.1);
    }
    let pe = reset_samples(&mut Pendulum::new(), n, |e| e.state().to_vec());
    assert_uniform("Pendulum θ", &pe[0], -PI, PI);
    assert_uniform("Pendulum θ̇", &pe[1], -1.0, 1.0);
    let mc = reset_samples(&mut MountainCarContinuous::new(), n, |e| e.state().to_vec());
    assert_uniform("MountainCar x", &mc[0], -0.6, -0.4);
    assert!(
        mc[1].iter().all(|v| *v == 0.0),
        "MountainCar starts at rest"
    );
}

#[test]
fn reset_writes_the_state_as_observation() {
    let mut obs = [0.0f32; 4];
    let mut cp = CartPole::new();
    cp.reset(Some(1), &mut obs);
    assert_eq!(obs, cp.state().map(|s| s as f32));
    let mut obs = [0.0f32; 3];
    let mut pe = Pendulum::new();
    pe.reset(Some(1), &mut obs);
    let [th, thdot] = pe.state();
    assert_eq!(obs, [th.cos() as f32, th.sin() as f32, thdot as f32]);
}
