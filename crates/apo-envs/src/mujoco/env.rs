//! [`MujocoEnv`]: the machinery every MuJoCo task shares — frame skip, reset noise,
//! the instability check — around a small [`Task`] that defines observation, reward and
//! termination.

use std::sync::{Arc, Mutex};

use rand::Rng;
use rand_distr::StandardNormal;

use super::error::MujocoError;
use super::model::{Data, Model, ObjKind};
use super::physics::{default_physics, Physics};
use super::render::SceneRenderer;
use super::scene::TrackView;
use crate::env::{Action, Env, StepInfo, Transition};
use crate::render::{Camera, Frame, RenderError};
use crate::rng::{entropy_rng, reseed, EnvRng};
use crate::space::Space;

/// How [`MujocoEnv::reset`] perturbs the initial state, as in Gymnasium's `reset_model`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ResetNoise {
    /// `qpos += U(-qpos, qpos)`, `qvel += U(-qvel, qvel)` per coordinate.
    Uniform {
        /// Half-width for positions.
        qpos: f64,
        /// Half-width for velocities.
        qvel: f64,
    },
    /// `qpos += U(-qpos, qpos)`, `qvel += qvel_std · N(0, 1)` per coordinate.
    UniformNormal {
        /// Half-width for positions.
        qpos: f64,
        /// Standard deviation for velocities.
        qvel_std: f64,
    },
}

impl ResetNoise {
    /// Adds the noise to `qpos` and `qvel`.
    pub fn apply(&self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        let (pos, vel_uniform, vel_std) = match *self {
            ResetNoise::Uniform { qpos, qvel } => (qpos, qvel, 0.0),
            ResetNoise::UniformNormal { qpos, qvel_std } => (qpos, 0.0, qvel_std),
        };
        for q in qpos.iter_mut() {
            *q += uniform(rng, pos);
        }
        for v in qvel.iter_mut() {
            *v += if vel_std > 0.0 {
                vel_std * rng.sample::<f64, _>(StandardNormal)
            } else {
                uniform(rng, vel_uniform)
            };
        }
    }
}

/// A sample of `U(-half, half)` (0 when `half` is 0).
pub(crate) fn uniform(rng: &mut EnvRng, half: f64) -> f64 {
    if half > 0.0 {
        rng.random_range(-half..half)
    } else {
        0.0
    }
}

/// What a step's reward and termination are computed from, besides the state after it.
#[derive(Debug, Clone, Copy)]
pub struct StepContext<'a> {
    /// The action applied (the controls, `[nu]`).
    pub action: &'a [f32],
    /// The value [`Task::before_step`] returned before simulating.
    pub before: [f64; 3],
    /// Seconds simulated by the step: `timestep × frame_skip`.
    pub dt: f64,
}

/// The model sizes a task expects; checked when the environment is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sizes {
    /// Generalized coordinates.
    pub nq: usize,
    /// Degrees of freedom.
    pub nv: usize,
    /// Actuators (the action dimension).
    pub nu: usize,
    /// Bodies, the world included.
    pub nbody: usize,
}

/// One MuJoCo task: its model, sizes and the functions that differ between tasks.
pub trait Task: Sized + Send + 'static {
    /// The environment's name (`Hopper`, ...).
    const NAME: &'static str;
    /// The MJCF model (embedded text).
    const MJCF: &'static str;
    /// The model sizes the task is written for.
    const SIZES: Sizes;
    /// Observation length.
    const OBS_DIM: usize;
    /// Simulator steps per environment step.
    const FRAME_SKIP: usize;
    /// The keyframe whose `qpos` is the initial configuration, instead of the model's `qpos0`.
    const INIT_KEY: Option<&'static str> = None;
    /// Whether `cfrc_ext` must be computed after stepping (`mj_rnePostConstraint`, as
    /// Gymnasium does) because the observation or the reward reads it.
    const CONTACT_FORCES: bool = false;
    /// How [`Camera::Track`] frames the task in [`Env::render`].
    const TRACK: TrackView = TrackView::SIDE;

    /// Builds the task for `model`, looking up the named objects it needs.
    fn new(model: &Model) -> Result<Self, MujocoError>;

    /// Perturbs the initial state (`qpos` starts at the initial configuration, `qvel` at 0).
    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]);

    /// A quantity to remember before simulating (a position to difference, for example).
    fn before_step(&self, _data: &Data, _action: &[f32]) -> [f64; 3] {
        [0.0; 3]
    }

    /// The reward of the step and whether the new state is terminal.
    fn reward(&self, data: &Data, ctx: &StepContext<'_>) -> (f64, bool);

    /// Writes the observation of the current state into `obs` (`[OBS_DIM]`).
    fn observe(&self, data: &Data, obs: &mut [f32]);
}

