//! Rendering an environment's state to an RGB picture ([`crate::Env::render`]).
//!
//! - The classic-control environments draw a 2D picture of their state ([`Canvas`]).
//! - The MuJoCo suites (Gym, GUARD, hands) render with MuJoCo's own renderer on a headless
//!   OpenGL context (EGL or OSMesa, opened at run time; `APO_GL=egl|osmesa` picks one).
//! - Other environments implement [`crate::Env::render`] themselves; those without a
//!   renderer return [`RenderError::Unsupported`].
//!
//! Every renderer writes a [`Frame`] of the size the caller asks for; the caller owns the
//! frame, so a video of many steps reuses one buffer.

use std::fmt;
use std::str::FromStr;

use tiny_skia::{FillRule, Paint, PathBuilder, Pixmap, Stroke, Transform};

/// The largest side of a frame, in pixels.
pub const MAX_SIDE: u32 = 4096;

/// An RGB picture, 8 bits per channel, rows from the top: pixel `(x, y)` is
/// `rgb[3 * (y * width + x)..][..3]`.
#[derive(Clone, PartialEq, Eq)]
pub struct Frame {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

impl fmt::Debug for Frame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Frame")
            .field("width", &self.width)
            .field("height", &self.height)
            .finish_non_exhaustive()
    }
}

impl Frame {
    /// A black frame of `width × height` pixels.
    ///
    /// # Errors
    /// [`RenderError::Size`] when a side is 0 or larger than [`MAX_SIDE`].
    pub fn new(width: u32, height: u32) -> Result<Frame, RenderError> {
        if !(1..=MAX_SIDE).contains(&width) || !(1..=MAX_SIDE).contains(&height) {
            return Err(RenderError::Size { width, height });
        }
        Ok(Frame {
            width,
            height,
            rgb: vec![0; 3 * width as usize * height as usize],
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixels, `[height][width][3]` row-major, rows from the top.
    pub fn rgb(&self) -> &[u8] {
        &self.rgb
    }

    /// The pixels, mutable, in the layout of [`Frame::rgb`].
    pub fn rgb_mut(&mut self) -> &mut [u8] {
        &mut self.rgb
    }

    /// The pixel at `(x, y)` (`x < width`, `y < height`, else `None`).
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = 3 * (y as usize * self.width as usize + x as usize);
        Some([self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]])
    }
}

/// Where the camera looks from.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Camera {
    /// Follows the robot where the scene has one; a fixed view of the whole scene otherwise
    /// (the classic-control pictures).
    #[default]
    Track,
    /// A free camera looking at the whole scene from MuJoCo's default viewpoint.
    Free,
    /// A camera of the model, by name.
    Named(String),
}

impl FromStr for Camera {
    type Err = std::convert::Infallible;

    /// `track`, `free`, or any other text as a camera name.
    fn from_str(text: &str) -> Result<Camera, Self::Err> {
        Ok(match text {
            "track" => Camera::Track,
            "free" => Camera::Free,
            name => Camera::Named(name.to_owned()),
        })
    }
}

impl fmt::Display for Camera {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Camera::Track => f.write_str("track"),
            Camera::Free => f.write_str("free"),
            Camera::Named(name) => f.write_str(name),
        }
    }
}

