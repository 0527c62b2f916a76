//! The environment API, with Gymnasium semantics.
//!
//! Observations are written into a caller-owned `&mut [f32]` of length
//! `observation_space().flat_dim()`, so the rollout loop allocates nothing per step.

use crate::render::{Camera, Frame, RenderError};
use crate::space::Space;

/// An action passed to [`Env::step`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Action<'a> {
    /// A point of a [`Space::Box`] action space, `[action_dim]`.
    Continuous(&'a [f32]),
    /// An index of a [`Space::Discrete`] action space.
    Discrete(usize),
}

/// Extra facts about a step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepInfo {
    /// The simulator became unstable (non-finite state, bad accelerations):
    /// the episode was ended with `terminated = true` and must be counted, not trusted.
    pub unstable: bool,
    /// Whether the task's goal is achieved after this step (Gymnasium-Robotics'
    /// `info["is_success"]`), for tasks that define a goal (the hand tasks); `None` for the others.
    pub success: Option<bool>,
}

/// The outcome of [`Env::step`] besides the observation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Transition {
    /// The reward for this step.
    pub reward: f64,
    /// The episode reached a terminal state of the MDP (its value is 0).
    pub terminated: bool,
    /// The episode was cut for a reason outside the MDP (a time limit); bootstrap its value.
    pub truncated: bool,
    /// Extra facts.
    pub info: StepInfo,
}

impl Transition {
    /// `terminated || truncated`.
    pub fn done(&self) -> bool {
        self.terminated || self.truncated
    }
}

/// A reinforcement-learning environment.
///
/// `Send` so that a vector of environments can step on several threads.
pub trait Env: Send {
    /// The space of observations (a box).
    fn observation_space(&self) -> &Space;

    /// The space of actions.
    fn action_space(&self) -> &Space;

    /// Starts a new episode and writes its first observation into `obs`
    /// (`[observation_dim]`). With `Some(seed)` the environment's RNG is reseeded first,
    /// so the same seed gives the same episode; with `None` it continues its RNG stream.
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]);

    /// Applies `action`, advances one step and writes the next observation into `obs`
    /// (`[observation_dim]`). After a step with `done()`, call [`Env::reset`] before stepping again.
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition;

    /// Draws the current state into `frame` (its size is the picture's), seen from `camera`.
    /// Rendering only reads the state: an episode rendered at every step plays exactly as one
    /// that is not. Wrappers pass it through to the environment they wrap.
    ///
    /// # Errors
    /// [`RenderError::Unsupported`] by default; the renderers' own errors (an unknown camera,
    /// no headless OpenGL) otherwise.
    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        let _ = (camera, frame);
        Err(RenderError::Unsupported)
    }
}

impl<E: Env + ?Sized> Env for Box<E> {
    fn observation_space(&self) -> &Space {
        (**self).observation_space()
    }
    fn action_space(&self) -> &Space {
        (**self).action_space()
    }
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        (**self).reset(seed, obs)
    }
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        (**self).step(action, obs)
    }
    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        (**self).render(camera, frame)
    }
}