/// A MuJoCo environment: a shared [`Model`], its own [`Data`], a [`Task`] and an RNG.
///
/// A step sets the controls to the action, runs `frame_skip` simulator steps, and then checks
/// stability: when MuJoCo raised a bad-number or buffer-overflow warning during the step, or
/// `qpos`/`qvel`, the reward or the observation are not finite, the step returns `terminated = true`,
/// `info.unstable = true` and reward 0, and non-finite observation entries are written as 0.
/// The episode must then be reset. Time limits are not applied here (see the TimeLimit wrapper).
pub struct MujocoEnv<T: Task> {
    task: T,
    data: Data,
    rng: EnvRng,
    init_qpos: Vec<f64>,
    observation_space: Space,
    action_space: Space,
    dt: f64,
    /// Its OpenGL context and scene, made by the first [`Env::render`].
    renderer: SceneRenderer,
}

impl<T: Task> std::fmt::Debug for MujocoEnv<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MujocoEnv")
            .field("task", &T::NAME)
            .field("data", &self.data)
            .finish()
    }
}

impl<T: Task> MujocoEnv<T> {
    /// Builds the environment with the task's embedded model, compiled once per process and
    /// shared by every environment of the task.
    pub fn make() -> Result<Self, MujocoError> {
        Self::with_model(shared_model(T::NAME, T::MJCF)?)
    }

    /// Builds the environment on `model`, which must have the task's sizes and named objects.
    /// It starts from `qpos0` or from the task's keyframe. The action space is the
    /// actuators' control ranges (unlimited actuators get `[-inf, inf]`); the RNG starts from
    /// OS entropy until the first seeded reset.
    pub fn with_model(model: Arc<Model>) -> Result<Self, MujocoError> {
        let found = [model.nq(), model.nv(), model.nu(), model.nbody()];
        let expected = [T::SIZES.nq, T::SIZES.nv, T::SIZES.nu, T::SIZES.nbody];
        for ((what, found), expected) in ["nq", "nv", "nu", "nbody"]
            .into_iter()
            .zip(found)
            .zip(expected)
        {
            if found != expected {
                return Err(MujocoError::Shape {
                    env: T::NAME,
                    what,
                    found,
                    expected,
                });
            }
        }
        let task = T::new(&model)?;
        let init_qpos = match T::INIT_KEY {
            Some(key) => {
                let id = model.id(ObjKind::Key, key)?;
                model
                    .key_qpos(id)
                    .ok_or(MujocoError::UnknownName {
                        kind: "keyframe",
                        name: key.into(),
                    })?
                    .to_vec()
            }
            None => model.qpos0().to_vec(),
        };
        let (low, high): (Vec<f32>, Vec<f32>) = (0..model.nu())
            .map(|i| match model.actuator_ctrlrange().get(i) {
                Some(&[lo, hi]) if model.actuator_ctrllimited(i) => (lo as f32, hi as f32),
                _ => (f32::NEG_INFINITY, f32::INFINITY),
            })
            .unzip();
        let dt = model.timestep() * T::FRAME_SKIP as f64;
        let data = Data::new(model)?;
        Ok(MujocoEnv {
            task,
            data,
            rng: entropy_rng(),
            init_qpos,
            observation_space: Space::uniform_box(T::OBS_DIM, f32::NEG_INFINITY, f32::INFINITY),
            action_space: Space::Box {
                shape: vec![low.len()],
                low,
                high,
            },
            dt,
            renderer: SceneRenderer::default(),
        })
    }

    /// The task.
    pub fn task(&self) -> &T {
        &self.task
    }

    /// The simulation data (read-only).
    pub fn data(&self) -> &Data {
        &self.data
    }

    /// Seconds of simulated time per environment step.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Sets the state to `qpos`, `qvel` and recomputes derived quantities (`mj_forward`),
    /// like Gymnasium's `set_state`.
    ///
    /// # Panics
    /// If the lengths differ from `nq` and `nv`.
    pub fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) {
        self.data.qpos_mut().copy_from_slice(qpos);
        self.data.qvel_mut().copy_from_slice(qvel);
        self.data.forward();
    }

    /// Writes the observation of the current state (for example after [`MujocoEnv::set_state`]).
    ///
    /// # Panics
    /// If `obs.len()` is not the observation dimension.
    pub fn observe(&self, obs: &mut [f32]) {
        assert_eq!(
            obs.len(),
            T::OBS_DIM,
            "{}: observation buffer has the wrong length",
            T::NAME
        );
        self.task.observe(&self.data, obs);
    }
}

impl<T: Task> Env for MujocoEnv<T> {
    fn observation_space(&self) -> &Space {
        &self.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.action_space
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        reseed(&mut self.rng, seed);
        self.data.reset();
        // mj_resetData left qpos = qpos0 and qvel = 0: start from the initial configuration
        // and perturb in place.
        self.data.qpos_mut().copy_from_slice(&self.init_qpos);
        let (qpos, qvel) = self.data.state_mut();
        self.task.reset_state(&mut self.rng, qpos, qvel);
        self.data.forward();
        self.observe(obs);
    }

