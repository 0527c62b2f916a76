//! The registry: names, specs, wrapping, suggestions, families registered from outside, and
//! box shapes.

use std::time::Instant;

use apo_envs::registry::{self, EnvSpec, Family};
use apo_envs::{Action, Env, EnvError, Space, StepInfo, Transition};

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
            name: name.to_owned(),
            family: "classic".to_owned(),
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
        let mut env = registry::make(&spec.name).unwrap_or_else(|e| panic!("{}: {e}", spec.name));
        assert_eq!(
            env.observation_space().flat_dim(),
            spec.observation_dim,
            "{}",
            spec.name
        );
        assert_eq!(env.action_space(), &spec.action_space, "{}", spec.name);
        assert_eq!(registry::spec(&spec.name).expect("registered"), spec);
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

// ------------------------------------------------------------------ open registry

/// A test environment whose sizes depend on its builder's arguments: `robot` has `joints`
/// joints (the observation is `2 · joints` reals), and the `reach` task acts with one torque
/// per joint while the `switch` task picks one of `joints` joints. Reward: the step's index.
struct Robot {
    t: usize,
    observation_space: Space,
    action_space: Space,
}

impl Robot {
    fn new(task: &str, joints: usize) -> Self {
        Robot {
            t: 0,
            observation_space: Space::uniform_box(2 * joints, -1.0, 1.0),
            action_space: match task {
                "reach" => Space::uniform_box(joints, -3.0, 3.0),
                _ => Space::Discrete { n: joints },
            },
        }
    }
}

impl Env for Robot {
    fn observation_space(&self) -> &Space {
        &self.observation_space
    }
    fn action_space(&self) -> &Space {
        &self.action_space
    }
    fn reset(&mut self, _seed: Option<u64>, obs: &mut [f32]) {
        self.t = 0;
        obs.fill(0.0);
    }
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        self.t += 1;
        let first = match action {
            Action::Continuous(a) => a[0],
            Action::Discrete(i) => i as f32,
        };
        obs.fill(0.0);
        obs[0] = first / 3.0;
        Transition {
            reward: self.t as f64,
            terminated: false,
            truncated: false,
            info: StepInfo::default(),
        }
    }
}

#[test]
fn a_family_generated_from_a_grid_is_made_by_name_with_its_own_sizes() {
    let tasks = ["reach", "switch"];
    let robots = [("arm", 2), ("snake", 5), ("hexapod", 18)];
    let mut family = Family::new("robots");
    for task in tasks {
        for (robot, joints) in robots {
            family.add(format!("Grid{task}_{robot}-v0"), 7, move || {
                Ok(Box::new(Robot::new(task, joints)))
            });
        }
    }
    assert_eq!(family.name(), "robots");
    registry::register(family).expect("new names");

    for task in tasks {
        for (robot, joints) in robots {
            let name = format!("Grid{task}_{robot}-v0");
            let spec = registry::spec(&name).expect("registered");
            let action_space = if task == "reach" {
                Space::uniform_box(joints, -1.0, 1.0) // rescaled for the policy
            } else {
                Space::Discrete { n: joints }
            };
            assert_eq!(
                spec,
                EnvSpec {
                    name: name.clone(),
                    family: "robots".to_owned(),
                    observation_dim: 2 * joints,
                    action_space: action_space.clone(),
                    max_episode_steps: 7,
                }
            );
            assert!(registry::list().contains(&spec), "{name} listed");

            // Made by name (any case, or without the version), rescaled and time-limited.
            let mut env = registry::make(&name.to_lowercase()).expect("registered");
            assert_eq!(env.action_space(), &action_space);
            let mut obs = vec![0.0f32; spec.observation_dim];
            env.reset(Some(1), &mut obs);
            let action = vec![1.0f32; joints];
            let mut steps = 0;
            loop {
                steps += 1;
                let t = match task {
                    "reach" => env.step(Action::Continuous(&action), &mut obs),
                    _ => env.step(Action::Discrete(joints - 1), &mut obs),
                };
                assert_eq!(t.reward, steps as f64);
                if t.done() {
                    assert!(t.truncated && !t.terminated);
                    break;
                }
            }
            assert_eq!(steps, 7, "{name}");
            // Policy action 1.0 is the robot's torque 3.0, or the last joint's index.
            let expected = if task == "reach" {
                1.0
            } else {
                (joints - 1) as f32 / 3.0
            };
            assert_eq!(obs[0], expected, "{name}");
            assert!(registry::spec(&format!("grid{task}_{robot}")).is_ok());
        }
    }
    let vector = apo_envs::VecEnv::make("Gridswitch_snake-v0", 3).expect("registered");
    assert_eq!(vector.observation_space().flat_dim(), 10);
}