/// Why a frame could not be rendered.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// The environment has no renderer.
    #[error("this environment has no renderer")]
    Unsupported,
    /// A frame side is 0 or too large.
    #[error(
        "frame size {width}x{height} is out of range: each side must be 1..={MAX_SIDE} pixels"
    )]
    Size {
        /// The width asked for.
        width: u32,
        /// The height asked for.
        height: u32,
    },
    /// The model has no camera of this name.
    #[error("unknown camera `{name}`; this scene has: {}", .available.join(", "))]
    UnknownCamera {
        /// The name asked for.
        name: String,
        /// The cameras the scene has (`track`, `free` and the model's named cameras).
        available: Vec<String>,
    },
    /// `APO_GL` names no OpenGL platform.
    #[error("APO_GL={value}: it must be `egl` or `osmesa` (or unset: EGL, then OSMesa)")]
    UnknownGl {
        /// The variable's value.
        value: String,
    },
    /// No headless OpenGL context could be made.
    #[error(
        "no headless OpenGL for rendering (tried {tried}): {reason}; install Debian's libegl1 \
         libgl1-mesa-dri (EGL) or libosmesa6 (OSMesa)"
    )]
    NoDisplay {
        /// The platforms tried.
        tried: String,
        /// Why each failed.
        reason: String,
    },
    /// The renderer failed.
    #[error("rendering failed: {0}")]
    Failed(String),
}

/// A 2D drawing surface for the classic-control pictures: a world rectangle mapped onto the
/// frame (y up), filled with white, on which shapes are drawn in world units.
pub struct Canvas {
    pixmap: Pixmap,
    /// World → pixel transform.
    transform: Transform,
    /// Pixels per world unit.
    scale: f32,
}

/// An RGB colour.
pub type Rgb = [u8; 3];

impl Canvas {
    /// A white canvas of the frame's size showing the world rectangle `x ∈ [x0, x1]`,
    /// `y ∈ [y0, y1]` (`x1 > x0`, `y1 > y0`), uniformly scaled and centred.
    pub fn new(
        frame: &Frame,
        [x0, x1]: [f32; 2],
        [y0, y1]: [f32; 2],
    ) -> Result<Canvas, RenderError> {
        let mut pixmap = Pixmap::new(frame.width(), frame.height()).ok_or(RenderError::Size {
            width: frame.width(),
            height: frame.height(),
        })?;
        pixmap.fill(tiny_skia::Color::WHITE);
        let (w, h) = (frame.width() as f32, frame.height() as f32);
        let scale = (w / (x1 - x0)).min(h / (y1 - y0));
        let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
        // pixel = (w/2 + scale (x − cx), h/2 − scale (y − cy))
        let transform = Transform::from_row(
            scale,
            0.0,
            0.0,
            -scale,
            w / 2.0 - scale * cx,
            h / 2.0 + scale * cy,
        );
        Ok(Canvas {
            pixmap,
            transform,
            scale,
        })
    }

    fn paint(color: Rgb) -> Paint<'static> {
        let mut paint = Paint::default();
        paint.set_color_rgba8(color[0], color[1], color[2], 255);
        paint.anti_alias = true;
        paint
    }

    /// A line from `a` to `b`, `width` world units thick, with round ends.
    pub fn line(&mut self, a: [f32; 2], b: [f32; 2], width: f32, color: Rgb) {
        let mut path = PathBuilder::new();
        path.move_to(a[0], a[1]);
        path.line_to(b[0], b[1]);
        if let Some(path) = path.finish() {
            let stroke = Stroke {
                width,
                line_cap: tiny_skia::LineCap::Round,
                ..Stroke::default()
            };
            self.pixmap
                .stroke_path(&path, &Self::paint(color), &stroke, self.transform, None);
        }
    }

    /// A polyline through `points`, `width` world units thick.
    pub fn polyline(&mut self, points: &[[f32; 2]], width: f32, color: Rgb) {
        let mut path = PathBuilder::new();
        for (i, p) in points.iter().enumerate() {
            if i == 0 {
                path.move_to(p[0], p[1]);
            } else {
                path.line_to(p[0], p[1]);
            }
        }
        if let Some(path) = path.finish() {
            let stroke = Stroke {
                width,
                line_join: tiny_skia::LineJoin::Round,
                ..Stroke::default()
            };
            self.pixmap
                .stroke_path(&path, &Self::paint(color), &stroke, self.transform, None);
        }
    }

    /// A filled disc of `radius` world units at `centre`.
    pub fn disc(&mut self, centre: [f32; 2], radius: f32, color: Rgb) {
        if let Some(path) = PathBuilder::from_circle(centre[0], centre[1], radius) {
            self.pixmap.fill_path(
                &path,
                &Self::paint(color),
                FillRule::Winding,
                self.transform,
                None,
            );
        }
    }

    /// A filled polygon with corners `points`.
    pub fn polygon(&mut self, points: &[[f32; 2]], color: Rgb) {
        let mut path = PathBuilder::new();
        for (i, p) in points.iter().enumerate() {
            if i == 0 {
                path.move_to(p[0], p[1]);
            } else {
                path.line_to(p[0], p[1]);
            }
        }
        path.close();
        if let Some(path) = path.finish() {
            self.pixmap.fill_path(
                &path,
                &Self::paint(color),
                FillRule::Winding,
                self.transform,
                None,
            );
        }
    }

    /// A world length in pixels.
    pub fn pixels(&self, length: f32) -> f32 {
        length * self.scale
    }

    /// Writes the drawing into `frame` (of the size the canvas was made for).
    pub fn finish(self, frame: &mut Frame) {
        for (out, px) in frame
            .rgb_mut()
            .chunks_exact_mut(3)
            .zip(self.pixmap.pixels())
        {
            // opaque drawing on an opaque background: premultiplied = straight
            let c = px.demultiply();
            out.copy_from_slice(&[c.red(), c.green(), c.blue()]);
        }
    }
}