    /// # Panics
    /// If the action is not continuous with one value per actuator, or `obs` has the wrong length.
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let Action::Continuous(action) = action else {
            panic!("{}: expects a continuous action", T::NAME);
        };
        assert_eq!(
            action.len(),
            self.data.model().nu(),
            "{}: action has the wrong length",
            T::NAME
        );
        let before = self.task.before_step(&self.data, action);
        for (c, &a) in self.data.ctrl_mut().iter_mut().zip(action) {
            *c = f64::from(a);
        }
        let warnings = self.data.unstable_warnings();
        for _ in 0..T::FRAME_SKIP {
            self.data.step();
        }
        if T::CONTACT_FORCES {
            self.data.rne_post_constraint();
        }
        let outcome = (!self.data.unstable_since(warnings)).then(|| {
            self.task.reward(
                &self.data,
                &StepContext {
                    action,
                    before,
                    dt: self.dt,
                },
            )
        });
        self.observe(obs);
        transition(outcome, obs)
    }

    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        self.renderer
            .render(&mut self.data, camera, T::TRACK, &[], frame)
    }
}

/// The transition of a simulated step whose reward and termination are `outcome`, `None` when
/// the simulator became unstable during the step. An unstable step, or one with a non-finite
/// reward or a non-finite entry in the observation `obs` (already written), ends the episode
/// with `info.unstable`, reward 0, and the non-finite entries of `obs` set to 0.
///
/// The observation is checked as well as the state because a finite `qpos`/`qvel` does not
/// make finite sensors: MuJoCo checks the accelerations inside `mj_step` only, so an
/// `mj_forward` after the step can still compute a non-finite `qacc` and, from it, a
/// non-finite accelerometer (seen on GUARD's Goal_Hopper: the policy then acted on NaN and
/// the update failed, docs/results/guard-campaign.md).
pub(crate) fn transition(outcome: Option<(f64, bool)>, obs: &mut [f32]) -> Transition {
    let (reward, terminated, unstable) = match outcome {
        Some((reward, terminated)) if reward.is_finite() && obs.iter().all(|x| x.is_finite()) => {
            (reward, terminated, false)
        }
        _ => (0.0, true, true),
    };
    if unstable {
        obs.iter_mut()
            .filter(|x| !x.is_finite())
            .for_each(|x| *x = 0.0);
    }
    Transition {
        reward,
        terminated,
        truncated: false,
        info: StepInfo {
            unstable,
            success: None,
        },
    }
}

/// The compiled models of the embedded tasks, by task name and physics: each is compiled once.
static MODELS: Mutex<Vec<(ModelKey, Arc<Model>)>> = Mutex::new(Vec::new());

/// A compiled model's task name and physics.
type ModelKey = (&'static str, Physics);

/// The model of task `name` compiled from `mjcf` with the default physics
/// ([`super::default_physics`]), shared between all its environments.
pub(crate) fn shared_model(
    name: &'static str,
    mjcf: &'static str,
) -> Result<Arc<Model>, MujocoError> {
    let physics = default_physics();
    let mut models = MODELS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some((_, model)) = models.iter().find(|(key, _)| *key == (name, physics)) {
        return Ok(Arc::clone(model));
    }
    let model = Arc::new(Model::from_xml_str_with(mjcf, physics)?);
    models.push(((name, physics), Arc::clone(&model)));
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::transition;

    #[test]
    fn a_stable_step_keeps_its_reward_termination_and_observation() {
        let mut obs = [0.5, -2.0];
        let t = transition(Some((1.25, true)), &mut obs);
        assert_eq!(
            (t.reward, t.terminated, t.info.unstable),
            (1.25, true, false)
        );
        assert_eq!(obs, [0.5, -2.0]);
    }

    #[test]
    fn a_non_finite_observation_ends_the_step_as_unstable() {
        // the simulator raised no warning and the reward is finite, but a sensor is not
        let mut obs = [f32::NAN, 0.5, f32::INFINITY, -1.0];
        let t = transition(Some((0.75, false)), &mut obs);
        assert!(t.terminated && t.info.unstable && !t.truncated, "{t:?}");
        assert_eq!(t.reward, 0.0);
        assert_eq!(obs, [0.0, 0.5, 0.0, -1.0]);
    }

    #[test]
    fn a_non_finite_reward_or_a_flagged_step_is_unstable() {
        for outcome in [
            Some((f64::NAN, false)),
            Some((f64::NEG_INFINITY, false)),
            None,
        ] {
            let mut obs = [1.0, f32::NAN];
            let t = transition(outcome, &mut obs);
            assert!(t.terminated && t.info.unstable, "{outcome:?}: {t:?}");
            assert_eq!(t.reward, 0.0);
            assert_eq!(obs, [1.0, 0.0]);
        }
    }
}