#[test]
fn a_taken_name_is_refused_naming_it_and_its_family() {
    let mut family = Family::new("late-classics");
    family
        .add("DupA-v0", 10, || Ok(Box::new(Robot::new("reach", 1))))
        .add("cartpole-V1", 10, || Ok(Box::new(Robot::new("reach", 1))));
    let err = registry::register(family).expect_err("CartPole-v1 is taken");
    let EnvError::AlreadyRegistered {
        name,
        family,
        existing,
        holder,
    } = &err
    else {
        panic!("{err}")
    };
    assert_eq!(
        (
            name.as_str(),
            family.as_str(),
            existing.as_str(),
            holder.as_str()
        ),
        ("cartpole-V1", "late-classics", "CartPole-v1", "classic")
    );
    let message = err.to_string();
    assert!(
        message.contains("`cartpole-V1`")
            && message.contains("`CartPole-v1`")
            && message.contains("family `classic`"),
        "{message}"
    );
    // Nothing of a refused family is registered.
    assert!(matches!(
        registry::spec("DupA-v0"),
        Err(EnvError::Unknown { .. })
    ));

    // Twice in one family, or in two registrations.
    let mut family = Family::new("twins");
    family
        .add("Twin-v0", 10, || Ok(Box::new(Robot::new("reach", 1))))
        .add("Twin-v0", 20, || Ok(Box::new(Robot::new("reach", 2))));
    let err = registry::register(family).expect_err("twice");
    assert!(
        matches!(&err, EnvError::AlreadyRegistered { name, holder, .. } if name == "Twin-v0" && holder == "twins"),
        "{err}"
    );
    let mut family = Family::new("once");
    family.add("Once-v0", 10, || Ok(Box::new(Robot::new("reach", 1))));
    registry::register(family).expect("new");
    let mut family = Family::new("again");
    family.add("Once-v0", 10, || Ok(Box::new(Robot::new("reach", 1))));
    let err = registry::register(family).expect_err("taken");
    assert_eq!(
        err.to_string(),
        "cannot register `Once-v0` (family `again`): `Once-v0` is already registered by family `once`"
    );
    assert_eq!(registry::spec("Once-v0").expect("kept").family, "once");
}

#[test]
fn registered_families_get_suggestions_too() {
    let mut family = Family::new("suggested");
    family.add("Quokka-v3", 10, || Ok(Box::new(Robot::new("switch", 2))));
    registry::register(family).expect("new");
    let err = registry::make("Qukka-v3").err().expect("unknown");
    let EnvError::Unknown {
        suggestions,
        registered,
        ..
    } = &err
    else {
        panic!("{err}")
    };
    assert_eq!(suggestions.first().map(String::as_str), Some("Quokka-v3"));
    assert!(registered.iter().any(|n| n == "CartPole-v1"));
    assert!(registry::spec("quokka").is_ok());
}

#[test]
fn a_family_that_cannot_be_built_reports_why_and_is_not_listed() {
    let mut family = Family::new("broken");
    family.add("Broken-v0", 10, || {
        Err(EnvError::Init {
            name: "Broken-v0".into(),
            reason: "no such device".into(),
        })
    });
    registry::register(family).expect("new");
    for err in [
        registry::spec("Broken-v0").expect_err("cannot build"),
        registry::make("broken").err().expect("cannot build"),
    ] {
        assert!(err.to_string().contains("no such device"), "{err}");
    }
    assert!(registry::list().iter().all(|s| s.name != "Broken-v0"));
}

#[test]
fn families_register_from_many_threads() {
    std::thread::scope(|scope| {
        for worker in 0..4 {
            scope.spawn(move || {
                let mut family = Family::new(format!("threads{worker}"));
                for i in 0..25 {
                    family.add(format!("Threaded{worker}x{i}-v0"), 5, move || {
                        Ok(Box::new(Robot::new("switch", i + 1)))
                    });
                }
                registry::register(family).expect("distinct names");
                registry::make(&format!("Threaded{worker}x3")).expect("registered");
            });
        }
    });
    let specs = registry::list();
    for worker in 0..4 {
        for i in 0..25 {
            let name = format!("Threaded{worker}x{i}-v0");
            let spec = specs.iter().find(|s| s.name == name).expect("listed");
            assert_eq!(spec.action_space, Space::Discrete { n: i + 1 });
        }
    }
}

