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

/// Builds task `T` with the model `mjcf` on `physics`.
fn env<T: Task>(mjcf: &str, physics: Physics) -> MujocoEnv<T> {
    let model = Model::from_xml_str_with(mjcf, physics)
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

/// Two versions' trajectories compared step by step.
struct Divergence {
    /// The largest [`gap`] over the steps.
    worst: f64,
    /// The steps compared.
    steps: usize,
    /// The first (step, contacts in 2.2.2) where the gap passed 1e-9.
    apart: Option<(usize, usize)>,
    /// Each step's gap, and whether either version had a contact after it.
    each: Vec<(f64, bool)>,
}

/// Steps `T` on both physics from the same seeded reset with the same uniform random actions
/// in [−1, 1] for `steps` steps (or until either episode ends).
fn divergence<T: Task>(steps: usize) -> Divergence {
    divergence_of::<T>(T::MJCF, steps)
}

/// [`divergence`] with the model `mjcf`.
fn divergence_of<T: Task>(mjcf: &str, steps: usize) -> Divergence {
    let mut two = env::<T>(mjcf, Physics::Mujoco2);
    let mut three = env::<T>(mjcf, Physics::Mujoco3);
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
    let mut out = Divergence {
        worst: 0.0,
        steps: 0,
        apart: None,
        each: Vec::new(),
    };
    for step in 0..steps {
        action
            .iter_mut()
            .for_each(|x| *x = rng.random_range(-1.0..1.0));
        let ta = two.step(Action::Continuous(&action), &mut a);
        let tb = three.step(Action::Continuous(&action), &mut b);
        let now = gap(&two, &three);
        out.each
            .push((now, two.data().ncon() + three.data().ncon() > 0));
        out.worst = out.worst.max(now);
        out.steps = step + 1;
        if out.apart.is_none() && out.worst > 1e-9 {
            out.apart = Some((step + 1, two.data().ncon()));
        }
        if ta.terminated || tb.terminated {
            break;
        }
    }
    out
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
    for (name, d) in close {
        eprintln!("{name}: gap {:.3e} over {} steps", d.worst, d.steps);
        assert!(
            d.worst < TOLERANCE,
            "{name}: gap {:.3e} at step {:?}",
            d.worst,
            d.apart
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
    for (name, d) in apart {
        eprintln!(
            "{name}: gap {:.3e} over {} steps, above 1e-9 from (step, contacts) {:?}",
            d.worst, d.steps, d.apart
        );
        assert!(d.worst.is_finite() && d.steps > 0, "{name}");
    }
}

#[test]
fn humanoid_parts_through_its_solver_budget_and_then_at_the_first_contact() {
    // The knee limits (−160°..−2°) are active from the start (q = 0), so the constraint solver
    // runs from the first step; its registered budget (PGS, 50 iterations, tolerance 1e-8)
    // stops the two versions' iterations at points about 1e-9 apart.
    let first = divergence::<Humanoid>(3).each[0].0;
    assert!((1e-12..1e-6).contains(&first), "step 1 gap {first:.3e}");
    // Solved to convergence, the versions agree to rounding until the first contact.
    let converged =
        Humanoid::MJCF.replace(r#"iterations="50""#, r#"iterations="1000" tolerance="0""#);
    assert_ne!(
        converged,
        Humanoid::MJCF,
        "the option to replace is in the model"
    );
    let each = divergence_of::<Humanoid>(&converged, 1000).each;
    let contact = each
        .iter()
        .position(|&(_, contact)| contact)
        .expect("the humanoid falls onto the floor");
    assert!(contact >= 5, "first contact after step {}", contact + 1);
    let before = each[..contact].iter().map(|&(g, _)| g).fold(0.0, f64::max);
    eprintln!(
        "Humanoid, solver converged: gap {before:.3e} over the {contact} steps before the first \
         contact, {:.3e} at it",
        each[contact].0
    );
    assert!(before < 1e-12, "gap {before:.3e} before the first contact");
    assert!(
        each[contact].0 > 1e-6,
        "the contact step parts the versions"
    );
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

/// The number of pixels that differ between two frames of one size.
fn changed(a: &apo_envs::Frame, b: &apo_envs::Frame) -> usize {
    a.rgb()
        .chunks_exact(3)
        .zip(b.rgb().chunks_exact(3))
        .filter(|(p, q)| p != q)
        .count()
}

#[test]
fn mujoco3_renders_with_its_own_renderer_like_mujoco2() {
    use apo_envs::{Camera, Frame};
    let mut two = env::<Hopper>(Hopper::MJCF, Physics::Mujoco2);
    let mut three = env::<Hopper>(Hopper::MJCF, Physics::Mujoco3);
    let qpos = [0.0, 1.25, 0.0, 0.0, 0.0, 0.0];
    two.set_state(&qpos, &[0.0; 6]);
    three.set_state(&qpos, &[0.0; 6]);
    let mut a = Frame::new(160, 120).expect("frame");
    let mut b = a.clone();
    let mut again = a.clone();
    two.render(&Camera::Track, &mut a)
        .expect("MuJoCo 2.2.2 renders");
    three
        .render(&Camera::Track, &mut b)
        .expect("MuJoCo 3.17 renders");
    three
        .render(&Camera::Track, &mut again)
        .expect("MuJoCo 3.17 renders");
    assert_eq!(changed(&b, &again), 0, "the same state rendered twice");
    // the same scene from the same camera: most pixels agree between the versions
    let differ = changed(&a, &b);
    assert!(
        differ < 160 * 120 / 5,
        "{differ} of {} pixels differ",
        160 * 120
    );
    // another state moves the robot's pixels
    three.set_state(&[0.0, 1.25, 0.0, -1.0, -1.0, 0.8], &[0.0; 6]);
    three
        .render(&Camera::Track, &mut again)
        .expect("MuJoCo 3.17 renders");
    assert!(changed(&b, &again) > 100);
    assert!(matches!(
        three.render(&Camera::Named("nope".into()), &mut again),
        Err(apo_envs::RenderError::UnknownCamera { .. })
    ));
}
