//! Each GUARD robot's compiled model against the facts of GUARD's own model (`guard_models/facts.rs`,
//! docs/guard.md "Robot models field by field"): masses, inertias, joint anchors, axes, ranges,
//! stiffness, damping, armature, geom sizes and contact parameters, actuators and the step, so
//! that an edit of `assets/guard/*.xml` cannot change a robot's dynamics unnoticed.
//! Needs Debian's `libmujoco-dev` (MuJoCo 2.2.2).

mod guard_models {
    pub mod facts;
}

use apo_envs::mujoco::guard::{Robot, Suite, TaskKind, BALL_RADIUS};
use apo_envs::mujoco::{Dynamics, Model};
use guard_models::facts::{facts, Facts};

/// The compiled dynamics of `task` on `robot`.
fn compiled(task: TaskKind, robot: Robot) -> Dynamics {
    let xml = Suite { task, robot }.mjcf();
    Model::from_xml_str(&xml)
        .unwrap_or_else(|e| panic!("{}: {e}", robot.name()))
        .dynamics()
}

/// Every mismatch of `ours` against `facts`, one line each (`field[index]: ours vs GUARD`),
/// to 1e-8 relative.
fn mismatches<const N: usize>(field: &str, ours: &[[f64; N]], facts: &[[f64; N]]) -> Vec<String> {
    if ours.len() != facts.len() {
        return vec![format!(
            "{field}: {} entries vs GUARD's {}",
            ours.len(),
            facts.len()
        )];
    }
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-8 * a.abs().max(b.abs()).max(1.0);
    ours.iter()
        .zip(facts)
        .enumerate()
        .filter(|(_, (o, f))| !o.iter().zip(f.iter()).all(|(&a, &b)| close(a, b)))
        .map(|(i, (o, f))| format!("{field}[{i}]: ours {o:?} vs GUARD {f:?}"))
        .collect()
}

/// `xs` as one-element rows, to compare scalars with [`mismatches`].
fn rows(xs: &[f64]) -> Vec<[f64; 1]> {
    xs.iter().map(|&x| [x]).collect()
}

/// Every difference between `d` and `f`.
fn differences(d: &Dynamics, f: &Facts) -> Vec<String> {
    let ranges = |limited: &[bool], ranges: &[[f64; 2]]| -> Vec<[f64; 2]> {
        limited
            .iter()
            .zip(ranges)
            .map(|(&l, &r)| if l { r } else { [0.0; 2] })
            .collect()
    };
    let mut out = Vec::new();
    out.extend(mismatches("timestep", &[[d.timestep]], &[[f.timestep]]));
    out.extend(mismatches("gravity", &[d.gravity], &[f.gravity]));
    out.extend(mismatches("magnetic", &[d.magnetic], &[[0.0, -0.5, 0.0]]));
    // GUARD's files set no solver option: MuJoCo 2.2.2's defaults, Euler with pyramidal cones.
    let solver = |d: &Dynamics| {
        [
            f64::from(d.integrator),
            f64::from(d.cone),
            d.impratio,
            f64::from(d.iterations),
            d.tolerance,
            f64::from(d.disableflags),
            f64::from(d.enableflags),
        ]
    };
    out.extend(mismatches(
        "solver (integrator, cone, impratio, iterations, tolerance, disable and enable flags)",
        &[solver(d)],
        &[[0.0, 0.0, 1.0, 100.0, 1e-8, 0.0, 0.0]],
    ));
    out.extend(mismatches(
        "body_mass",
        &rows(&d.body_mass),
        &rows(f.body_mass),
    ));
    out.extend(mismatches("body_inertia", &d.body_inertia, f.body_inertia));
    out.extend(mismatches("jnt_pos", &d.jnt_pos, f.jnt_pos));
    out.extend(mismatches("jnt_axis", &d.jnt_axis, f.jnt_axis));
    out.extend(mismatches(
        "jnt_stiffness",
        &rows(&d.jnt_stiffness),
        &rows(f.jnt_stiffness),
    ));
    out.extend(mismatches(
        "jnt_range",
        &ranges(&d.jnt_limited, &d.jnt_range),
        f.jnt_range,
    ));
    out.extend(mismatches(
        "dof_armature",
        &rows(&d.dof_armature),
        &rows(f.dof_armature),
    ));
    out.extend(mismatches(
        "dof_damping",
        &rows(&d.dof_damping),
        &rows(f.dof_damping),
    ));
    out.extend(mismatches("geom_size", &d.geom_size, f.geom_size));
    out.extend(mismatches("geom_pos", &d.geom_pos, f.geom_pos));
    out.extend(mismatches(
        "geom_friction",
        &d.geom_friction,
        f.geom_friction,
    ));
    let condim = |c: &[i32]| rows(&c.iter().map(|&c| f64::from(c)).collect::<Vec<_>>());
    out.extend(mismatches(
        "geom_condim",
        &condim(&d.geom_condim),
        &condim(f.geom_condim),
    ));
    out.extend(mismatches(
        "geom_margin",
        &rows(&d.geom_margin),
        &rows(f.geom_margin),
    ));
    out.extend(mismatches("geom_solref", &d.geom_solref, f.geom_solref));
    out.extend(mismatches("geom_solimp", &d.geom_solimp, f.geom_solimp));
    let gear: Vec<[f64; 6]> = f
        .actuator_gear
        .iter()
        .map(|&g| [g, 0.0, 0.0, 0.0, 0.0, 0.0])
        .collect();
    out.extend(mismatches("actuator_gear", &d.actuator_gear, &gear));
    out.extend(mismatches(
        "actuator_forcerange",
        &ranges(&d.actuator_forcelimited, &d.actuator_forcerange),
        f.actuator_forcerange,
    ));
    out
}

