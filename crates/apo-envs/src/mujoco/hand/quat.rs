//! Quaternions `(w, x, y, z)` for the manipulate tasks' poses and goals, in the conventions of
//! Gymnasium-Robotics' `rotations` module and of MuJoCo's free-joint `qpos`: the Hamilton
//! product, and `q(θ, n) = (cos θ/2, sin θ/2 · n)` for a turn by `θ` about the unit axis `n`.

/// A quaternion `(w, x, y, z)`; a rotation when of unit norm.
pub(crate) type Quat = [f64; 4];

/// The identity rotation.
pub(crate) const IDENTITY: Quat = [1.0, 0.0, 0.0, 0.0];

/// The Hamilton product `a ⊗ b` (the rotation `b` first, then `a`).
pub(crate) fn mul(a: Quat, b: Quat) -> Quat {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]
}

/// The conjugate `(w, −x, −y, −z)`: the inverse of a unit quaternion.
pub(crate) fn conjugate(q: Quat) -> Quat {
    [q[0], -q[1], -q[2], -q[3]]
}

/// The Euclidean norm of the 4 components.
pub(crate) fn norm(q: Quat) -> f64 {
    q.iter().map(|c| c * c).sum::<f64>().sqrt()
}

/// `q / ‖q‖`; the identity when `q` is zero or not finite (where Gymnasium would divide by 0).
pub(crate) fn normalized(q: Quat) -> Quat {
    let n = norm(q);
    if n > 0.0 && n.is_finite() {
        q.map(|c| c / n)
    } else {
        IDENTITY
    }
}

/// The turn by `angle` radians about `axis` (normalised here): Gymnasium-Robotics'
/// `quat_from_angle_and_axis`. A zero or non-finite axis gives the identity.
pub(crate) fn from_angle_axis(angle: f64, axis: [f64; 3]) -> Quat {
    let n = axis.iter().map(|c| c * c).sum::<f64>().sqrt();
    if n > 0.0 && n.is_finite() {
        let (s, c) = (angle / 2.0).sin_cos();
        normalized([c, s * axis[0] / n, s * axis[1] / n, s * axis[2] / n])
    } else {
        IDENTITY
    }
}

/// The manipulate tasks' rotation distance `2·arccos(clip(w(a ⊗ conj(b)), −1, 1))`.
///
/// As in Gymnasium-Robotics there is no `abs` on `w`, so the value lies in `[0, 2π]`: `q` and
/// `−q` (the same rotation) are `2π` apart. A non-finite input gives NaN.
pub(crate) fn angle_between(a: Quat, b: Quat) -> f64 {
    let w = mul(a, conjugate(b))[0];
    2.0 * w.clamp(-1.0, 1.0).acos()
}

#[cfg(test)]
mod tests {
    use std::f64::consts::{FRAC_1_SQRT_2, FRAC_PI_2, PI, TAU};

    use super::*;

    fn close(a: Quat, b: Quat) -> bool {
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    /// `q⁻¹ = conj(q) / ‖q‖²`.
    fn inverse(q: Quat) -> Quat {
        let n2 = norm(q).powi(2);
        conjugate(q).map(|c| c / n2)
    }

    #[test]
    fn a_quarter_turn_about_z_is_a_right_angle_from_the_identity() {
        let q = from_angle_axis(FRAC_PI_2, [0.0, 0.0, 1.0]);
        assert!(close(q, [FRAC_1_SQRT_2, 0.0, 0.0, FRAC_1_SQRT_2]), "{q:?}");
        assert!((angle_between(IDENTITY, q) - FRAC_PI_2).abs() < 1e-12);
        assert!((angle_between(q, IDENTITY) - FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn the_axis_is_normalised_and_a_half_turn_has_zero_w() {
        let q = from_angle_axis(PI, [0.0, 0.0, 5.0]);
        assert!(close(q, [0.0, 0.0, 0.0, 1.0]), "{q:?}");
        assert!(close(from_angle_axis(1.0, [0.0; 3]), IDENTITY));
    }

    #[test]
    fn a_quaternion_times_its_inverse_is_the_identity() {
        let q = [0.3, -1.2, 0.5, 2.0];
        assert!(close(mul(q, inverse(q)), IDENTITY));
        assert!(close(mul(inverse(q), q), IDENTITY));
        let u = normalized(q);
        assert!((norm(u) - 1.0).abs() < 1e-12);
        assert!(close(mul(u, conjugate(u)), IDENTITY));
    }

    #[test]
    fn products_compose_turns_about_one_axis_and_follow_hamiltons_rules() {
        let quarter = from_angle_axis(FRAC_PI_2, [0.0, 0.0, 1.0]);
        let half = from_angle_axis(PI, [0.0, 0.0, 1.0]);
        assert!(close(mul(quarter, quarter), half));
        // i·j = k, j·i = −k.
        let (i, j, k) = (
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        );
        assert!(close(mul(i, j), k));
        assert!(close(mul(j, i), k.map(|c| -c)));
    }

    #[test]
    fn the_distance_has_no_abs_so_a_sign_flip_is_a_full_turn() {
        let q = from_angle_axis(0.7, [1.0, 2.0, 3.0]);
        assert!(angle_between(q, q).abs() < 1e-6);
        assert!((angle_between(q, q.map(|c| -c)) - TAU).abs() < 1e-6);
        // The distance between two turns about one axis is the difference of their angles.
        let a = from_angle_axis(0.4, [1.0, -1.0, 0.5]);
        let b = from_angle_axis(1.5, [1.0, -1.0, 0.5]);
        assert!((angle_between(a, b) - 1.1).abs() < 1e-9);
    }

    #[test]
    fn zero_and_non_finite_quaternions_normalise_to_the_identity() {
        assert_eq!(normalized([0.0; 4]), IDENTITY);
        assert_eq!(normalized([f64::NAN, 0.0, 0.0, 0.0]), IDENTITY);
        assert!(angle_between([f64::NAN, 0.0, 0.0, 0.0], IDENTITY).is_nan());
    }
}
