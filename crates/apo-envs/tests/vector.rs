//! Vectorized stepping with automatic reset.

mod common;

use apo_envs::classic::{CartPole, Pendulum};
use apo_envs::{
    Env, EnvError, SerialVecEnv, Space, ThreadedVecEnv, TimeLimit, VecEnv, VecStep, VectorEnv,
};
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

/// One vector step, bit for bit: observations, outcomes, the final-observation buffer, and
/// which `final_obs(i)` are `Some`.
type Record = (Vec<u32>, Vec<VecStep>, Vec<u32>, Vec<bool>);

/// Steps `venv` 400 times with actions drawn from a fixed stream, reseeding it at step 150 and
/// resetting it without a seed at step 300, and returns every observation, outcome and final
/// observation, bit for bit. With a non-empty `switch`, every 50 steps the vector moves to the
/// next thread count of `switch` (cycling), keeping its environments' state.
fn trajectory(mut venv: VecEnv, switch: &[usize]) -> Vec<Record> {
    use rand::{Rng, SeedableRng};
    let n = venv.num_envs();
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let mut obs = vec![0.0f32; n * venv.obs_dim()];
    let mut out = vec![VecStep::default(); n];
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
    venv.reset(Some(11), &mut obs);
    let discrete = matches!(venv.action_space(), Space::Discrete { .. });
    let mut records = vec![(bits(&obs), vec![], vec![], vec![])];
    for t in 0..400 {
        if !switch.is_empty() && t % 50 == 49 {
            let threads = switch[(t / 50) % switch.len()];
            venv = venv.with_threads(threads).expect("threads start");
            assert_eq!(venv.threads(), threads.min(n));
        }
        if t == 150 || t == 300 {
            venv.reset((t == 150).then_some(5), &mut obs);
            assert!((0..n).all(|i| venv.final_obs(i).is_none()));
            records.push((bits(&obs), vec![], bits(venv.final_obs_buffer()), vec![]));
        }
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
        let some: Vec<bool> = (0..n).map(|i| venv.final_obs(i).is_some()).collect();
        for (i, o) in out.iter().enumerate() {
            assert_eq!(
                some[i],
                o.done(),
                "final_obs({i}) is Some exactly when done"
            );
            if let Some(row) = venv.final_obs(i) {
                let dim = venv.obs_dim();
                assert_eq!(row, &venv.final_obs_buffer()[i * dim..(i + 1) * dim]);
            }
        }
        records.push((bits(&obs), out.clone(), bits(venv.final_obs_buffer()), some));
    }
    records
}

/// Scripted environments whose episodes end every 1 to 6 steps.
fn short_counters() -> VecEnv {
    counters(&[1, 2, 3, 4, 5, 6])
}

#[test]
fn threads_do_not_change_a_single_bit() {
    type Make = Box<dyn Fn() -> VecEnv>;
    let cases: [(&str, Make); 3] = [
        (
            "CartPole-v1",
            Box::new(|| VecEnv::make("CartPole-v1", 5).expect("registered")),
        ),
        (
            "Hopper",
            Box::new(|| VecEnv::make("Hopper", 7).expect("registered")),
        ),
        ("counters", Box::new(short_counters)),
    ];
    for (name, make) in cases {
        let serial = make();
        let n = serial.num_envs();
        assert_eq!(serial.threads(), 1);
        let reference = trajectory(serial, &[]);
        assert!(
            reference
                .iter()
                .any(|(_, out, _, _)| out.iter().any(VecStep::done)),
            "{name}: no episode ended, resets untested"
        );
        for threads in [1, 2, 3, n - 1, n, 64] {
            let venv = make().with_threads(threads).expect("threads start");
            assert_eq!(venv.threads(), threads.min(n));
            assert!(
                trajectory(venv, &[]) == reference,
                "{name}: {threads} threads changed the trajectory"
            );
        }
        let switching = trajectory(make(), &[2, 1, 3, n, 64, 1, 2]);
        assert!(
            switching == reference,
            "{name}: changing the thread count on the way changed the trajectory"
        );
    }
}

