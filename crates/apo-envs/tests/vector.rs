//! Vectorized stepping with automatic reset.

mod common;

use apo_envs::classic::{CartPole, Pendulum};
use apo_envs::{Env, EnvError, Space, TimeLimit, VecEnv, VecStep};
use common::Counter;

fn counters(lengths: &[usize]) -> VecEnv {
    let envs: Vec<Box<dyn Env>> = lengths
        .iter()
        .map(|k| Box::new(Counter::new(Space::uniform_box(1, -1.0, 1.0), Some(*k))) as Box<dyn Env>)
        .collect();
    VecEnv::new(envs).expect("same spaces")
}

#[test]
fn auto_reset_keeps_the_final_observation_and_starts_the_next_episode() {
    // Env 0 terminates every 2 steps, env 1 every 3 steps. Observation: [episode, t, action].
    let mut venv = counters(&[2, 3]);
    assert_eq!((venv.num_envs(), venv.obs_dim(), venv.act_dim()), (2, 3, 1));
    let mut obs = vec![0.0f32; 6];
    let mut out = vec![VecStep::default(); 2];
    venv.reset(Some(10), &mut obs);
    assert_eq!(obs, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert_eq!((venv.final_obs(0), venv.final_obs(1)), (None, None));

    // Step 1: nobody done.
    venv.step(&[0.25, 0.5], &mut obs, &mut out);
    assert_eq!(obs, [0.0, 1.0, 0.25, 0.0, 1.0, 0.5]);
    assert!(!out[0].done() && !out[1].done());
    assert_eq!((out[0].reward, out[1].reward), (1.0, 1.0));

    // Step 2: env 0 terminates, is reset: its row is episode 1's first observation and the final
    // observation of episode 0 is kept. Env 1 goes on.
    venv.step(&[0.75, -0.5], &mut obs, &mut out);
    assert!(out[0].terminated && !out[0].truncated && out[0].done());
    assert_eq!(out[0].reward, 2.0, "the reward of the finishing step");
    assert!(!out[1].done());
    assert_eq!(
        &obs[..3],
        &[1.0, 0.0, 0.0],
        "first observation of env 0's next episode"
    );
    assert_eq!(
        venv.final_obs(0),
        Some(&[0.0, 2.0, 0.75][..]),
        "last observation of env 0's episode"
    );
    assert_eq!(venv.final_obs(1), None);
    assert_eq!(&obs[3..], &[0.0, 2.0, -0.5]);
    assert_eq!(&venv.final_obs_buffer()[..3], &[0.0, 2.0, 0.75]);

    // Step 3: env 1 terminates; env 0's flag from the previous step is cleared.
    venv.step(&[0.0, 1.0], &mut obs, &mut out);
    assert!(!out[0].done() && out[1].done());
    assert_eq!(venv.final_obs(0), None);
    assert_eq!(venv.final_obs(1), Some(&[0.0, 3.0, 1.0][..]));
    assert_eq!(obs, [1.0, 1.0, 0.0, 1.0, 0.0, 0.0]);

    // Step 4: env 0 terminates again (episode 1 → 2).
    venv.step(&[0.5, 0.5], &mut obs, &mut out);
    assert!(out[0].done() && !out[1].done());
    assert_eq!(venv.final_obs(0), Some(&[1.0, 2.0, 0.5][..]));
    assert_eq!(&obs[..3], &[2.0, 0.0, 0.0]);
    assert_eq!(venv.final_obs(2), None, "out of range");
}

#[test]
fn truncated_episodes_are_reset_too_and_reported_as_truncated() {
    let envs: Vec<Box<dyn Env>> = (0..3)
        .map(|_| Box::new(TimeLimit::new(Pendulum::new(), 4)) as Box<dyn Env>)
        .collect();
    let mut venv = VecEnv::new(envs).expect("same spaces");
    let mut obs = vec![0.0f32; 9];
    let mut out = vec![VecStep::default(); 3];
    venv.reset(Some(0), &mut obs);
    for k in 1..=4 {
        let before = obs.clone();
        venv.step(&[0.0, 1.0, -1.0], &mut obs, &mut out);
        for (i, o) in out.iter().enumerate() {
            assert_eq!(o.truncated, k == 4, "env {i} step {k}");
            assert!(!o.terminated);
            assert!(o.reward < 0.0);
        }
        if k == 4 {
            for i in 0..3 {
                let last = venv.final_obs(i).expect("done");
                assert_ne!(
                    last,
                    &obs[3 * i..3 * i + 3],
                    "env {i}: reset obs differs from the final one"
                );
                assert_ne!(last, &before[3 * i..3 * i + 3]);
            }
        }
    }
}

#[test]
fn reset_seeds_env_i_with_seed_plus_i() {
    // Env i's first observation equals that of a lone CartPole reset with seed 100 + i.
    let make = || {
        let envs: Vec<Box<dyn Env>> = (0..3)
            .map(|_| Box::new(CartPole::new()) as Box<dyn Env>)
            .collect();
        VecEnv::new(envs).expect("same spaces")
    };
    let mut venv = make();
    let mut obs = vec![0.0f32; 12];
    venv.reset(Some(100), &mut obs);
    for i in 0..3u64 {
        let mut single = CartPole::new();
        let mut o = [0.0f32; 4];
        single.reset(Some(100 + i), &mut o);
        assert_eq!(
            &obs[4 * i as usize..4 * i as usize + 4],
            &o,
            "env {i} seeded with 100 + {i}"
        );
    }
    // Same seed → same observations from a fresh vector; rows differ from each other.
    let mut again = vec![0.0f32; 12];
    make().reset(Some(100), &mut again);
    assert_eq!(obs, again);
    assert_ne!(obs[..4], obs[4..8]);
}

#[test]
fn discrete_actions_are_indices_stored_as_floats() {
    let envs: Vec<Box<dyn Env>> = (0..2)
        .map(|_| Box::new(Counter::new(Space::Discrete { n: 3 }, None)) as Box<dyn Env>)
        .collect();
    let mut venv = VecEnv::new(envs).expect("same spaces");
    let mut obs = vec![0.0f32; 6];
    let mut out = vec![VecStep::default(); 2];
    venv.reset(None, &mut obs);
    venv.step(&[2.0, 0.0], &mut obs, &mut out);
    assert_eq!((obs[2], obs[5]), (2.0, 0.0));
}

#[test]
#[should_panic(expected = "not an index")]
fn discrete_action_out_of_range_panics() {
    let envs: Vec<Box<dyn Env>> = vec![Box::new(CartPole::new())];
    let mut venv = VecEnv::new(envs).expect("one env");
    let mut obs = vec![0.0f32; 4];
    let mut out = vec![VecStep::default(); 1];
    venv.reset(Some(0), &mut obs);
    venv.step(&[1.5], &mut obs, &mut out);
}

#[test]
#[should_panic(expected = "`obs` has length")]
fn wrong_buffer_length_panics() {
    let mut venv = counters(&[2, 2]);
    let mut obs = vec![0.0f32; 5];
    venv.reset(None, &mut obs);
}

#[test]
fn construction_errors() {
    assert!(matches!(
        VecEnv::new(Vec::new()),
        Err(EnvError::EmptyVector)
    ));
    let envs: Vec<Box<dyn Env>> = vec![Box::new(CartPole::new()), Box::new(Pendulum::new())];
    let err = VecEnv::new(envs).expect_err("different spaces");
    assert!(
        matches!(err, EnvError::MismatchedSpaces { index: 1, .. }),
        "{err}"
    );
}

#[test]
fn make_builds_registered_envs() {
    let mut venv = VecEnv::make("CartPole-v1", 4).expect("registered");
    assert_eq!((venv.num_envs(), venv.obs_dim(), venv.act_dim()), (4, 4, 1));
    assert_eq!(venv.action_space(), &Space::Discrete { n: 2 });
    assert_eq!(venv.observation_space().flat_dim(), 4);
    // Run 600 steps: every CartPole episode ends (termination or the 500-step limit) and
    // restarts; observation rows always stay inside the space.
    let mut obs = vec![0.0f32; 16];
    let mut out = vec![VecStep::default(); 4];
    venv.reset(Some(1), &mut obs);
    let mut finished = 0;
    for k in 0..600 {
        let actions: Vec<f32> = (0..4).map(|i| ((k + i) % 2) as f32).collect();
        venv.step(&actions, &mut obs, &mut out);
        finished += out.iter().filter(|o| o.done()).count();
        for row in obs.chunks(4) {
            assert!(venv.observation_space().contains(row));
        }
    }
    assert!(finished >= 4);
    assert!(matches!(
        VecEnv::make("CartPole-v1", 0),
        Err(EnvError::EmptyVector)
    ));
    assert!(matches!(
        VecEnv::make("CartPoel", 2),
        Err(EnvError::Unknown { .. })
    ));
}

/// Steps `venv` 300 times with actions drawn from a fixed stream and returns every
/// observation, outcome and final observation, bit for bit.
fn trajectory(mut venv: VecEnv) -> Vec<(Vec<u32>, Vec<VecStep>, Vec<u32>)> {
    use rand::{Rng, SeedableRng};
    let n = venv.num_envs();
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let mut obs = vec![0.0f32; n * venv.obs_dim()];
    let mut out = vec![VecStep::default(); n];
    venv.reset(Some(11), &mut obs);
    let discrete = matches!(venv.action_space(), Space::Discrete { .. });
    (0..300)
        .map(|_| {
            let actions: Vec<f32> = (0..n * venv.act_dim())
                .map(|_| {
                    if discrete {
                        rng.random_range(0..2) as f32
                    } else {
                        rng.random_range(-1.0..1.0)
                    }
                })
                .collect();
            venv.step(&actions, &mut obs, &mut out);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
            (bits(&obs), out.clone(), bits(venv.final_obs_buffer()))
        })
        .collect()
}

#[test]
fn threads_do_not_change_a_single_bit() {
    for (name, n) in [("CartPole-v1", 5), ("Hopper", 7)] {
        let serial = VecEnv::make(name, n).expect("registered");
        assert_eq!(serial.threads(), 1);
        let reference = trajectory(serial);
        assert!(
            reference
                .iter()
                .any(|(_, out, _)| out.iter().any(VecStep::done)),
            "{name}: no episode ended, resets untested"
        );
        for threads in [2, 3, 64] {
            let venv = VecEnv::make(name, n)
                .and_then(|v| v.with_threads(threads))
                .expect("threads start");
            assert_eq!(venv.threads(), threads.min(n));
            assert!(
                trajectory(venv) == reference,
                "{name}: {threads} threads changed the trajectory"
            );
        }
    }
}
