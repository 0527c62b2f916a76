//! The physics backends: `Physics` names and defaults, MuJoCo 3 refused in builds without the
//! `mujoco3` feature, and (with the feature) the same models, ids, contact forces, warnings,
//! body edits and threads on MuJoCo 3.17 as on 2.2.2, with both libraries in one process.
//!
//! Proposed as `crates/apo-envs/tests/mujoco_backends.rs`. Needs Debian's `libmujoco-dev`
//! 2.2.2; with `--features mujoco3` also `libmujoco.so.3.17.0` on the loader path.

use apo_envs::mujoco::tasks::Hopper;
use apo_envs::mujoco::{default_physics, set_default_physics, Model, MujocoError, Physics, Task};

#[test]
fn physics_names_round_trip_and_unknown_names_list_the_choices() {
    for physics in Physics::ALL {
        assert_eq!(physics.to_string().parse::<Physics>().unwrap(), physics);
    }
    assert_eq!(" MuJoCo3 ".parse::<Physics>().unwrap(), Physics::Mujoco3);
    let err = "bullet".parse::<Physics>().unwrap_err();
    assert!(matches!(err, MujocoError::InvalidInput(_)), "{err}");
    let text = err.to_string();
    assert!(
        text.contains("bullet") && text.contains("mujoco2, mujoco3"),
        "{text}"
    );
    assert_eq!(Physics::default(), Physics::Mujoco2);
    assert!(Physics::Mujoco2.is_built());
    assert_eq!(Physics::Mujoco3.is_built(), cfg!(feature = "mujoco3"));
}

#[test]
fn the_default_physics_is_mujoco2_and_can_be_set() {
    // The only test of this binary that touches the process default; the others name their
    // physics, so running in parallel with them is harmless.
    assert_eq!(default_physics(), Physics::Mujoco2);
    set_default_physics(Physics::Mujoco3);
    assert_eq!(default_physics(), Physics::Mujoco3);
    set_default_physics(Physics::Mujoco2);
    assert_eq!(default_physics(), Physics::Mujoco2);
}

#[test]
fn mujoco2_models_say_so() {
    let model = Model::from_xml_str_with(Hopper::MJCF, Physics::Mujoco2).unwrap();
    assert_eq!(model.physics(), Physics::Mujoco2);
}

