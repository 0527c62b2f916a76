//! What both of MuJoCo's renderers draw ([`super::render`] for MuJoCo 2.2.2,
//! [`super::render3`] for 3.17): the tasks' [`Decor`], the tracking camera's [`TrackView`],
//! the floor grid, the camera choice, and the few MuJoCo constants both pass (the same
//! values in 2.2.2 and 3.17).

use std::ffi::c_int;

use crate::render::{Camera, Frame, RenderError};

/// `mjCAMERA_TRACKING`, `mjCAMERA_FIXED`.
pub(super) const CAMERA_TRACKING: c_int = 1;
pub(super) const CAMERA_FIXED: c_int = 2;
/// `mjCAT_ALL`: static, dynamic and decorative geoms.
pub(super) const CATEGORY_ALL: c_int = 7;
/// `mjFB_WINDOW`: the context's default framebuffer (the EGL pbuffer, the OSMesa buffer).
pub(super) const FRAMEBUFFER_WINDOW: c_int = 0;
/// `mjFONTSCALE_100`.
pub(super) const FONT_SCALE: c_int = 100;
/// Geoms the scene holds: the model's and the decor.
pub(super) const MAX_GEOMS: c_int = 2000;

/// The shape of a [`Decor`] (`mjtGeom`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Shape {
    /// `size[0]` is the radius.
    Sphere = 2,
    /// `size[0]` is the radius, `size[1]` the half-height; the axis is vertical.
    Cylinder = 5,
    /// `size` holds the half-lengths along x, y and z.
    Box = 6,
}

/// A shape drawn into the scene that is not a geom of the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Decor {
    /// The shape.
    pub(crate) shape: Shape,
    /// Its sizes, as MuJoCo's geoms take them.
    pub(crate) size: [f64; 3],
    /// Its centre, world frame.
    pub(crate) pos: [f64; 3],
    /// Its colour, red, green, blue, alpha in `0..=1`.
    pub(crate) rgba: [f32; 4],
}

/// How [`Camera::Track`] frames the scene: a camera at `distance` metres from the centre of
/// mass of body `body`'s subtree, turned by `azimuth` and `elevation` degrees (MuJoCo's
/// tracking camera; azimuth 90 looks along +y, so +x points right), over a grid of lines on
/// the floor one metre apart when `grid` (so that the ground is seen to move).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackView {
    /// The body followed (0, the world, follows the whole model's centre of mass).
    pub body: usize,
    /// Distance from the followed point, in metres.
    pub distance: f64,
    /// Degrees around the vertical axis.
    pub azimuth: f64,
    /// Degrees above (negative: looking down) the horizontal.
    pub elevation: f64,
    /// Draw the floor grid (at height 0).
    pub grid: bool,
}

impl TrackView {
    /// Follows body 1 (a robot's root) from the side (the robot's +x to the right), a little
    /// from above.
    pub const SIDE: TrackView = TrackView {
        body: 1,
        distance: 3.5,
        azimuth: 90.0,
        elevation: -20.0,
        grid: true,
    };

    /// [`TrackView::SIDE`] at `distance` metres.
    pub const fn side(distance: f64) -> TrackView {
        TrackView {
            distance,
            ..TrackView::SIDE
        }
    }
}

/// Lines of the floor grid on each side of the followed point.
const GRID_LINES: i32 = 12;

/// The floor grid's lines around `centre` (x, y), one metre apart, fixed in the world: thin
/// boxes along y at whole x, and along x at whole y.
pub(super) fn grid(centre: [f64; 3]) -> impl Iterator<Item = Decor> {
    let (cx, cy) = (centre[0].round(), centre[1].round());
    let half = f64::from(GRID_LINES);
    let rgba = [0.3, 0.3, 0.3, 0.5];
    (-GRID_LINES..=GRID_LINES).flat_map(move |i| {
        let i = f64::from(i);
        [
            Decor {
                shape: Shape::Box,
                size: [0.01, half, 0.001],
                pos: [cx + i, cy, 0.001],
                rgba,
            },
            Decor {
                shape: Shape::Box,
                size: [half, 0.01, 0.001],
                pos: [cx, cy + i, 0.001],
                rgba,
            },
        ]
    })
}

impl Default for TrackView {
    /// [`TrackView::SIDE`].
    fn default() -> TrackView {
        TrackView::SIDE
    }
}

/// Copies MuJoCo's pixels (RGB, rows from the bottom) into `frame` (rows from the top).
pub(super) fn copy_flipped(pixels: &[u8], frame: &mut Frame) {
    let row = 3 * frame.width() as usize;
    for (to, from) in frame
        .rgb_mut()
        .chunks_exact_mut(row)
        .zip(pixels.chunks_exact(row).rev())
    {
        to.copy_from_slice(from);
    }
}

/// The camera to render from: `None` for [`Camera::Track`], `Some(None)` for the free
/// camera, `Some(Some(id))` for the model's camera `id`, among the model's camera `names`
/// (in id order).
pub(super) fn camera_id(
    camera: &Camera,
    names: impl FnOnce() -> Vec<String>,
) -> Result<Option<Option<c_int>>, RenderError> {
    match camera {
        Camera::Track => Ok(None),
        Camera::Free => Ok(Some(None)),
        Camera::Named(name) => {
            let names = names();
            match names.iter().position(|n| n == name) {
                Some(id) => Ok(Some(Some(id as c_int))),
                None => Err(RenderError::UnknownCamera {
                    name: name.clone(),
                    available: ["track", "free"]
                        .into_iter()
                        .map(String::from)
                        .chain(names)
                        .collect(),
                }),
            }
        }
    }
}
