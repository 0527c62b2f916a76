//! Environments for apo, with Gymnasium semantics.

pub mod classic;
pub mod env;
pub mod error;
mod family;
pub mod mujoco;
pub mod registry;
pub mod rng;
pub mod space;
pub mod vector;
pub mod wrappers;

pub use env::{Action, Env, StepInfo, Transition};
pub use error::EnvError;
pub use registry::{list, make, make_with, register, EnvSpec, Family, MakeOptions};
pub use space::Space;
pub use vector::{SerialVecEnv, ThreadedVecEnv, VecEnv, VecStep, VectorEnv};
pub use wrappers::{FixedReset, NormalizeObservation, RescaleAction, RunningMeanStd, TimeLimit};
