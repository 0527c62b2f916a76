//! Where GUARD puts things: uniform draws on the floor square with keep-out distances.
//!
//! Each object has a keep-out radius `k`; it is drawn uniformly in `[−2 + k, 2 − k]²` and must
//! be at least the sum of both keep-outs away (in xy) from every object already placed. An
//! object gets at most [`DRAWS_PER_OBJECT`] draws; when one fails, the whole layout is drawn
//! again (at most [`LAYOUT_TRIES`] times).

use rand::Rng;

use crate::rng::EnvRng;

/// Half the side of the square objects are placed in.
pub(crate) const EXTENT: f64 = 2.0;
/// Keep-out of the robot.
pub(crate) const ROBOT_KEEPOUT: f64 = 0.4;
/// Keep-out of the goal.
pub(crate) const GOAL_KEEPOUT: f64 = 0.4;
/// Keep-out of the Push task's ball.
pub(crate) const BALL_KEEPOUT: f64 = 0.2;
/// Keep-out of each 3D hazard sphere.
pub(crate) const HAZARD3D_KEEPOUT: f64 = 0.4;
/// Keep-out of each Chase robber.
pub(crate) const ROBBER_KEEPOUT: f64 = 0.5;
/// Draws one object gets before its layout is abandoned.
pub(crate) const DRAWS_PER_OBJECT: usize = 100;
/// Layouts drawn before giving up.
pub(crate) const LAYOUT_TRIES: usize = 10_000;
/// Draws of a goal on its own (at reset and after each success) before giving up.
pub(crate) const GOAL_TRIES: usize = 10_000;

/// An object on the floor: its xy and keep-out radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Placed {
    pub(crate) xy: [f64; 2],
    pub(crate) keepout: f64,
}

impl Placed {
    /// Whether a new object at `xy` with `keepout` keeps its distance from this one.
    pub(crate) fn clear_of(&self, xy: [f64; 2], keepout: f64) -> bool {
        (xy[0] - self.xy[0]).hypot(xy[1] - self.xy[1]) >= self.keepout + keepout
    }
}

/// A uniform point of `[−(EXTENT − keepout), EXTENT − keepout]²`.
pub(crate) fn uniform_xy(rng: &mut EnvRng, keepout: f64) -> [f64; 2] {
    let half = EXTENT - keepout;
    [
        rng.random_range(-half..=half),
        rng.random_range(-half..=half),
    ]
}

/// Draws an object with `keepout` clear of every object of `placed` and accepted by `extra`,
/// in at most `draws` draws; pushes it onto `placed` and returns its xy.
pub(crate) fn draw(
    rng: &mut EnvRng,
    placed: &mut Vec<Placed>,
    keepout: f64,
    draws: usize,
    extra: impl Fn([f64; 2]) -> bool,
) -> Option<[f64; 2]> {
    for _ in 0..draws {
        let xy = uniform_xy(rng, keepout);
        if extra(xy) && placed.iter().all(|p| p.clear_of(xy, keepout)) {
            placed.push(Placed { xy, keepout });
            return Some(xy);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn drawn_objects_keep_their_distances_and_stay_in_their_square() {
        let mut rng = EnvRng::seed_from_u64(3);
        for _ in 0..200 {
            let mut placed = Vec::new();
            let keepouts = [0.4, 0.4, 0.2, 0.5, 0.5];
            let xys: Vec<_> = keepouts
                .iter()
                .map(|&k| draw(&mut rng, &mut placed, k, DRAWS_PER_OBJECT, |_| true))
                .collect();
            if xys.iter().any(Option::is_none) {
                continue;
            }
            for (i, a) in placed.iter().enumerate() {
                assert!(a.xy.iter().all(|c| c.abs() <= EXTENT - a.keepout));
                for b in &placed[i + 1..] {
                    assert!(a.clear_of(b.xy, b.keepout), "{a:?} too close to {b:?}");
                }
            }
        }
    }

    #[test]
    fn an_impossible_object_gives_up() {
        let mut rng = EnvRng::seed_from_u64(0);
        let mut placed = vec![Placed {
            xy: [0.0, 0.0],
            keepout: 10.0,
        }];
        assert_eq!(draw(&mut rng, &mut placed, 0.4, 50, |_| true), None);
        assert_eq!(placed.len(), 1);
    }
}
