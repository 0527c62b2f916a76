//! Environments for apo, with Gymnasium semantics.

pub mod env;
pub mod space;

pub use env::{Action, Env, StepInfo, Transition};
pub use space::Space;
