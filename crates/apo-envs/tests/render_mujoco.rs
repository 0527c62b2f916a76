//! Frame checks of the MuJoCo suites, rendered headless by MuJoCo's own renderer (EGL or
//! OSMesa, Mesa's software rasterizer on machines without a GPU).

use apo_envs::mujoco::guard::{GuardEnv, Robot, Suite, TaskKind};
use apo_envs::mujoco::tasks::Hopper;
use apo_envs::mujoco::MujocoEnv;
use apo_envs::{make, Action, Camera, Env, Frame, RenderError};

/// The number of pixels that differ between two frames of one size.
fn changed(a: &Frame, b: &Frame) -> usize {
    a.rgb()
        .chunks_exact(3)
        .zip(b.rgb().chunks_exact(3))
        .filter(|(p, q)| p != q)
        .count()
}

/// The number of distinct colours of a frame (a blank frame has one).
fn colours(frame: &Frame) -> usize {
    let mut seen: Vec<[u8; 3]> = frame
        .rgb()
        .chunks_exact(3)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    seen.sort_unstable();
    seen.dedup();
    seen.len()
}

#[test]
fn a_hopper_renders_the_same_state_alike_and_another_state_differently() {
    let mut env = MujocoEnv::<Hopper>::make().expect("Hopper");
    let mut frame = Frame::new(200, 150).expect("frame");
    let mut again = frame.clone();
    let qpos = [0.0, 1.25, 0.0, 0.0, 0.0, 0.0];
    env.set_state(&qpos, &[0.0; 6]);
    env.render(&Camera::Track, &mut frame).expect("renders");
    assert!(colours(&frame) > 50, "{} colours", colours(&frame));
    env.render(&Camera::Track, &mut again).expect("renders");
    assert_eq!(changed(&frame, &again), 0, "the same state rendered twice");
    // bend the thigh, leg and foot joints: the robot's pixels move
    env.set_state(&[0.0, 1.25, 0.0, -1.0, -1.0, 0.8], &[0.0; 6]);
    env.render(&Camera::Track, &mut again).expect("renders");
    let moved = changed(&frame, &again);
    assert!(moved > 200, "{moved} pixels changed");
    // the free camera sees the scene from elsewhere
    env.render(&Camera::Free, &mut again).expect("renders");
    assert!(changed(&frame, &again) > 1000);
}

#[test]
fn frames_have_the_size_asked_for_and_a_new_size_rebuilds_the_renderer() {
    let mut env = make("Walker2d-v4").expect("Walker2d");
    let mut obs = vec![0.0; env.observation_space().flat_dim()];
    env.reset(Some(0), &mut obs);
    for (w, h) in [(64, 48), (333, 111), (64, 48)] {
        let mut frame = Frame::new(w, h).expect("frame");
        env.render(&Camera::Track, &mut frame).expect("renders");
        assert_eq!((frame.width(), frame.height()), (w, h));
        assert!(colours(&frame) > 10);
    }
}

#[test]
fn rendering_does_not_change_a_mujoco_episode() {
    let play = |render: bool| {
        let mut env = make("Hopper-v4").expect("Hopper");
        let mut obs = vec![0.0; 11];
        let mut frame = Frame::new(48, 32).expect("frame");
        env.reset(Some(5), &mut obs);
        let mut trace = Vec::new();
        for t in 0..30 {
            if render {
                env.render(&Camera::Track, &mut frame).expect("renders");
            }
            let a = [0.5 * ((t % 3) as f32 - 1.0), 0.3, -0.2];
            let step = env.step(Action::Continuous(&a), &mut obs);
            trace.push((obs.clone(), step.reward, step.done()));
        }
        trace
    };
    assert_eq!(play(true), play(false));
}

#[test]
fn an_unknown_camera_names_the_cameras_there_are() {
    let mut env = make("Hopper-v4").expect("Hopper");
    let mut frame = Frame::new(32, 32).expect("frame");
    let err = env
        .render(&Camera::Named("no-such-camera".into()), &mut frame)
        .expect_err("unknown camera");
    match err {
        RenderError::UnknownCamera { name, available } => {
            assert_eq!(name, "no-such-camera");
            assert!(available.starts_with(&["track".to_string(), "free".to_string()]));
        }
        other => panic!("unexpected {other:?}"),
    }
}

#[test]
fn a_guard_scene_shows_its_goal_in_green() {
    let suite = Suite {
        task: TaskKind::Goal,
        robot: Robot::Point,
    };
    let mut env = GuardEnv::new(suite).expect("Goal_Point");
    let mut obs = vec![0.0; env.observation_space().flat_dim()];
    env.reset(Some(2), &mut obs);
    let mut frame = Frame::new(160, 120).expect("frame");
    env.render(&Camera::Track, &mut frame).expect("renders");
    let green = |f: &Frame| {
        f.rgb()
            .chunks_exact(3)
            .filter(|p| {
                p[1] > 120 && p[1] as u32 > p[0] as u32 + 40 && p[1] as u32 > p[2] as u32 + 40
            })
            .count()
    };
    assert!(green(&frame) > 20, "{} green pixels", green(&frame));
}

#[test]
fn the_hand_renders() {
    let mut env = make("HandReachDense-v3").expect("HandReach");
    let mut obs = vec![0.0; env.observation_space().flat_dim()];
    env.reset(Some(0), &mut obs);
    let mut frame = Frame::new(120, 90).expect("frame");
    env.render(&Camera::Track, &mut frame).expect("renders");
    assert!(colours(&frame) > 50);
}
