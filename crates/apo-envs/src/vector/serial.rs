//! The serial vector: every environment stepped in order on the caller's thread.

use super::{final_row, Layout, Parts, Rows, Shard, VecStep, VectorEnv};
use crate::env::Env;
use crate::error::EnvError;
use crate::space::Space;

/// A [`VectorEnv`] that steps its environments in order on the caller's thread.
pub struct SerialVecEnv {
    layout: Layout,
    shard: Shard,
    final_obs: Vec<f32>,
    finished: Vec<bool>,
}

impl std::fmt::Debug for SerialVecEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialVecEnv")
            .field("num_envs", &self.layout.num_envs)
            .field("observation_space", &self.layout.observation_space)
            .field("action_space", &self.layout.action_space)
            .finish_non_exhaustive()
    }
}

impl SerialVecEnv {
    /// A vector of the given environments.
    ///
    /// # Errors
    /// Those of [`VecEnv::new`](super::VecEnv::new).
    pub fn new(envs: Vec<Box<dyn Env>>) -> Result<Self, EnvError> {
        Parts::new(envs).map(Self::from_parts)
    }

    /// The environments, in order.
    pub fn into_envs(self) -> Vec<Box<dyn Env>> {
        self.shard.envs
    }

    pub(super) fn from_parts(parts: Parts) -> Self {
        Self {
            layout: parts.layout,
            shard: Shard {
                envs: parts.envs,
                first: 0,
            },
            final_obs: parts.final_obs,
            finished: parts.finished,
        }
    }

    pub(super) fn into_parts(self) -> Parts {
        Parts {
            layout: self.layout,
            envs: self.shard.envs,
            final_obs: self.final_obs,
            finished: self.finished,
        }
    }
}

impl VectorEnv for SerialVecEnv {
    fn num_envs(&self) -> usize {
        self.layout.num_envs
    }

    fn observation_space(&self) -> &Space {
        &self.layout.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.layout.action_space
    }

    fn obs_dim(&self) -> usize {
        self.layout.obs_dim
    }

    fn act_dim(&self) -> usize {
        self.layout.act_dim
    }

    fn threads(&self) -> usize {
        1
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.layout.check_len("obs", obs.len(), self.layout.obs_dim);
        self.shard.reset(seed, obs, &mut 0);
        self.finished.fill(false);
    }

    fn step(&mut self, actions: &[f32], obs: &mut [f32], out: &mut [VecStep]) {
        let layout = &self.layout;
        layout.check_len("actions", actions.len(), layout.act_dim);
        layout.check_len("obs", obs.len(), layout.obs_dim);
        layout.check_len("out", out.len(), 1);
        let rows = Rows {
            actions,
            obs,
            final_obs: &mut self.final_obs,
            finished: &mut self.finished,
            out,
        };
        self.shard.step(&layout.action_space, rows, &mut 0);
    }

    fn final_obs(&self, i: usize) -> Option<&[f32]> {
        final_row(&self.final_obs, &self.finished, self.layout.obs_dim, i)
    }

    fn final_obs_buffer(&self) -> &[f32] {
        &self.final_obs
    }
}
