//! Helpers shared by the integration tests.
#![allow(dead_code)] // each test binary uses a different part of this module

use apo_envs::{Action, Env, Space, StepInfo, Transition};

/// A scripted environment: observation `[episode, t, last_action_0]`, terminates after
/// `terminate_after` steps (never if `None`), reward `t` (the step's index from 1), and records
/// every continuous action it receives.
pub struct Counter {
    pub episode: f32,
    pub t: usize,
    pub terminate_after: Option<usize>,
    pub seeds: Vec<Option<u64>>,
    pub actions: Vec<Vec<f32>>,
    observation_space: Space,
    action_space: Space,
}

impl Counter {
    pub fn new(action_space: Space, terminate_after: Option<usize>) -> Self {
        Self {
            episode: -1.0,
            t: 0,
            terminate_after,
            seeds: Vec::new(),
            actions: Vec::new(),
            observation_space: Space::uniform_box(3, -1e6, 1e6),
            action_space,
        }
    }
}

impl Env for Counter {
    fn observation_space(&self) -> &Space {
        &self.observation_space
    }
    fn action_space(&self) -> &Space {
        &self.action_space
    }
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.seeds.push(seed);
        self.episode += 1.0;
        self.t = 0;
        obs.copy_from_slice(&[self.episode, 0.0, 0.0]);
    }
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        self.t += 1;
        let a = match action {
            Action::Continuous(a) => {
                self.actions.push(a.to_vec());
                a[0]
            }
            Action::Discrete(i) => {
                self.actions.push(vec![i as f32]);
                i as f32
            }
        };
        obs.copy_from_slice(&[self.episode, self.t as f32, a]);
        let terminated = self.terminate_after.is_some_and(|k| self.t >= k);
        Transition {
            reward: self.t as f64,
            terminated,
            truncated: false,
            info: StepInfo::default(),
        }
    }
}

/// Asserts `|a - b| <= tol` with a readable message.
pub fn close(a: f64, b: f64, tol: f64, what: &str) {
    assert!(
        (a - b).abs() <= tol,
        "{what}: {a} vs {b} (|diff| = {:e} > {tol:e})",
        (a - b).abs()
    );
}