/// Checks `robot`'s model (its Goal suite: the robot's file alone) against its facts, the body
/// and geom positions and the control ranges too.
fn check(robot: Robot) {
    let f = facts(robot);
    let xml = Suite {
        task: TaskKind::Goal,
        robot,
    }
    .mjcf();
    let model = Model::from_xml_str(&xml).unwrap_or_else(|e| panic!("{}: {e}", robot.name()));
    let mut out = differences(&model.dynamics(), &f);
    out.extend(mismatches("body_pos", model.body_pos(), f.body_pos));
    out.extend(mismatches(
        "actuator_ctrlrange",
        model.actuator_ctrlrange(),
        f.actuator_ctrlrange,
    ));
    assert!(
        out.is_empty(),
        "{} differs from GUARD's model:\n{}",
        robot.name(),
        out.join("\n")
    );
}

#[test]
fn point_model_has_guards_dynamics() {
    check(Robot::Point);
}

#[test]
fn swimmer_model_has_guards_dynamics() {
    check(Robot::Swimmer);
}

#[test]
fn arm3_model_has_guards_dynamics() {
    check(Robot::Arm3);
}

#[test]
fn drone_model_has_guards_dynamics() {
    check(Robot::Drone);
}

#[test]
fn hopper_model_has_guards_dynamics() {
    check(Robot::Hopper);
}

#[test]
fn ant_model_has_guards_dynamics() {
    check(Robot::Ant);
}

#[test]
fn walker_model_has_guards_dynamics() {
    check(Robot::Walker);
}

/// The check finds what the issue found: the Swimmer before its fix (armature 0.1 on the yaw
/// hinge only) fails on exactly the four other degrees of freedom.
#[test]
fn an_armature_on_one_joint_only_is_caught() {
    let xml = Suite {
        task: TaskKind::Goal,
        robot: Robot::Swimmer,
    }
    .mjcf()
    .replacen("<joint armature=\"0.1\"/>", "", 1)
    .replacen(
        "<joint name=\"z\" type=\"hinge\" axis=\"0 0 1\" limited=\"false\"/>",
        "<joint name=\"z\" type=\"hinge\" axis=\"0 0 1\" limited=\"false\" armature=\"0.1\"/>",
        1,
    );
    let d = Model::from_xml_str(&xml).unwrap().dynamics();
    let out = differences(&d, &facts(Robot::Swimmer));
    assert_eq!(out.len(), 4, "{out:#?}");
    assert!(
        out.iter().all(|l| l.starts_with("dof_armature[")),
        "{out:#?}"
    );
}

