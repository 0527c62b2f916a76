//! Every MuJoCo task of apo on MuJoCo 3.17 (feature `mujoco3`): the Gym locomotion tasks, the
//! GUARD suites and the Shadow-hand tasks build and step on it, and on the Gym tasks the same
//! actions from the same start give trajectories close to MuJoCo 2.2.2's, within tolerances
//! measured here (docs/mujoco.md, "MuJoCo 3").
//!
//! Needs `libmujoco.so.3.17.0` (`scripts/setup.sh --mujoco3`) on the library path and Debian's
//! MuJoCo 2.2.2 (`libmujoco-dev`). Every test of this binary that builds through the registry
//! first makes MuJoCo 3 the process default; the comparisons name their physics explicitly.
#![cfg(feature = "mujoco3")]

use std::sync::Arc;

use apo_envs::mujoco::tasks::{
    Ant, HalfCheetah, Hopper, Humanoid, HumanoidStandup, InvertedDoublePendulum, InvertedPendulum,
    Reacher, Swimmer, Walker2d,
};
use apo_envs::mujoco::{set_default_physics, Model, MujocoEnv, Physics, Task};
use apo_envs::{registry, Action, Env};
use rand::{Rng, SeedableRng};

/// Builds task `T` on `physics`.
fn env<T: Task>(physics: Physics) -> MujocoEnv<T> {
    let model = Model::from_xml_str_with(T::MJCF, physics)
        .unwrap_or_else(|e| panic!("{} on {physics}: {e}", T::NAME));
    MujocoEnv::<T>::with_model(Arc::new(model))
        .unwrap_or_else(|e| panic!("{} on {physics}: {e}", T::NAME))
}

/// The largest difference between the two states, over the bodies' world positions (`xpos`) and
/// the velocities (`qvel`), each relative to `max(1, |value in 2.2.2|)`.
fn gap<T: Task>(two: &MujocoEnv<T>, three: &MujocoEnv<T>) -> f64 {
    let (a, b) = (two.data(), three.data());
    let positions = a.xpos().iter().flatten().zip(b.xpos().iter().flatten());
    positions
        .chain(a.qvel().iter().zip(b.qvel()))
        .map(|(x, y)| (x - y).abs() / x.abs().max(1.0))
        .fold(0.0, f64::max)
}

/// Steps `T` on both physics from the same seeded reset with the same uniform random actions
/// in [−1, 1] for `steps` steps (or until either episode ends) and returns the largest
/// [`gap`] over the steps, with the number of steps compared.
fn divergence<T: Task>(steps: usize) -> (f64, usize, Option<(usize, usize)>) {
    let mut two = env::<T>(Physics::Mujoco2);
    let mut three = env::<T>(Physics::Mujoco3);
    let n = T::OBS_DIM;
    let (mut a, mut b) = (vec![0.0f32; n], vec![0.0f32; n]);
    two.reset(Some(3), &mut a);
    three.reset(Some(3), &mut b);
    // The same seed draws the same start state. `qpos` itself may differ: MuJoCo 2.2's
    // `mj_forward` normalises free-joint quaternions in place, 3.x only in its own copy. So
    // the states are compared through the world positions of the bodies and `qvel`.
    assert!(gap(&two, &three) < 1e-12, "{}: the same start", T::NAME);
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let mut action = vec![0.0f32; T::SIZES.nu];
    let mut worst = 0.0f64;
    let mut first_apart = None;
    for step in 0..steps {
        action
            .iter_mut()
            .for_each(|x| *x = rng.random_range(-1.0..1.0));
        let ta = two.step(Action::Continuous(&action), &mut a);
        let tb = three.step(Action::Continuous(&action), &mut b);
        worst = worst.max(gap(&two, &three));
        if first_apart.is_none() && worst > 1e-9 {
            first_apart = Some((step + 1, two.data().ncon()));
        }
        if ta.terminated || tb.terminated {
            return (worst, step + 1, first_apart);
        }
    }
    (worst, steps, first_apart)
}

/// The tolerance on [`gap`] for the Gym tasks whose trajectories agree: 1e-8, where the
/// largest measured gap was 8.4e-10 (Swimmer after 1 000 steps) and the others ≤ 4e-15.
const TOLERANCE: f64 = 1e-8;

#[test]
fn gym_trajectories_stay_close_across_the_two_versions() {
    // Over the registered episode (or until the episode ends), the same actions from the same
    // start give the same states to rounding on these five tasks.
    let close = [
        ("InvertedPendulum", divergence::<InvertedPendulum>(1000)),
        (
            "InvertedDoublePendulum",
            divergence::<InvertedDoublePendulum>(1000),
        ),
        ("Reacher", divergence::<Reacher>(50)),
        ("Swimmer", divergence::<Swimmer>(1000)),
        ("Walker2d", divergence::<Walker2d>(1000)),
    ];
    for (name, (worst, steps, apart)) in close {
        eprintln!("{name}: gap {worst:.3e} over {steps} steps");
        assert!(
            worst < TOLERANCE,
            "{name}: gap {worst:.3e} at step {apart:?}"
        );
    }
    // The others part within their first steps (docs/mujoco.md, "MuJoCo 3"): the gap is
    // reported, and both versions must have simulated the same number of steps.
    let apart = [
        ("Hopper", divergence::<Hopper>(1000)),
        ("HalfCheetah", divergence::<HalfCheetah>(1000)),
        ("Ant", divergence::<Ant>(1000)),
        ("Humanoid", divergence::<Humanoid>(1000)),
        ("HumanoidStandup", divergence::<HumanoidStandup>(1000)),
    ];
    for (name, (worst, steps, apart)) in apart {
        eprintln!("{name}: gap {worst:.3e} over {steps} steps, above {TOLERANCE:e} from (step, contacts) {apart:?}");
        assert!(worst.is_finite() && steps > 0, "{name}");
    }
}

#[test]
fn every_registered_mujoco_task_builds_and_steps_on_mujoco3() {
    set_default_physics(Physics::Mujoco3);
    let names: Vec<String> = registry::list()
        .into_iter()
        .filter(|spec| matches!(spec.family.as_str(), "mujoco" | "guard" | "hand"))
        .map(|spec| spec.name)
        .collect();
    assert_eq!(names.len(), 10 + 17 + 6, "{names:?}");
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    for name in &names {
        let mut env = registry::make(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut obs = vec![0.0f32; env.observation_space().flat_dim()];
        let mut action = vec![0.0f32; env.action_space().flat_dim()];
        env.reset(Some(1), &mut obs);
        let mut unstable = 0;
        for _ in 0..100 {
            action
                .iter_mut()
                .for_each(|x| *x = rng.random_range(-1.0..1.0));
            let t = env.step(Action::Continuous(&action), &mut obs);
            assert!(obs.iter().all(|x| x.is_finite()), "{name}");
            assert!(t.reward.is_finite(), "{name}");
            unstable += usize::from(t.info.unstable);
            if t.terminated || t.truncated {
                env.reset(None, &mut obs);
            }
        }
        assert_eq!(unstable, 0, "{name}: unstable steps under random actions");
    }
}
