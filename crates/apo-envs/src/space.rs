//! Observation and action spaces.

use serde::{Deserialize, Serialize};

/// A space of observations or actions, as in Gymnasium.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Space {
    /// A box `low[i] <= x[i] <= high[i]` of `low.len()` reals; bounds may be infinite.
    Box {
        /// Lower bounds, one per dimension.
        low: Vec<f32>,
        /// Upper bounds, one per dimension.
        high: Vec<f32>,
    },
    /// The integers `0..n`.
    Discrete {
        /// Number of actions.
        n: usize,
    },
}

impl Space {
    /// A box with the same bounds `[low, high]` in each of `dim` dimensions.
    pub fn uniform_box(dim: usize, low: f32, high: f32) -> Self {
        Space::Box {
            low: vec![low; dim],
            high: vec![high; dim],
        }
    }

    /// The number of reals a value of this space takes in a flat buffer:
    /// the box dimension, or 1 for a discrete space (the index stored as a float).
    pub fn flat_dim(&self) -> usize {
        match self {
            Space::Box { low, .. } => low.len(),
            Space::Discrete { .. } => 1,
        }
    }

    /// Whether `value` (a flat buffer as in [`Space::flat_dim`]) lies in the space.
    pub fn contains(&self, value: &[f32]) -> bool {
        match self {
            Space::Box { low, high } => {
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
