//! The registry: names, specs, wrapping and suggestions.

use apo_envs::registry::{self, EnvSpec};
use apo_envs::{Action, EnvError, Space};

#[test]
fn list_describes_the_classic_environments() {
    let specs = registry::list();
    let expected = [
        ("CartPole-v1", 4, Space::Discrete { n: 2 }, 500),
        ("Acrobot-v1", 6, Space::Discrete { n: 3 }, 500),
        ("Pendulum-v1", 3, Space::uniform_box(1, -1.0, 1.0), 200),
        (
            "MountainCarContinuous-v0",
            2,
            Space::uniform_box(1, -1.0, 1.0),
            999,
        ),
    ];
    for (name, observation_dim, action_space, max_episode_steps) in expected {
        let want = EnvSpec {
            name,
            observation_dim,
            action_space,
            max_episode_steps,
        };
        assert!(specs.contains(&want), "{want:?} missing from {specs:?}");
    }
}

#[test]
fn every_registered_env_matches_its_spec() {
    for spec in registry::list() {
        let mut env = registry::make(spec.name).unwrap_or_else(|e| panic!("{}: {e}", spec.name));
        assert_eq!(
            env.observation_space().flat_dim(),
            spec.observation_dim,
            "{}",
            spec.name
        );
        assert_eq!(env.action_space(), &spec.action_space, "{}", spec.name);
        assert_eq!(registry::spec(spec.name).expect("registered"), spec);
        let mut obs = vec![0.0f32; spec.observation_dim];
        env.reset(Some(0), &mut obs);
        assert!(
            env.observation_space().contains(&obs),
            "{}: {obs:?}",
            spec.name
        );
    }
}

#[test]
fn made_envs_are_time_limited_and_act_in_unit_box() {
    // Pendulum never terminates: the 200-step limit truncates it.
    let mut env = registry::make("Pendulum-v1").expect("registered");
    let mut obs = [0.0f32; 3];
    env.reset(Some(0), &mut obs);
    let mut steps = 0;
    let last = loop {
        steps += 1;
        // 1.0 is the largest policy action; it maps to torque 2.
        let t = env.step(Action::Continuous(&[1.0]), &mut obs);
        if t.done() {
            break t;
        }
    };
    assert_eq!(steps, 200);
    assert!(last.truncated && !last.terminated);

    // Policy action 0.5 on Pendulum is torque 1: the reward's action term is 0.001 · 1².
    let mut wrapped = registry::make("Pendulum-v1").expect("registered");
    let mut bare = apo_envs::classic::Pendulum::new();
    let (mut o1, mut o2) = ([0.0f32; 3], [0.0f32; 3]);
    wrapped.reset(Some(9), &mut o1);
    apo_envs::Env::reset(&mut bare, Some(9), &mut o2);
    let t1 = wrapped.step(Action::Continuous(&[0.5]), &mut o1);
    let t2 = apo_envs::Env::step(&mut bare, Action::Continuous(&[1.0]), &mut o2);
    assert_eq!((o1, t1.reward), (o2, t2.reward));

    // CartPole stays discrete, limited to 500 steps.
    let mut env = registry::make("CartPole-v1").expect("registered");
    assert_eq!(env.action_space(), &Space::Discrete { n: 2 });
    let mut obs = [0.0f32; 4];
    env.reset(Some(0), &mut obs);
    let t = env.step(Action::Discrete(0), &mut obs);
    assert_eq!(t.reward, 1.0);
}

#[test]
fn names_match_case_insensitively_and_without_version() {
    for name in ["pendulum-v1", "PENDULUM-V1", "Pendulum", "pendulum"] {
        assert_eq!(
            registry::spec(name).expect(name).name,
            "Pendulum-v1",
            "{name}"
        );
    }
    assert_eq!(
        registry::spec("mountaincarcontinuous")
            .expect("unversioned")
            .name,
        "MountainCarContinuous-v0"
    );
    assert!(registry::make("cartpole-v1").is_ok());
    // A wrong version is not silently accepted.
    assert!(matches!(
        registry::spec("Pendulum-v0"),
        Err(EnvError::Unknown { .. })
    ));
}

#[test]
fn misspelled_names_get_suggestions() {
    let Err(EnvError::Unknown {
        name, suggestions, ..
    }) = registry::make("Pendulm-v1")
    else {
        panic!("expected an unknown-name error");
    };
    assert_eq!(name, "Pendulm-v1");
    assert_eq!(suggestions.first().map(String::as_str), Some("Pendulum-v1"));

    let err = registry::make("cartpol").err().expect("unknown");
    let EnvError::Unknown { suggestions, .. } = &err else {
        panic!("{err}")
    };
    assert_eq!(suggestions.first().map(String::as_str), Some("CartPole-v1"));
    let message = err.to_string();
    assert!(
        message.contains("unknown environment `cartpol`"),
        "{message}"
    );
    assert!(
        message.contains("did you mean `CartPole-v1`?") || message.contains("`CartPole-v1`,"),
        "{message}"
    );

    // The wrong version of a registered name suggests the right one.
    let err = registry::spec("Acrobot-v2").expect_err("unknown");
    let EnvError::Unknown { suggestions, .. } = &err else {
        panic!("{err}")
    };
    assert_eq!(suggestions.first().map(String::as_str), Some("Acrobot-v1"));

    // Nothing close: no suggestions, the message lists the registered names.
    let err = registry::make("zzzzqqqq").err().expect("unknown");
    let EnvError::Unknown { suggestions, .. } = &err else {
        panic!("{err}")
    };
    assert!(suggestions.is_empty(), "{suggestions:?}");
    let message = err.to_string();
    assert!(
        message.contains("registered environments:")
            && message.contains("`MountainCarContinuous-v0`"),
        "{message}"
    );
}
