//! Frame checks of the classic-control pictures, through the registry's wrappers.

use apo_envs::classic::{CartPole, Pendulum};
use apo_envs::{make, Action, Camera, Env, Frame, RenderError};

/// Pixels that are not the white background.
fn ink(frame: &Frame) -> usize {
    frame
        .rgb()
        .chunks_exact(3)
        .filter(|p| p != &[255, 255, 255])
        .count()
}

#[test]
fn every_classic_task_draws_a_picture_of_the_size_asked_for() {
    for name in [
        "CartPole-v1",
        "Acrobot-v1",
        "Pendulum-v1",
        "MountainCarContinuous-v0",
    ] {
        let mut env = make(name).expect("a registered task");
        let mut obs = vec![0.0; env.observation_space().flat_dim()];
        env.reset(Some(3), &mut obs);
        let mut frame = Frame::new(160, 120).expect("frame");
        env.render(&Camera::Track, &mut frame).expect("renders");
        assert_eq!((frame.width(), frame.height()), (160, 120));
        let drawn = ink(&frame);
        assert!(
            drawn > 200 && drawn < 160 * 120 / 2,
            "{name}: {drawn} drawn pixels"
        );
    }
}

#[test]
fn the_same_state_draws_the_same_pixels_and_another_state_moves_them() {
    let mut pendulum = Pendulum::new();
    let mut frame = Frame::new(100, 100).expect("frame");
    let mut again = frame.clone();
    pendulum.set_state([0.0, 0.0]);
    pendulum
        .render(&Camera::Track, &mut frame)
        .expect("renders");
    pendulum
        .render(&Camera::Track, &mut again)
        .expect("renders");
    assert_eq!(frame, again);
    // upright: the rod is above the pivot (rows from the top), not below it
    let red = |f: &Frame, y: u32| f.pixel(50, y).is_some_and(|p| p[0] > 150 && p[1] < 120);
    assert!(red(&frame, 35) && !red(&frame, 65));
    pendulum.set_state([std::f64::consts::PI, 0.0]);
    pendulum
        .render(&Camera::Track, &mut again)
        .expect("renders");
    assert!(red(&again, 65) && !red(&again, 35));
}

#[test]
fn rendering_does_not_change_the_episode() {
    let play = |render: bool| {
        let mut env = CartPole::new();
        let mut obs = vec![0.0; 4];
        let mut frame = Frame::new(64, 48).expect("frame");
        env.reset(Some(11), &mut obs);
        let mut trace = Vec::new();
        for t in 0..40 {
            if render {
                env.render(&Camera::Track, &mut frame).expect("renders");
            }
            let step = env.step(Action::Discrete(t % 2), &mut obs);
            trace.push((obs.clone(), step.reward, step.done()));
        }
        trace
    };
    assert_eq!(play(true), play(false));
}

#[test]
fn an_unknown_camera_is_named_in_the_error() {
    let mut env = make("Pendulum-v1").expect("registered");
    let mut frame = Frame::new(10, 10).expect("frame");
    let err = env
        .render(&Camera::Named("side".into()), &mut frame)
        .expect_err("no camera `side`");
    assert!(matches!(err, RenderError::UnknownCamera { ref name, .. } if name == "side"));
    assert!(err.to_string().contains("`side`"), "{err}");
}