#[test]
fn built_in_families_are_listed_with_unique_names() {
    let start = Instant::now();
    let specs = registry::list();
    let elapsed = start.elapsed();
    eprintln!("list(): {} environments in {elapsed:?}", specs.len());
    assert!(elapsed.as_secs_f64() < 5.0, "{elapsed:?}");
    let built_in: Vec<_> = specs
        .iter()
        .filter(|s| s.family == "classic" || s.family == "mujoco")
        .map(|s| (s.family.as_str(), s.name.as_str()))
        .collect();
    assert_eq!(
        &built_in[..4],
        &[
            ("classic", "CartPole-v1"),
            ("classic", "Acrobot-v1"),
            ("classic", "Pendulum-v1"),
            ("classic", "MountainCarContinuous-v0"),
        ]
    );
    assert_eq!(built_in.len(), 14);
    assert!(built_in[4..]
        .iter()
        .all(|(f, n)| *f == "mujoco" && n.ends_with("-v4")));
    let mut lower: Vec<String> = specs.iter().map(|s| s.name.to_lowercase()).collect();
    lower.sort();
    lower.dedup();
    assert_eq!(lower.len(), specs.len(), "names are unique up to case");
}

// ------------------------------------------------------------------ box shapes

#[test]
fn boxes_carry_a_shape() {
    let image = Space::box_with_shape(vec![0.0; 6], vec![1.0; 6], vec![2, 3]).expect("6 bounds");
    assert_eq!(image.flat_dim(), 6);
    assert_eq!(image.shape(), &[2, 3]);
    assert!(image.contains(&[0.5; 6]));
    assert!(!image.contains(&[0.5; 5]));

    let err = Space::box_with_shape(vec![0.0; 6], vec![1.0; 5], vec![2, 3]).expect_err("5 upper");
    assert_eq!((err.low, err.high, err.shape.clone()), (6, 5, vec![2, 3]));
    assert!(err.to_string().contains("needs 6 bounds"), "{err}");

    assert_eq!(Space::uniform_box(4, -1.0, 1.0).shape(), &[4]);
    assert_eq!(Space::Discrete { n: 3 }.shape(), &[] as &[usize]);
    // A bare classic environment states its boxes' shapes.
    assert_eq!(
        apo_envs::classic::Pendulum::new()
            .observation_space()
            .shape(),
        &[3]
    );

    // The policy's box keeps the environment's shape.
    let mut family = Family::new("shaped");
    family.add("ShapedActions-v0", 10, || {
        let mut robot = Robot::new("reach", 6);
        robot.action_space =
            Space::box_with_shape(vec![-2.0; 6], vec![2.0; 6], vec![3, 2]).expect("6 bounds");
        Ok(Box::new(robot))
    });
    registry::register(family).expect("new");
    let spec = registry::spec("ShapedActions").expect("registered");
    assert_eq!(spec.action_space.shape(), &[3, 2]);
    assert_eq!(
        spec.action_space,
        Space::box_with_shape(vec![-1.0; 6], vec![1.0; 6], vec![3, 2]).expect("6 bounds")
    );
}

