//! Observation and action spaces.

use serde::{Deserialize, Serialize};

/// A space of observations or actions, as in Gymnasium.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Space {
    /// A box `low[i] <= x[i] <= high[i]` of `low.len()` reals; bounds may be infinite.
    ///
    /// A value is stored flat, in row-major order of `shape`: the product of `shape` is
    /// `low.len() == high.len()` (a vector of `d` reals has shape `[d]`). Build boxes with
    /// [`Space::uniform_box`] or [`Space::box_with_shape`], which keep these lengths consistent.
    Box {
        /// Lower bounds, one per flat entry.
        low: Vec<f32>,
        /// Upper bounds, one per flat entry.
        high: Vec<f32>,
        /// The dimensions of a value, e.g. `[d]` or `[channels, height, width]`.
        shape: Vec<usize>,
    },
    /// The integers `0..n`.
    Discrete {
        /// Number of actions.
        n: usize,
    },
}

/// [`Space::box_with_shape`] was given bounds whose lengths do not match the shape.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("a box of shape {shape:?} needs {} bounds, got {low} lower and {high} upper bounds", .shape.iter().product::<usize>())]
pub struct ShapeMismatch {
    /// The shape asked for.
    pub shape: Vec<usize>,
    /// The number of lower bounds given.
    pub low: usize,
    /// The number of upper bounds given.
    pub high: usize,
}

impl Space {
    /// A box of shape `[dim]` with the same bounds `[low, high]` in each dimension.
    pub fn uniform_box(dim: usize, low: f32, high: f32) -> Self {
        Space::Box {
            low: vec![low; dim],
            high: vec![high; dim],
            shape: vec![dim],
        }
    }

    /// A box of the given `shape` with per-entry bounds `low` and `high` (flat, row-major).
    ///
    /// ```
    /// use apo_envs::Space;
    /// let image = Space::box_with_shape(vec![0.0; 6], vec![1.0; 6], vec![2, 3]).unwrap();
    /// assert_eq!((image.flat_dim(), image.shape()), (6, &[2, 3][..]));
    /// assert!(Space::box_with_shape(vec![0.0; 5], vec![1.0; 6], vec![2, 3]).is_err());
    /// ```
    ///
    /// # Errors
    /// [`ShapeMismatch`] unless `low` and `high` both have one entry per element of the shape.
    pub fn box_with_shape(
        low: Vec<f32>,
        high: Vec<f32>,
        shape: Vec<usize>,
    ) -> Result<Self, ShapeMismatch> {
        let len = shape.iter().product::<usize>();
        if low.len() != len || high.len() != len {
            return Err(ShapeMismatch {
                shape,
                low: low.len(),
                high: high.len(),
            });
        }
        Ok(Space::Box { low, high, shape })
    }

    /// The number of reals a value of this space takes in a flat buffer:
    /// the number of entries of a box, or 1 for a discrete space (the index stored as a float).
    pub fn flat_dim(&self) -> usize {
        match self {
            Space::Box { low, .. } => low.len(),
            Space::Discrete { .. } => 1,
        }
    }

    /// The dimensions of a value: a box's `shape`, or `[]` (a scalar) for a discrete space.
    pub fn shape(&self) -> &[usize] {
        match self {
            Space::Box { shape, .. } => shape,
            Space::Discrete { .. } => &[],
        }
    }

    /// Whether `value` (a flat buffer as in [`Space::flat_dim`]) lies in the space.
    pub fn contains(&self, value: &[f32]) -> bool {
        match self {
            Space::Box { low, high, .. } => {
                value.len() == low.len()
                    && value
                        .iter()
                        .zip(low.iter().zip(high))
                        .all(|(v, (l, h))| *v >= *l && *v <= *h)
            }
            Space::Discrete { n } => {
                value.len() == 1
                    && value[0] >= 0.0
                    && value[0].fract() == 0.0
                    && (value[0] as usize) < *n
            }
        }
    }
}