#[cfg(not(feature = "mujoco3"))]
#[test]
fn mujoco3_without_the_feature_says_how_to_get_it() {
    let err = Model::from_xml_str_with(Hopper::MJCF, Physics::Mujoco3).unwrap_err();
    assert!(
        matches!(
            err,
            MujocoError::Unavailable {
                physics: "mujoco3",
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("--features mujoco3"), "{err}");
    assert_eq!(Physics::Mujoco3.check().unwrap_err(), err);
}

#[cfg(feature = "mujoco3")]
mod mujoco3 {
    use std::sync::Arc;

    use apo_envs::mujoco::tasks::InvertedPendulum;
    use apo_envs::mujoco::{Data, ObjKind, Warning};

    use super::*;

    fn both(xml: &str) -> (Arc<Model>, Arc<Model>) {
        let two = Model::from_xml_str_with(xml, Physics::Mujoco2).expect("MuJoCo 2 compiles it");
        let three = Model::from_xml_str_with(xml, Physics::Mujoco3).expect("MuJoCo 3 compiles it");
        assert_eq!(three.physics(), Physics::Mujoco3);
        (Arc::new(two), Arc::new(three))
    }

    #[test]
    fn the_library_is_3_17() {
        Physics::Mujoco3
            .check()
            .expect("libmujoco.so.3.17.0 is linked");
    }

    #[test]
    fn both_backends_compile_the_same_model() {
        let (two, three) = both(Hopper::MJCF);
        let sizes = |m: &Model| (m.nq(), m.nv(), m.nu(), m.nbody(), m.njnt(), m.nkey());
        assert_eq!(sizes(&two), sizes(&three));
        assert_eq!(two.qpos0(), three.qpos0());
        assert_eq!(two.body_mass(), three.body_mass());
        assert_eq!(two.body_pos(), three.body_pos());
        assert_eq!(two.actuator_ctrlrange(), three.actuator_ctrlrange());
        assert_eq!(two.timestep(), three.timestep());
        for (kind, name) in [
            (ObjKind::Body, "torso"),
            (ObjKind::Body, "foot"),
            (ObjKind::Joint, "rootz"),
            (ObjKind::Actuator, "foot"),
            (ObjKind::Geom, "floor"),
        ] {
            assert_eq!(
                two.id(kind, name).unwrap(),
                three.id(kind, name).unwrap(),
                "{name}"
            );
        }
        assert!(matches!(
            three.id(ObjKind::Body, "wing"),
            Err(MujocoError::UnknownName { kind: "body", .. })
        ));
        assert!(three.id(ObjKind::Body, "to\0rso").is_err());
    }

    #[test]
    fn a_pendulum_falls_the_same_on_both() {
        // No contacts: the engines agree to rounding, the fall onto the joint limit included
        // (measured with the two libraries through ctypes: 1.7e-13 apart after 100 steps).
        let (two, three) = both(InvertedPendulum::MJCF);
        let run = |model: Arc<Model>| {
            let mut data = Data::new(model).unwrap();
            data.qpos_mut()[1] = 0.05;
            for _ in 0..100 {
                data.step();
            }
            data.qpos().to_vec()
        };
        let (a, b) = (run(two), run(three));
        assert!(a[1] > 1.5, "the pole fell onto its limit: {a:?}");
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-9, "{a:?} vs {b:?}");
        }
    }

    #[test]
    fn contact_forces_carry_the_weight_of_a_resting_body() {
        let xml = r#"
        <mujoco>
          <option timestep="0.002"/>
          <worldbody>
            <geom name="floor" type="plane" size="5 5 0.1"/>
            <body name="box" pos="0 0 0.2">
              <freejoint/>
              <geom name="box" type="box" size="0.1 0.1 0.1" mass="1"/>
            </body>
          </worldbody>
        </mujoco>"#;
        let model = Arc::new(Model::from_xml_str_with(xml, Physics::Mujoco3).unwrap());
        let mut data = Data::new(Arc::clone(&model)).unwrap();
        for _ in 0..1500 {
            data.step();
        }
        assert!(data.ncon() >= 4, "ncon = {}", data.ncon());
        let normal: f64 = (0..data.ncon())
            .map(|i| data.contact_force(i).unwrap().force[0])
            .sum();
        assert!((normal - 9.81).abs() < 0.05, "normal forces {normal}");
        let c = data.contact_force(0).unwrap();
        assert_eq!((c.geom1, c.geom2), (0, 1));
        assert!(data.contact_force(data.ncon()).is_none());
        data.rne_post_constraint();
        let box_id = model.id(ObjKind::Body, "box").unwrap();
        let force_z = data.cfrc_ext()[box_id][5];
        assert!((force_z - 9.81).abs() < 0.05, "cfrc_ext z force {force_z}");
    }

    #[test]
    fn warnings_count_and_reset_clears_them() {
        let model =
            Arc::new(Model::from_xml_str_with(InvertedPendulum::MJCF, Physics::Mujoco3).unwrap());
        let mut data = Data::new(Arc::clone(&model)).unwrap();
        data.qvel_mut()[1] = f64::NAN;
        data.step();
        assert!(data.warning_count(Warning::BadQvel) > 0);
        assert_eq!(data.warning_count(Warning::VisualGeomFull), 0);
        assert!(data.unstable_warnings() > 0);
        data.reset();
        assert_eq!(data.unstable_warnings(), 0);
        assert_eq!(data.qpos(), model.qpos0());
        assert_eq!(data.time(), 0.0);
    }

    #[test]
    fn a_private_model_can_move_a_body_through_its_data() {
        // As GUARD places a robot without a free joint (guard/env.rs, `place_robot`).
        let xml = r#"
        <mujoco>
          <worldbody>
            <body name="robot" pos="1 2 0">
              <joint type="slide" axis="1 0 0"/>
              <geom type="sphere" size="0.1"/>
            </body>
          </worldbody>
        </mujoco>"#;
        let model = Model::from_xml_str_with(xml, Physics::Mujoco3).unwrap();
        let robot = model.id(ObjKind::Body, "robot").unwrap();
        let mut data = Data::new(Arc::new(model)).unwrap();
        let moved = data
            .model_mut()
            .expect("the data is the model's only holder")
            .set_body_pose(robot, [3.0, -1.0, 0.5], [1.0, 0.0, 0.0, 0.0]);
        assert!(moved);
        data.forward();
        assert_eq!(data.xpos()[robot], [3.0, -1.0, 0.5]);
        assert_eq!(data.model().body_pos()[robot], [3.0, -1.0, 0.5]);
        let shared = Arc::clone(data.model());
        assert!(data.model_mut().is_none(), "a shared model is read-only");
        drop(shared);
        assert!(!data
            .model_mut()
            .unwrap()
            .set_body_pose(99, [0.0; 3], [1.0, 0.0, 0.0, 0.0]));
    }

    #[test]
    fn a_shared_model_steps_identically_on_several_threads() {
        let model = Arc::new(Model::from_xml_str_with(Hopper::MJCF, Physics::Mujoco3).unwrap());
        let run = |model: Arc<Model>| {
            std::thread::spawn(move || {
                let mut data = Data::new(model).unwrap();
                data.ctrl_mut().copy_from_slice(&[0.5, -0.5, 0.2]);
                for _ in 0..500 {
                    data.step();
                }
                data.qpos().to_vec()
            })
        };
        let (a, b) = (run(Arc::clone(&model)), run(Arc::clone(&model)));
        let (a, b) = (a.join().unwrap(), b.join().unwrap());
        assert_eq!(a, b);
        assert_ne!(a, model.qpos0(), "the hopper moved");
    }

    #[test]
    fn both_libraries_step_side_by_side_in_one_process() {
        // Without RTLD_DEEPBIND on the 2.2.2 library, its internal calls bind to 3.17's
        // symbols and this crashes (see library_patch.md).
        let (two, three) = both(Hopper::MJCF);
        let mut d2 = Data::new(Arc::clone(&two)).unwrap();
        let mut d3 = Data::new(Arc::clone(&three)).unwrap();
        let solo = {
            let mut d = Data::new(Arc::clone(&two)).unwrap();
            for _ in 0..300 {
                d.step();
            }
            d.qpos().to_vec()
        };
        for _ in 0..300 {
            d2.step();
            d3.step();
        }
        assert_eq!(
            d2.qpos(),
            solo.as_slice(),
            "MuJoCo 2 is unaffected by MuJoCo 3"
        );
        for (x, y) in d2.qpos().iter().zip(d3.qpos()) {
            assert!((x - y).abs() < 0.05, "{:?} vs {:?}", d2.qpos(), d3.qpos());
        }
    }

    #[test]
    fn a_missing_file_names_the_path() {
        let err =
            Model::from_xml_file_with("/nonexistent/dir/robot.xml", Physics::Mujoco3).unwrap_err();
        match &err {
            MujocoError::Model { source_name, .. } => {
                assert_eq!(source_name, "/nonexistent/dir/robot.xml");
            }
            other => panic!("expected a model error, got {other:?}"),
        }
        let err = Model::from_xml_file_with("a\0b.xml", Physics::Mujoco3).unwrap_err();
        assert!(matches!(err, MujocoError::InvalidInput(_)), "{err}");
    }
}
