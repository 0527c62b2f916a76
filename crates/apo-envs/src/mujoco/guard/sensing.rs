//! GUARD's engine-computed observations: the compass and the pseudo-lidars, as pure
//! functions of positions and orientations (no simulator), written into caller-owned slices
//! so an observation allocates nothing.
//!
//! Conventions (see `docs/guard.md`):
//! - `R` is a body's world orientation as a row-major 3 × 3 matrix (MuJoCo's `xmat`): a vector
//!   `u` in the body's frame is `R u` in the world's, so a world vector `v` reads `Rᵀ v` in the
//!   body's frame.
//! - Pseudo-lidar bins read `exp(−distance)` of the closest object in their direction and 0 when
//!   empty; with aliasing, an object also lights its two neighbour bins, weighted by where it
//!   falls inside its own bin.

use std::f64::consts::{PI, TAU};

/// Bins of the 2D pseudo-lidar (and azimuth bins of the 3D one).
pub const LIDAR_BINS: usize = 16;
/// Azimuth bins of the 3D pseudo-lidar.
pub const LIDAR3D_AZIMUTH_BINS: usize = 10;
/// Elevation bins of the 3D pseudo-lidar, from straight down to straight up.
pub const LIDAR3D_ELEVATION_BINS: usize = 6;

/// `Rᵀ (p − origin)`: world point `p` in the frame of a body at `origin` with orientation `r`.
pub fn to_body_frame(r: &[f64; 9], origin: &[f64; 3], p: &[f64; 3]) -> [f64; 3] {
    let v = [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]];
    [
        r[0] * v[0] + r[3] * v[1] + r[6] * v[2],
        r[1] * v[0] + r[4] * v[1] + r[7] * v[2],
        r[2] * v[0] + r[5] * v[1] + r[8] * v[2],
    ]
}

/// The compass of a body at `origin` with orientation `r` towards `target`: the target in the
/// body's frame, its first `out.len()` components (2 or 3) kept and divided by their norm plus
/// 0.001. Writes `out` (`[2]` or `[3]`).
pub fn compass(r: &[f64; 9], origin: &[f64; 3], target: &[f64; 3], out: &mut [f32]) {
    let u = to_body_frame(r, origin, target);
    let kept = &u[..out.len().min(3)];
    let norm = kept.iter().map(|x| x * x).sum::<f64>().sqrt();
    for (o, &x) in out.iter_mut().zip(kept) {
        *o = (x / (norm + 0.001)) as f32;
    }
}

/// The bin of angle `angle` (radians, any range) among `bins` bins covering `[0, 2π)`, and
/// the position inside it in `[0, 1)`.
fn azimuth_bin(angle: f64, bins: usize) -> (usize, f64) {
    let width = TAU / bins as f64;
    let angle = angle.rem_euclid(TAU);
    let scaled = angle / width;
    let bin = (scaled.floor() as usize).min(bins - 1);
    (bin, (scaled - bin as f64).clamp(0.0, 1.0))
}

/// Raises `out[i]` to at least `value`.
fn raise(out: &mut [f32], i: usize, value: f64) {
    let value = value as f32;
    if out[i] < value {
        out[i] = value;
    }
}

/// The 2D pseudo-lidar of a body at `origin` with orientation `r` over `objects`: each object
/// `(x, y, ·)` is taken at height 0, moved into the body's frame, and its horizontal direction
/// picks one of `out.len()` bins (bin 0 starts dead ahead, angles grow counter-clockwise);
/// the bin keeps the largest `exp(−‖xy‖)`. With `alias`, the next bin also gets `frac · s`
/// and the previous `(1 − frac) · s`, wrapping around. Writes `out` (`[bins]`), zeroed first.
pub fn lidar_2d<'a>(
    r: &[f64; 9],
    origin: &[f64; 3],
    objects: impl IntoIterator<Item = &'a [f64; 3]>,
    alias: bool,
    out: &mut [f32],
) {
    out.fill(0.0);
    let bins = out.len();
    if bins == 0 {
        return;
    }
    for p in objects {
        let v = to_body_frame(r, origin, &[p[0], p[1], 0.0]);
        let (bin, frac) = azimuth_bin(v[1].atan2(v[0]), bins);
        let s = (-v[0].hypot(v[1])).exp();
        raise(out, bin, s);
        if alias {
            raise(out, (bin + 1) % bins, frac * s);
            raise(out, (bin + bins - 1) % bins, (1.0 - frac) * s);
        }
    }
}

