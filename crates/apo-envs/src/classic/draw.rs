//! The classic-control pictures ([`crate::Env::render`]): the state drawn in 2D, after
//! Gymnasium's own pictures (same geometry and colours), into a [`Frame`] of any size.

use crate::render::{check_plain_camera, Camera, Canvas, Frame, RenderError, Rgb};

const POLE: Rgb = [202, 152, 101];
const AXLE: Rgb = [129, 132, 203];
const DARK: Rgb = [0, 0, 0];
const LINK: Rgb = [0, 204, 204];
const TRACK: Rgb = [128, 128, 128];

/// The pendulum `[θ, θ̇]` (θ = 0 upright): a rod of length 1 about a pivot.
pub(super) fn pendulum(
    state: [f64; 2],
    camera: &Camera,
    frame: &mut Frame,
) -> Result<(), RenderError> {
    check_plain_camera(camera)?;
    let mut c = Canvas::new(frame, [-2.2, 2.2], [-2.2, 2.2])?;
    let theta = state[0] as f32;
    let tip = [-theta.sin(), theta.cos()];
    c.line([0.0, 0.0], tip, 0.2, [204, 77, 77]);
    c.disc([0.0, 0.0], 0.05, DARK);
    c.finish(frame);
    Ok(())
}

/// The cart-pole `[x, ẋ, θ, θ̇]`: a cart on a track and a pole of length 1 (θ = 0 upright,
/// positive to the right).
pub(super) fn cartpole(
    state: [f64; 4],
    camera: &Camera,
    frame: &mut Frame,
) -> Result<(), RenderError> {
    check_plain_camera(camera)?;
    let mut c = Canvas::new(frame, [-2.4, 2.4], [-1.2, 2.4])?;
    let (x, theta) = (state[0] as f32, state[2] as f32);
    c.line([-2.4, 0.0], [2.4, 0.0], 0.02, DARK);
    let (w, h) = (0.5, 0.3);
    c.polygon(
        &[
            [x - w / 2.0, -h / 2.0],
            [x + w / 2.0, -h / 2.0],
            [x + w / 2.0, h / 2.0],
            [x - w / 2.0, h / 2.0],
        ],
        DARK,
    );
    let base = [x, h / 4.0];
    c.line(
        base,
        [base[0] + theta.sin(), base[1] + theta.cos()],
        0.1,
        POLE,
    );
    c.disc(base, 0.05, AXLE);
    c.finish(frame);
    Ok(())
}

/// The acrobot `[θ1, θ2, θ̇1, θ̇2]` (θ = 0 hanging down): two links of length 1 and the goal
/// line at height 1.
pub(super) fn acrobot(
    state: [f64; 4],
    camera: &Camera,
    frame: &mut Frame,
) -> Result<(), RenderError> {
    check_plain_camera(camera)?;
    let mut c = Canvas::new(frame, [-2.2, 2.2], [-2.2, 2.2])?;
    let (t1, t2) = (state[0] as f32, state[1] as f32);
    let p1 = [t1.sin(), -t1.cos()];
    let p2 = [p1[0] + (t1 + t2).sin(), p1[1] - (t1 + t2).cos()];
    c.line([-2.2, 1.0], [2.2, 1.0], 0.02, DARK);
    c.line([0.0, 0.0], p1, 0.2, LINK);
    c.line(p1, p2, 0.2, LINK);
    c.disc([0.0, 0.0], 0.1, [204, 204, 0]);
    c.disc(p1, 0.1, [204, 204, 0]);
    c.finish(frame);
    Ok(())
}

/// The mountain car `[x, ẋ]` on the curve `y = 0.45 sin(3x) + 0.55`, `x ∈ [min_x, max_x]`,
/// with the flag at `goal_x`.
pub(super) fn mountain_car(
    state: [f64; 2],
    [min_x, max_x]: [f64; 2],
    goal_x: f64,
    camera: &Camera,
    frame: &mut Frame,
) -> Result<(), RenderError> {
    check_plain_camera(camera)?;
    let height = |x: f32| 0.45 * (3.0 * x).sin() + 0.55;
    let (lo, hi) = (min_x as f32, max_x as f32);
    let mut c = Canvas::new(frame, [lo, hi], [-0.1, 1.2])?;
    let curve: Vec<[f32; 2]> = (0..=100)
        .map(|i| lo + (hi - lo) * i as f32 / 100.0)
        .map(|x| [x, height(x)])
        .collect();
    c.polyline(&curve, 0.01, TRACK);
    let goal = goal_x as f32;
    c.line(
        [goal, height(goal)],
        [goal, height(goal) + 0.15],
        0.01,
        DARK,
    );
    c.polygon(
        &[
            [goal, height(goal) + 0.15],
            [goal, height(goal) + 0.11],
            [goal + 0.07, height(goal) + 0.13],
        ],
        [204, 204, 0],
    );
    let x = state[0] as f32;
    let slope = (3.0 * x).cos() * 1.35;
    let angle = slope.atan();
    let (dx, dy) = (angle.cos(), angle.sin());
    let (nx, ny) = (-dy, dx);
    let (w, h) = (0.12, 0.06);
    let base = [x, height(x) + 0.01];
    let corner = |a: f32, b: f32| [base[0] + a * dx + b * nx, base[1] + a * dy + b * ny];
    c.polygon(
        &[
            corner(-w / 2.0, 0.0),
            corner(w / 2.0, 0.0),
            corner(w / 2.0, h),
            corner(-w / 2.0, h),
        ],
        DARK,
    );
    c.disc(corner(-w / 3.0, 0.0), 0.02, TRACK);
    c.disc(corner(w / 3.0, 0.0), 0.02, TRACK);
    c.finish(frame);
    Ok(())
}
