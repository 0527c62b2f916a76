//! The Shadow Dexterous Hand models of `assets/hand/`: they compile on MuJoCo 2.2.2 with Gymnasium-Robotics'
//! joint and actuator order, the scenes hold the same hand, and the published Reach start pose
//! puts the fingertips where the published initial goal says (docs/hand.md). The joint and
//! actuator tables and the start pose are the task module's (`apo_envs::mujoco::hand`).

use std::sync::Arc;

use apo_envs::mujoco::hand::{ACTUATORS, JOINTS, REACH_INITIAL_QPOS as REACH_QPOS};
use apo_envs::mujoco::{Data, Model, ObjKind};

fn asset(name: &str) -> String {
    format!("{}/assets/hand/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn load(name: &str) -> Arc<Model> {
    Arc::new(Model::from_xml_file(asset(name)).unwrap_or_else(|e| panic!("{name}: {e}")))
}

const TIPS: [&str; 5] = ["fftip", "mftip", "rftip", "lftip", "thtip"];

/// HandReach's documented initial fingertip positions (FF, MF, RF, LF, TH), rounded there to
/// 0.01 (0.005 for RF's z).
const REACH_TIPS: [[f64; 3]; 5] = [
    [0.99, 0.8, 0.15],
    [1.02, 0.8, 0.15],
    [1.04, 0.81, 0.155],
    [1.07, 0.82, 0.16],
    [0.95, 0.84, 0.16],
];

#[test]
fn the_hand_has_gymnasium_roboticss_joints_and_actuators_in_order() {
    for (file, nq, nv) in [
        ("shadow_hand.xml", 24, 24),
        ("reach.xml", 24, 24),
        ("manipulate_block.xml", 38, 36),
        ("manipulate_egg.xml", 38, 36),
    ] {
        let m = load(file);
        assert_eq!((m.nq(), m.nv(), m.nu()), (nq, nv, 20), "{file}");
        for (i, j) in JOINTS.iter().enumerate() {
            assert_eq!(
                m.id(ObjKind::Joint, &format!("robot0:{j}")).ok(),
                Some(i),
                "{file}: {j}"
            );
            assert_eq!(m.joint_qpos_adr(i), Some(i), "{file}: {j} is hinge {i}");
        }
        for (i, a) in ACTUATORS.iter().enumerate() {
            assert_eq!(
                m.id(ObjKind::Actuator, &format!("robot0:A_{a}")).ok(),
                Some(i),
                "{file}: {a}"
            );
        }
        for tip in TIPS {
            m.id(ObjKind::Site, &format!("robot0:S_{tip}"))
                .unwrap_or_else(|e| panic!("{file}: {tip}: {e}"));
        }
        if nq == 38 {
            for joint in ["object:joint", "target:joint"] {
                m.id(ObjKind::Joint, joint)
                    .unwrap_or_else(|e| panic!("{file}: {e}"));
            }
        }
    }
}

#[test]
fn the_scenes_hold_the_same_hand() {
    /// (the settings between `<mujoco …>` and `<worldbody>`, the world body's content, what
    /// follows it)
    fn parts(text: &str) -> (&str, &str, &str) {
        let model = text.find("<mujoco").expect("a <mujoco> element");
        let settings = model + text[model..].find('>').expect("its tag ends") + 1;
        let (head, rest) = text[settings..]
            .split_once("<worldbody>")
            .expect("a worldbody");
        let (world, tail) = rest.split_once("</worldbody>").expect("closed");
        (head, world, tail)
    }
    let hand = std::fs::read_to_string(asset("shadow_hand.xml")).expect("hand");
    let (settings, world, tail) = parts(&hand);
    for scene in ["reach.xml", "manipulate_block.xml", "manipulate_egg.xml"] {
        let text = std::fs::read_to_string(asset(scene)).expect("scene");
        let (s, w, t) = parts(&text);
        assert_eq!(
            s, settings,
            "{scene}: the hand's settings and assets changed"
        );
        assert!(
            w.starts_with(world.trim_end()),
            "{scene}: the hand's body tree changed"
        );
        assert_eq!(
            t, tail,
            "{scene}: the hand's tendons, actuators or contacts changed"
        );
    }
}

#[test]
fn the_reach_start_pose_puts_the_fingertips_at_the_published_goal() {
    let m = load("reach.xml");
    let mut d = Data::new(Arc::clone(&m)).expect("data");
    d.qpos_mut().copy_from_slice(&REACH_QPOS);
    d.forward();
    for (tip, want) in TIPS.iter().zip(REACH_TIPS) {
        let id = m
            .id(ObjKind::Site, &format!("robot0:S_{tip}"))
            .expect("tip");
        let got = d.site_xpos()[id];
        let gap = (0..3).map(|k| (got[k] - want[k]).abs()).fold(0.0, f64::max);
        assert!(
            gap <= 0.0075,
            "{tip}: {got:?} against the published {want:?} (gap {gap:.4})"
        );
    }
}