#[test]
fn the_implementations_behind_the_trait_agree() {
    let envs = |n| -> Vec<Box<dyn Env>> {
        (0..n)
            .map(|_| Box::new(TimeLimit::new(Pendulum::new(), 7)) as Box<dyn Env>)
            .collect()
    };
    let mut vectors: Vec<Box<dyn VectorEnv>> = vec![
        Box::new(SerialVecEnv::new(envs(5)).expect("same spaces")),
        Box::new(ThreadedVecEnv::new(envs(5), 2).expect("threads start")),
        Box::new(ThreadedVecEnv::new(envs(5), 5).expect("threads start")),
        Box::new(
            VecEnv::new(envs(5))
                .and_then(|v| v.with_threads(3))
                .expect("threads start"),
        ),
    ];
    let threads: Vec<usize> = vectors.iter().map(|v| v.threads()).collect();
    assert_eq!(threads, [1, 2, 5, 3]);
    let mut results = vec![];
    for venv in &mut vectors {
        assert_eq!((venv.num_envs(), venv.obs_dim(), venv.act_dim()), (5, 3, 1));
        assert_eq!(venv.action_space(), &Space::uniform_box(1, -2.0, 2.0));
        let mut obs = vec![0.0f32; 15];
        let mut out = vec![VecStep::default(); 5];
        let mut seen = vec![];
        venv.reset(Some(1), &mut obs);
        for k in 0..30 {
            let actions: Vec<f32> = (0..5)
                .map(|i| ((k * 5 + i) % 9) as f32 / 4.0 - 1.0)
                .collect();
            venv.step(&actions, &mut obs, &mut out);
            seen.push((obs.clone(), out.clone(), venv.final_obs_buffer().to_vec()));
        }
        assert!(out.iter().all(|o| !o.done()) && seen[27].1.iter().all(VecStep::done));
        results.push(seen);
    }
    assert!(results.iter().all(|r| r == &results[0]));
    // Back to the environments, in order: env i was reseeded with 1 + i.
    let threaded = ThreadedVecEnv::new(envs(4), 3).expect("threads start");
    let mut envs = threaded.into_envs();
    assert_eq!(envs.len(), 4);
    for (i, env) in envs.iter_mut().enumerate() {
        let (mut a, mut b) = ([0.0f32; 3], [0.0f32; 3]);
        env.reset(Some(40 + i as u64), &mut a);
        Pendulum::new().reset(Some(40 + i as u64), &mut b);
        assert_eq!(a, b);
    }
}

#[test]
fn threads_are_clamped_to_the_environments_and_zero_means_the_cores() {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    for n in [1, 3, 64] {
        let venv = counters(&vec![2; n])
            .with_threads(0)
            .expect("threads start");
        assert_eq!(venv.threads(), cores.min(n));
    }
    assert_eq!(
        counters(&[2, 2])
            .with_threads(9)
            .expect("threads start")
            .threads(),
        2
    );
    let threaded =
        ThreadedVecEnv::new(vec![Box::new(CartPole::new()) as Box<dyn Env>], 4).expect("one env");
    assert_eq!(threaded.threads(), 1);
    assert!(format!(
        "{:?}",
        VecEnv::make("CartPole-v1", 3)
            .unwrap()
            .with_threads(2)
            .unwrap()
    )
    .contains("threads: 2"));
}

#[test]
#[should_panic(expected = "not an index")]
fn discrete_action_out_of_range_panics_on_a_worker_too() {
    let mut venv = VecEnv::make("CartPole-v1", 4)
        .and_then(|v| v.with_threads(2))
        .expect("threads start");
    let mut obs = vec![0.0f32; 16];
    let mut out = vec![VecStep::default(); 4];
    venv.reset(Some(0), &mut obs);
    venv.step(&[0.0, 1.0, 0.0, 1.5], &mut obs, &mut out);
}

#[test]
#[should_panic(expected = "`actions` has length")]
fn wrong_buffer_length_panics_with_threads() {
    let mut venv = counters(&[2, 2, 2]).with_threads(3).expect("threads start");
    let mut obs = vec![0.0f32; 9];
    let mut out = vec![VecStep::default(); 3];
    venv.reset(None, &mut obs);
    venv.step(&[0.0; 2], &mut obs, &mut out);
}