/// The camera names a scene without named cameras accepts.
pub(crate) fn check_plain_camera(camera: &Camera) -> Result<(), RenderError> {
    match camera {
        Camera::Track | Camera::Free => Ok(()),
        Camera::Named(name) => Err(RenderError::UnknownCamera {
            name: name.clone(),
            available: vec!["track".into(), "free".into()],
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_opengl_says_what_to_install_and_a_wrong_apo_gl_names_itself() {
        let missing = RenderError::NoDisplay {
            tried: "egl, osmesa".into(),
            reason: "no libEGL.so.1".into(),
        }
        .to_string();
        assert!(
            missing.contains("libegl1") && missing.contains("libosmesa6"),
            "{missing}"
        );
        let wrong = RenderError::UnknownGl {
            value: "EGL".into(),
        }
        .to_string();
        assert!(
            wrong.contains("APO_GL=EGL") && !wrong.contains("install"),
            "{wrong}"
        );
    }

    #[test]
    fn frame_sizes_are_checked() {
        assert!(matches!(Frame::new(0, 10), Err(RenderError::Size { .. })));
        assert!(matches!(
            Frame::new(10, MAX_SIDE + 1),
            Err(RenderError::Size { .. })
        ));
        let frame = Frame::new(4, 3).expect("a small frame");
        assert_eq!(frame.rgb().len(), 36);
        assert_eq!(frame.pixel(3, 2), Some([0, 0, 0]));
        assert_eq!(frame.pixel(4, 0), None);
    }

    #[test]
    fn the_canvas_maps_world_units_with_y_up() {
        let mut frame = Frame::new(100, 100).expect("frame");
        let mut canvas = Canvas::new(&frame, [-1.0, 1.0], [-1.0, 1.0]).expect("canvas");
        // a red disc in the upper-left quadrant of the world
        canvas.disc([-0.5, 0.5], 0.2, [255, 0, 0]);
        canvas.finish(&mut frame);
        assert_eq!(
            frame.pixel(25, 25),
            Some([255, 0, 0]),
            "upper left in pixels"
        );
        assert_eq!(
            frame.pixel(75, 75),
            Some([255, 255, 255]),
            "lower right stays white"
        );
    }

    #[test]
    fn camera_names_parse() {
        assert_eq!("track".parse::<Camera>(), Ok(Camera::Track));
        assert_eq!("free".parse::<Camera>(), Ok(Camera::Free));
        assert_eq!("side".parse::<Camera>(), Ok(Camera::Named("side".into())));
        assert!(check_plain_camera(&Camera::Named("side".into())).is_err());
    }
}