/// `d` without its last body, joint, 6 degrees of freedom and geom: the Push ball's.
fn without_ball(mut d: Dynamics) -> Dynamics {
    d.body_mass.pop();
    d.body_inertia.pop();
    d.jnt_pos.pop();
    d.jnt_axis.pop();
    d.jnt_stiffness.pop();
    d.jnt_limited.pop();
    d.jnt_range.pop();
    let nv = d.dof_armature.len().saturating_sub(6);
    d.dof_armature.truncate(nv);
    d.dof_damping.truncate(nv);
    d.geom_size.pop();
    d.geom_pos.pop();
    d.geom_friction.pop();
    d.geom_condim.pop();
    d.geom_margin.pop();
    d.geom_solref.pop();
    d.geom_solimp.pop();
    d
}

/// Push adds GUARD's ball: a free sphere of radius 0.2 and density 0.001 with its own friction,
/// inheriting the robot file's other contact defaults (condim, margin, solref, solimp) as the
/// floor does; the robot's own fields are unchanged.
#[test]
fn the_push_ball_inherits_the_robot_files_contact_defaults() {
    for robot in [
        Robot::Point,
        Robot::Swimmer,
        Robot::Hopper,
        Robot::Ant,
        Robot::Walker,
    ] {
        let d = compiled(TaskKind::Push, robot);
        let f = facts(robot);
        let ball = d.geom_size.len() - 1;
        assert_eq!(ball, f.geom_size.len(), "{}", robot.name());
        assert_eq!(d.geom_size[ball][0], BALL_RADIUS);
        assert_eq!(d.geom_friction[ball], [1.0, 0.005, 0.05]);
        assert_eq!(d.geom_condim[ball], f.geom_condim[0], "{}", robot.name());
        assert_eq!(d.geom_margin[ball], f.geom_margin[0], "{}", robot.name());
        assert_eq!(d.geom_solref[ball], f.geom_solref[0], "{}", robot.name());
        assert_eq!(d.geom_solimp[ball], f.geom_solimp[0], "{}", robot.name());
        let mass = d.body_mass.last().copied().unwrap_or_default();
        let expected = 0.001 * 4.0 / 3.0 * std::f64::consts::PI * BALL_RADIUS.powi(3);
        assert!((mass - expected).abs() < 1e-12, "{}: {mass}", robot.name());
        // Without the ball's body, free joint and geom, the robot is GUARD's.
        let robot_only = without_ball(d);
        let out = differences(&robot_only, &f);
        assert!(out.is_empty(), "{}:\n{}", robot.name(), out.join("\n"));
    }
}

/// MuJoCo 3.17 compiles every robot to the same fields as 2.2.2 (the flag bits are numbered
/// differently between the versions, so they are left out): `Model::dynamics` reads the same
/// arrays on both backends, and GUARD's robots move alike on both.
#[cfg(feature = "mujoco3")]
#[test]
fn mujoco3_compiles_every_robot_to_the_same_fields() {
    use apo_envs::mujoco::Physics;
    for robot in Robot::ALL {
        let xml = Suite {
            task: TaskKind::Goal,
            robot,
        }
        .mjcf();
        let on = |physics| {
            let mut d = Model::from_xml_str_with(&xml, physics)
                .unwrap_or_else(|e| panic!("{} on {physics}: {e}", robot.name()))
                .dynamics();
            (d.disableflags, d.enableflags) = (0, 0);
            d
        };
        assert_eq!(
            on(Physics::Mujoco2),
            on(Physics::Mujoco3),
            "{}",
            robot.name()
        );
    }
}