#[test]
fn make_with_raw_actions_and_a_fixed_reset_seed() {
    use apo_envs::MakeOptions;
    // raw actions: Pendulum's own box [-2, 2], and an action of 2 is a torque of 2
    let raw = MakeOptions {
        rescale_actions: false,
        ..MakeOptions::default()
    };
    let mut env = registry::make_with("Pendulum-v1", &raw).expect("pendulum");
    assert_eq!(env.action_space(), &Space::uniform_box(1, -2.0, 2.0));
    let mut rescaled = registry::make("Pendulum-v1").expect("pendulum");
    assert_eq!(rescaled.action_space(), &Space::uniform_box(1, -1.0, 1.0));
    let (mut a, mut b) = ([0.0f32; 3], [0.0f32; 3]);
    env.reset(Some(3), &mut a);
    rescaled.reset(Some(3), &mut b);
    assert_eq!(a, b);
    let raw_step = env.step(Action::Continuous(&[2.0]), &mut a);
    let rescaled_step = rescaled.step(Action::Continuous(&[1.0]), &mut b);
    assert_eq!(a, b, "torque 2 either way");
    assert_eq!(raw_step.reward, rescaled_step.reward);
    // beyond the box, on a MuJoCo task: the simulator clamps the control either way, but the
    // control cost sees the raw action (Hopper: 1e-3 · Σa²)
    let mut raw_hopper = registry::make_with("Hopper-v4", &raw).expect("hopper");
    let mut hopper = registry::make("Hopper-v4").expect("hopper");
    let (mut a, mut b) = ([0.0f32; 11], [0.0f32; 11]);
    raw_hopper.reset(Some(3), &mut a);
    hopper.reset(Some(3), &mut b);
    let far = raw_hopper.step(Action::Continuous(&[3.0, 3.0, 3.0]), &mut a);
    let clipped = hopper.step(Action::Continuous(&[1.5, 1.5, 1.5]), &mut b);
    assert_eq!(a, b, "the controls are clamped to [-1, 1] either way");
    let cost_gap = clipped.reward - far.reward;
    assert!(
        (cost_gap - 1e-3 * (27.0 - 3.0)).abs() < 1e-9,
        "control costs 1e-3·27 raw, 1e-3·3 clipped: gap {cost_gap}"
    );

    // a fixed reset seed: every reset, seeded or not, starts from the same state
    let fixed = MakeOptions {
        fixed_reset_seed: Some(11),
        ..MakeOptions::default()
    };
    let mut env = registry::make_with("Pendulum-v1", &fixed).expect("pendulum");
    let (mut first, mut again, mut other) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 3]);
    env.reset(Some(1), &mut first);
    env.reset(None, &mut again);
    assert_eq!(first, again);
    env.reset(Some(2), &mut again);
    assert_eq!(first, again);
    let mut plain = registry::make("Pendulum-v1").expect("pendulum");
    plain.reset(Some(11), &mut other);
    assert_eq!(first, other, "the fixed seed is the seed of every reset");
    plain.reset(None, &mut other);
    assert_ne!(first, other, "without it, the stream continues");
}

#[test]
fn make_with_another_time_limit() {
    use apo_envs::MakeOptions;
    let short = MakeOptions {
        max_episode_steps: Some(7),
        ..MakeOptions::default()
    };
    let mut env = registry::make_with("Pendulum-v1", &short).expect("pendulum");
    let mut obs = [0.0f32; 3];
    env.reset(Some(0), &mut obs);
    for step in 1..=7 {
        let out = env.step(Action::Continuous(&[0.0]), &mut obs);
        assert!(!out.terminated, "Pendulum never terminates");
        assert_eq!(out.truncated, step == 7, "cut after 7 steps, not {step}");
    }
    // the registered limit when not overridden
    assert_eq!(
        registry::spec("Pendulum-v1")
            .expect("spec")
            .max_episode_steps,
        200
    );
}

#[test]
fn stated_discrete_sizes_are_listed_without_a_build_and_checked_at_build() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;

    use apo_envs::classic::CartPole;
    let builds = Arc::new(AtomicUsize::new(0));
    let mut family = Family::new("stated-corridors");
    let counted = Arc::clone(&builds);
    family.add_discrete("StatedCartPole-v0", 10, 4, 2, move || {
        counted.fetch_add(1, Ordering::SeqCst);
        Ok(Box::new(CartPole::new()))
    });
    // states 3 actions, but CartPole has 2
    family.add_discrete("MisstatedCartPole-v0", 10, 4, 3, || {
        Ok(Box::new(CartPole::new()))
    });
    registry::register(family).expect("new names");
    let spec = registry::spec("StatedCartPole-v0").expect("stated");
    assert_eq!(
        (spec.observation_dim, spec.action_space),
        (4, Space::Discrete { n: 2 })
    );
    assert!(registry::list()
        .iter()
        .any(|s| s.name == "MisstatedCartPole-v0"));
    assert_eq!(builds.load(Ordering::SeqCst), 0, "listing built nothing");
    registry::make("StatedCartPole-v0").expect("sizes as stated");
    assert_eq!(builds.load(Ordering::SeqCst), 1);
    let err = registry::make("MisstatedCartPole-v0")
        .err()
        .expect("a misstated family is caught")
        .to_string();
    assert!(
        err.contains("MisstatedCartPole-v0") && err.contains("states"),
        "{err}"
    );
}
