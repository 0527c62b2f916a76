//! The MuJoCo layer: library loading, model loading and its errors, named access, contact
//! forces, sensors, threads. Needs Debian's `libmujoco-dev` (MuJoCo 2.2.2).

use std::process::Command;
use std::sync::Arc;

use apo_envs::mujoco::tasks::{Hopper, InvertedPendulum};
use apo_envs::mujoco::{
    check_library, Data, Model, MujocoEnv, MujocoError, ObjKind, Task, Warning,
};

fn asset(name: &str) -> String {
    format!("{}/assets/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn model(xml: &str) -> Arc<Model> {
    Arc::new(Model::from_xml_str(xml).expect("model compiles"))
}

#[test]
fn library_is_mujoco_2_2_2() {
    check_library().expect("libmujoco-dev 2.2.2 is installed");
}

#[test]
fn model_and_data_are_send_and_sync() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<Model>();
    assert_send_sync::<Data>();
    assert_send_sync::<Arc<Model>>();
}

#[test]
fn malformed_mjcf_gives_mujocos_message() {
    let err = Model::from_xml_str("<mujoco><worldbody><bogus/></worldbody></mujoco>").unwrap_err();
    match &err {
        MujocoError::Model {
            source_name,
            message,
        } => {
            assert_eq!(source_name, "<string>");
            assert!(message.contains("unrecognized element"), "{message}");
            assert!(message.contains("bogus"), "{message}");
        }
        other => panic!("expected a model error, got {other:?}"),
    }
    assert!(err.to_string().contains("unrecognized element"));

    let err = Model::from_xml_str("<mujoco><worldbody>").unwrap_err();
    assert!(
        matches!(&err, MujocoError::Model { message, .. } if message.contains("XML_ERROR")),
        "{err}"
    );

    // A compile error (not a parse error): a joint in the world body.
    let err =
        Model::from_xml_str(r#"<mujoco><worldbody><joint type="hinge"/></worldbody></mujoco>"#)
            .unwrap_err();
    assert!(matches!(err, MujocoError::Model { .. }), "{err}");
}

#[test]
fn missing_file_gives_mujocos_message_with_the_path() {
    let err = Model::from_xml_file("/nonexistent/dir/robot.xml").unwrap_err();
    match &err {
        MujocoError::Model {
            source_name,
            message,
        } => {
            assert_eq!(source_name, "/nonexistent/dir/robot.xml");
            assert!(message.contains("FILE_NOT_FOUND"), "{message}");
            assert!(message.contains("/nonexistent/dir/robot.xml"), "{message}");
        }
        other => panic!("expected a model error, got {other:?}"),
    }
}

#[test]
fn nul_bytes_are_rejected_before_mujoco() {
    let err = Model::from_xml_file("a\0b.xml").unwrap_err();
    assert!(matches!(err, MujocoError::InvalidInput(_)), "{err}");
}

#[test]
fn asset_file_and_embedded_text_give_the_same_model() {
    let from_file = Model::from_xml_file(asset("hopper.xml")).expect("hopper.xml loads");
    let from_text = Model::from_xml_str(Hopper::MJCF).expect("embedded hopper loads");
    assert_eq!(
        (
            from_file.nq(),
            from_file.nv(),
            from_file.nu(),
            from_file.nbody()
        ),
        (6, 6, 3, 5)
    );
    assert_eq!(from_file.qpos0(), from_text.qpos0());
    assert_eq!(from_file.body_mass(), from_text.body_mass());
    assert_eq!(from_file.timestep(), 0.002);
}

#[test]
fn named_lookup_of_bodies_joints_sites_actuators() {
    let hopper = Model::from_xml_str(Hopper::MJCF).unwrap();
    assert_eq!(hopper.id(ObjKind::Body, "torso").unwrap(), 1);
    assert_eq!(hopper.id(ObjKind::Body, "foot").unwrap(), 4);
    let rootz = hopper.id(ObjKind::Joint, "rootz").unwrap();
    assert_eq!(hopper.joint_qpos_adr(rootz), Some(1));
    assert_eq!(hopper.joint_dof_adr(rootz), Some(1));
    assert_eq!(
        hopper.qpos0()[1],
        1.25,
        "rootz has ref 1.25: qpos[1] is the torso height"
    );
    assert_eq!(hopper.id(ObjKind::Actuator, "foot").unwrap(), 2);
    assert_eq!(hopper.id(ObjKind::Geom, "floor").unwrap(), 0);
    assert_eq!(hopper.actuator_ctrlrange(), &[[-1.0, 1.0]; 3]);
    let err = hopper.id(ObjKind::Body, "wing").unwrap_err();
    assert_eq!(
        err,
        MujocoError::UnknownName {
            kind: "body",
            name: "wing".into()
        }
    );
    assert!(err.to_string().contains("no body named `wing`"));

    let idp = Model::from_xml_str(apo_envs::mujoco::tasks::InvertedDoublePendulum::MJCF).unwrap();
    assert_eq!(idp.id(ObjKind::Site, "tip").unwrap(), 0);
    assert!(hopper.id(ObjKind::Site, "tip").is_err());
}

#[test]
fn sensors_by_name() {
    let xml = r#"
    <mujoco>
      <worldbody>
        <body>
          <joint name="hinge" type="hinge" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0 0 1" size="0.05"/>
          <site name="end" pos="0 0 1"/>
        </body>
      </worldbody>
      <sensor>
        <jointpos name="angle" joint="hinge"/>
        <framepos name="end_pos" objtype="site" objname="end"/>
      </sensor>
    </mujoco>"#;
    let model = model(xml);
    assert_eq!(model.nsensor(), 2);
    assert_eq!(model.nsensordata(), 4);
    let mut data = Data::new(Arc::clone(&model)).unwrap();
    data.qpos_mut()[0] = 0.5;
    data.forward();
    assert_eq!(data.sensor("angle").unwrap(), &[0.5]);
    let end = data.sensor("end_pos").unwrap();
    // Rotating (0, 0, 1) by 0.5 rad about y gives (sin 0.5, 0, cos 0.5).
    assert!(
        (end[0] - 0.5f64.sin()).abs() < 1e-12
            && end[1].abs() < 1e-12
            && (end[2] - 0.5f64.cos()).abs() < 1e-12
    );
    assert_eq!(data.site_xpos()[0], [end[0], end[1], end[2]]);
    assert!(matches!(
        data.sensor("speed"),
        Err(MujocoError::UnknownName { kind: "sensor", .. })
    ));
}

#[test]
fn contact_forces_carry_the_weight_of_a_resting_body() {
    // A 1 kg box resting on a plane: the normal contact forces add up to m·g.
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
    let model = model(xml);
    let mut data = Data::new(Arc::clone(&model)).unwrap();
    for _ in 0..1500 {
        data.step();
    }
    assert!(
        data.ncon() >= 4,
        "a box on a plane has its corners in contact, ncon = {}",
        data.ncon()
    );
    let normal: f64 = (0..data.ncon())
        .map(|i| data.contact_force(i).unwrap().force[0])
        .sum();
    assert!(
        (normal - 9.81).abs() < 0.05,
        "normal forces {normal} vs m g = 9.81"
    );
    let c = data.contact_force(0).unwrap();
    assert_eq!((c.geom1, c.geom2), (0, 1));
    assert!(c.pos[2].abs() < 0.01, "contact on the floor: {:?}", c.pos);
    assert!(data.contact_force(data.ncon()).is_none());
    // cfrc_ext is computed on request: the floor pushes the box up with m·g.
    data.rne_post_constraint();
    let box_id = model.id(ObjKind::Body, "box").unwrap();
    let force_z = data.cfrc_ext()[box_id][5];
    assert!((force_z - 9.81).abs() < 0.05, "cfrc_ext z force {force_z}");
}

#[test]
fn reset_restores_qpos0_and_clears_warnings() {
    let model = model(InvertedPendulum::MJCF);
    let mut data = Data::new(Arc::clone(&model)).unwrap();
    data.qvel_mut()[1] = f64::NAN;
    data.step();
    assert!(
        data.warning_count(Warning::BadQvel) > 0,
        "MuJoCo flags the NaN velocity"
    );
    assert!(data.unstable_warnings() > 0);
    data.qpos_mut()[0] = 0.3;
    data.ctrl_mut()[0] = 1.0;
    data.reset();
    assert_eq!(data.qpos(), model.qpos0());
    assert_eq!(data.qvel(), &[0.0, 0.0]);
    assert_eq!(data.ctrl(), &[0.0]);
    assert_eq!(data.unstable_warnings(), 0);
    assert_eq!(data.time(), 0.0);
}

#[test]
fn a_shared_model_steps_identically_on_several_threads() {
    let model = model(Hopper::MJCF);
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
fn a_model_with_other_sizes_is_rejected_by_a_task() {
    let err = MujocoEnv::<Hopper>::with_model(model(InvertedPendulum::MJCF)).unwrap_err();
    assert_eq!(
        err,
        MujocoError::Shape {
            env: "Hopper",
            what: "nq",
            found: 2,
            expected: 6
        }
    );
}

/// Runs the `library_child_*` test named `child` of this binary in a child process with
/// `APO_MUJOCO_LIB` set to `lib`, so that the library is loaded afresh there.
fn run_child(child: &str, lib: &str) {
    let exe = std::env::current_exe().expect("test binary path");
    let out = Command::new(exe)
        .args(["--exact", child, "--include-ignored", "--test-threads=1"])
        .env("APO_MUJOCO_LIB", lib)
        .env("APO_MUJOCO_TEST_CHILD", "1")
        .output()
        .expect("child runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("1 passed"),
        "child {child} failed:\n{text}"
    );
}

#[test]
fn a_missing_library_is_a_clear_error() {
    run_child("library_child_missing", "/nonexistent/libmujoco.so.2.2.2");
}

#[test]
fn a_library_without_mujoco_symbols_is_a_clear_error() {
    run_child("library_child_not_mujoco", "libm.so.6");
}

#[test]
#[ignore = "run by a_missing_library_is_a_clear_error in a child process"]
fn library_child_missing() {
    if std::env::var_os("APO_MUJOCO_TEST_CHILD").is_none() {
        return;
    }
    let err = check_library().unwrap_err();
    assert!(matches!(err, MujocoError::Library { .. }), "{err}");
    let text = err.to_string();
    assert!(text.contains("apt-get install libmujoco-dev"), "{text}");
    assert!(text.contains("/nonexistent/libmujoco.so.2.2.2"), "{text}");
    // Loading a model reports the same error instead of crashing.
    assert_eq!(Model::from_xml_str(Hopper::MJCF).unwrap_err(), err);
    assert!(MujocoEnv::<Hopper>::make().is_err());
    let registry_err = apo_envs::make("Hopper")
        .err()
        .expect("no MuJoCo, no Hopper")
        .to_string();
    assert!(registry_err.contains("libmujoco-dev"), "{registry_err}");
    assert!(registry_err.contains("`Hopper-v4`"), "{registry_err}");
    // The suite is still described: its sizes are the tasks' constants.
    let hopper = apo_envs::registry::spec("Hopper").expect("described without MuJoCo");
    assert_eq!(
        (hopper.observation_dim, hopper.action_space.flat_dim()),
        (11, 3)
    );
    let listed = apo_envs::list();
    assert_eq!(listed.iter().filter(|s| s.family == "mujoco").count(), 10);
    assert_eq!(listed.iter().filter(|s| s.family == "classic").count(), 4);
}

#[test]
#[ignore = "run by a_library_without_mujoco_symbols_is_a_clear_error in a child process"]
fn library_child_not_mujoco() {
    if std::env::var_os("APO_MUJOCO_TEST_CHILD").is_none() {
        return;
    }
    let err = check_library().unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("mju_user_error") || text.contains("mj_"),
        "names the missing symbol: {text}"
    );
    assert!(text.contains("libmujoco-dev"), "{text}");
}
