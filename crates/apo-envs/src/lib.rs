#![warn(missing_docs)]
//! Environments for apo, with Gymnasium semantics.
//!
//! * [`env`](mod@env) — the [`Env`] trait: spaces, `reset(seed)`, `step(action)` → [`Transition`]
//!   (reward, `terminated` vs `truncated`, cost, instability flags);
//! * [`registry`] — every environment by name ([`make`], [`list`]): the classic-control tasks,
//!   the Gymnasium MuJoCo v4 suite, GUARD and the dexterous hands ([`mujoco`]), your own
//!   with [`register`];
//! * [`wrappers`] — [`RescaleAction`], [`TimeLimit`], [`FixedReset`], [`NormalizeObservation`];
//! * [`vector`] — [`VecEnv`]: several copies stepped together, serially or on threads, with
//!   Gymnasium's autoreset;
//! * [`rng`] — the portable generator every environment owns, and the [`rng::Rng`] trait to
//!   draw from it (no direct `rand` dependency needed).
//!
//! # Bring your own environment
//!
//! An environment writes its observation into the caller's buffer and returns the step's
//! [`Transition`]; its random stream comes from [`rng::EnvRng`], reseeded by
//! [`rng::reseed`] when `reset` is given a seed. [`VecEnv`] steps copies of it with flat
//! buffers (`[num_envs, obs_dim]` observations, `[num_envs, act_dim]` actions, row-major):
//!
//! ```
//! use apo_envs::rng::{reseed, EnvRng, Rng, SeedableRng};
//! use apo_envs::{Action, Env, Space, Transition, VecEnv, VecStep};
//!
//! /// Walk on a line from a random start; the episode ends at |x| ≥ 1.
//! struct Walk {
//!     obs_space: Space,
//!     action_space: Space,
//!     x: f32,
//!     rng: EnvRng,
//! }
//!
//! impl Env for Walk {
//!     fn observation_space(&self) -> &Space {
//!         &self.obs_space
//!     }
//!     fn action_space(&self) -> &Space {
//!         &self.action_space
//!     }
//!     fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
//!         reseed(&mut self.rng, seed);
//!         self.x = self.rng.random_range(-0.5..0.5);
//!         obs[0] = self.x;
//!     }
//!     fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
//!         let push = match action {
//!             Action::Continuous(a) => a[0].clamp(-1.0, 1.0),
//!             Action::Discrete(_) => 0.0,
//!         };
//!         self.x += 0.1 * push;
//!         obs[0] = self.x;
//!         Transition {
//!             reward: f64::from(self.x),
//!             terminated: self.x.abs() >= 1.0,
//!             ..Default::default()
//!         }
//!     }
//! }
//!
//! let walk = || -> Box<dyn Env> {
//!     Box::new(Walk {
//!         obs_space: Space::uniform_box(1, -1.0, 1.0),
//!         action_space: Space::uniform_box(1, -1.0, 1.0),
//!         x: 0.0,
//!         rng: EnvRng::seed_from_u64(0),
//!     })
//! };
//! let mut envs = VecEnv::new(vec![walk(), walk()])?;
//! let mut obs = vec![0.0; envs.num_envs() * envs.obs_dim()];
//! envs.reset(Some(7), &mut obs);
//! let mut steps = vec![VecStep::default(); envs.num_envs()];
//! let mut ended = 0;
//! for _ in 0..15 {
//!     envs.step(&[1.0, 1.0], &mut obs, &mut steps);
//!     ended += steps.iter().filter(|s| s.terminated).count();
//! }
//! // pushed right by 0.1 per step from below 0.5, each copy reached x ≥ 1 at least once
//! assert!(ended >= 2);
//! # Ok::<(), apo_envs::EnvError>(())
//! ```
//!
//! To train on it, hand the [`VecEnv`] to `apo_train::Trainer::from_envs`; to make it
//! available by name (in `apo train --env`), [`register`] it.

pub mod classic;
pub mod env;
pub mod error;
mod family;
pub mod mujoco;
pub mod registry;
pub mod render;
pub mod rng;
pub mod space;
pub mod throughput;
pub mod vector;
pub mod wrappers;

pub use env::{Action, Env, StepInfo, Transition};
pub use error::EnvError;
pub use registry::{list, make, make_with, register, EnvSpec, Family, MakeOptions};
pub use render::{Camera, Frame, RenderError};
pub use space::Space;
pub use vector::{SerialVecEnv, ThreadedVecEnv, VecEnv, VecStep, VectorEnv};
pub use wrappers::{FixedReset, NormalizeObservation, RescaleAction, RunningMeanStd, TimeLimit};