/// The 3D pseudo-lidar of a body at `origin` with orientation `r` over `objects`:
/// [`LIDAR3D_AZIMUTH_BINS`] × [`LIDAR3D_ELEVATION_BINS`] bins, row-major (`[azimuth][elevation]`).
/// In the body's frame an object at `(x, y, z)` has azimuth `atan2(y, x)` and elevation
/// `atan2(z, ‖xy‖) + π/2 ∈ [0, π]` (bin 0 straight down); the bin keeps the largest
/// `exp(−‖(x, y, z)‖)`. With `alias`, the azimuth neighbours (wrapping) and the elevation
/// neighbours (clamped to the end bins) get the weighted reading as in [`lidar_2d`]. An object
/// exactly overhead falls in the top bin. Writes `out` (`[60]`), zeroed first.
pub fn lidar_3d<'a>(
    r: &[f64; 9],
    origin: &[f64; 3],
    objects: impl IntoIterator<Item = &'a [f64; 3]>,
    alias: bool,
    out: &mut [f32],
) {
    const AZ: usize = LIDAR3D_AZIMUTH_BINS;
    const EL: usize = LIDAR3D_ELEVATION_BINS;
    out.fill(0.0);
    if out.len() != AZ * EL {
        return;
    }
    for p in objects {
        let v = to_body_frame(r, origin, p);
        let horizontal = v[0].hypot(v[1]);
        let (az, az_frac) = azimuth_bin(v[1].atan2(v[0]), AZ);
        let elevation = v[2].atan2(horizontal) + PI / 2.0;
        let scaled = elevation / (PI / EL as f64);
        let el = (scaled.floor().max(0.0) as usize).min(EL - 1);
        let el_frac = (scaled - el as f64).clamp(0.0, 1.0);
        let s = (-(horizontal.hypot(v[2]))).exp();
        raise(out, az * EL + el, s);
        if alias {
            raise(out, ((az + 1) % AZ) * EL + el, az_frac * s);
            raise(out, ((az + AZ - 1) % AZ) * EL + el, (1.0 - az_frac) * s);
            raise(out, az * EL + (el + 1).min(EL - 1), el_frac * s);
            raise(out, az * EL + el.saturating_sub(1), (1.0 - el_frac) * s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const IDENTITY: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

    /// The rotation by `yaw` about z.
    fn yaw(angle: f64) -> [f64; 9] {
        let (s, c) = angle.sin_cos();
        [c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0]
    }

    #[test]
    fn dead_ahead_lights_bin_zero_and_aliases_fully_into_the_last_bin() {
        let mut out = [0.0f32; 16];
        lidar_2d(&IDENTITY, &[0.0; 3], [&[1.0, 0.0, 0.3]], true, &mut out);
        let s = (-1.0f64).exp() as f32;
        assert_eq!(out[0], s);
        // frac = 0: the next bin gets 0, the previous (wrapping to 15) gets all of it.
        assert_eq!(out[1], 0.0);
        assert_eq!(out[15], s);
        assert_eq!(out.iter().filter(|&&x| x > 0.0).count(), 2);
    }

    #[test]
    fn behind_lights_bin_eight() {
        let mut out = [0.0f32; 16];
        lidar_2d(&IDENTITY, &[0.0; 3], [&[-2.0, 0.0, 0.0]], false, &mut out);
        assert_eq!(out[8], (-2.0f64).exp() as f32);
        assert_eq!(out.iter().filter(|&&x| x > 0.0).count(), 1);
    }

    #[test]
    fn between_two_bins_splits_by_the_fraction() {
        // Bin width 22.5°: an object at 33.75° is half-way through bin 1.
        let angle = 33.75f64.to_radians();
        let p = [angle.cos(), angle.sin(), 0.0];
        let mut out = [0.0f32; 16];
        lidar_2d(&IDENTITY, &[0.0; 3], [&p], true, &mut out);
        let s = (-1.0f64).exp();
        assert!((f64::from(out[1]) - s).abs() < 1e-7);
        assert!((f64::from(out[2]) - 0.5 * s).abs() < 1e-6);
        assert!((f64::from(out[0]) - 0.5 * s).abs() < 1e-6);
    }

    #[test]
    fn the_robot_frame_turns_the_bins_and_the_closest_object_wins() {
        // Robot at (1, 1) facing +y: a point at (1, 3) is dead ahead, 2 m away; one at (1, 5)
        // in the same bin is farther and does not lower the reading.
        let mut out = [0.0f32; 16];
        let origin = [1.0, 1.0, 0.1];
        lidar_2d(
            &yaw(PI / 2.0),
            &origin,
            [&[1.0, 5.0, 0.0], &[1.0, 3.0, 0.0]],
            false,
            &mut out,
        );
        assert!((f64::from(out[0]) - (-2.0f64).exp()).abs() < 1e-6);
        // An object to the robot's right (world −x from (1,1) facing +y is the robot's left,
        // so world +x is its right: azimuth −90° = 270°, bin 12).
        lidar_2d(&yaw(PI / 2.0), &origin, [&[2.0, 1.0, 0.0]], false, &mut out);
        assert!((f64::from(out[12]) - (-1.0f64).exp()).abs() < 1e-6);
    }

    #[test]
    fn compass_is_the_unit_direction_in_the_body_frame() {
        let mut out = [0.0f32; 2];
        // Facing +y, a target at world +x is at the robot's right: body (0, −1).
        compass(&yaw(PI / 2.0), &[0.0; 3], &[3.0, 0.0, 0.26], &mut out);
        assert!((f64::from(out[0])).abs() < 1e-6);
        assert!((f64::from(out[1]) + 3.0 / 3.001).abs() < 1e-6);
        // 3D compass keeps z.
        let mut out3 = [0.0f32; 3];
        compass(&IDENTITY, &[0.0, 0.0, 1.0], &[0.0, 0.0, 3.0], &mut out3);
        assert!((f64::from(out3[2]) - 2.0 / 2.001).abs() < 1e-6);
    }

    #[test]
    fn lidar_3d_bins_by_azimuth_and_elevation() {
        let mut out = [0.0f32; 60];
        // Level and dead ahead: azimuth bin 0, elevation π/2 → bin 3 (start of it: frac 0).
        lidar_3d(&IDENTITY, &[0.0; 3], [&[1.0, 0.0, 0.0]], false, &mut out);
        let s = (-1.0f64).exp() as f32;
        assert_eq!(out[3], s);
        assert_eq!(out.iter().filter(|&&x| x > 0.0).count(), 1);
        // Straight above: elevation π → clamped into the top bin 5 of azimuth bin 0.
        lidar_3d(&IDENTITY, &[0.0; 3], [&[0.0, 0.0, 2.0]], false, &mut out);
        assert_eq!(out[5], (-2.0f64).exp() as f32);
        assert_eq!(out.iter().filter(|&&x| x > 0.0).count(), 1);
        // Behind and 45° below, with aliasing: azimuth 180° = bin 5 (width 36°) at frac 0;
        // elevation 45° → bin 1 at frac 0.5.
        let p = [-1.0, 0.0, -1.0];
        lidar_3d(&IDENTITY, &[0.0; 3], [&p], true, &mut out);
        let s = (-(2.0f64).sqrt()).exp();
        let at = |az: usize, el: usize| f64::from(out[az * 6 + el]);
        assert!((at(5, 1) - s).abs() < 1e-6);
        assert!(
            (at(4, 1) - s).abs() < 1e-6,
            "previous azimuth bin gets (1 − 0) s"
        );
        assert!(at(6, 1).abs() < 1e-7);
        assert!((at(5, 2) - 0.5 * s).abs() < 1e-6);
        assert!((at(5, 0) - 0.5 * s).abs() < 1e-6);
    }
}
