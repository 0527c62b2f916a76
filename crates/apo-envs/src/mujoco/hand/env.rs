//! [`HandEnv`]: one Shadow-hand task (Reach, Block or Egg) as an [`Env`], stepped, reset and
//! rewarded as Gymnasium-Robotics' `MujocoHandReachEnv` and `MujocoManipulateEnv` are (with
//! `reward_type="dense"`; see `docs/hand.md`).
//!
//! The model of each task is compiled once per process and shared read-only by all its
//! environments. The manipulate tasks' `target` body only shows the goal: it never touches
//! anything and is not observed, so it is kept at the goal (as Gymnasium does before each
//! render) rather than left to fall.

use std::f64::consts::PI;

use rand::Rng;
use rand_distr::StandardNormal;

use super::quat::{self, Quat};
use super::{HandObservation, HandTask};
use crate::env::{Action, Env, Transition};
use crate::mujoco::env::{shared_model, transition};
use crate::mujoco::error::MujocoError;
use crate::mujoco::model::{Data, ObjKind};
use crate::mujoco::render::SceneRenderer;
use crate::mujoco::scene::{Decor, Shape, TrackView};
use crate::render::{Camera, Frame, RenderError};
use crate::rng::{entropy_rng, reseed, EnvRng};
use crate::space::Space;

/// Simulator steps per environment step (`n_substeps`): 20 × 0.002 s, so 25 Hz.
pub const SUBSTEPS: usize = 20;
/// The action dimension: one position servo per actuated joint.
pub const ACTIONS: usize = 20;
/// The hand's hinge joints, the first `ROBOT_JOINTS` entries of `qpos` and `qvel`.
pub const ROBOT_JOINTS: usize = 24;
/// Success needs the goal distance (Reach) or the position distance (Block, Egg) below this
/// (metres).
pub const DISTANCE_THRESHOLD: f64 = 0.01;
/// Success on Block and Egg also needs the rotation distance below this (radians).
pub const ROTATION_THRESHOLD: f64 = 0.1;
/// The weight of the position distance in the manipulate reward `−(10·d_pos + d_rot)`.
pub const POSITION_WEIGHT: f64 = 10.0;

/// The hand's joints in model order (= observation order), without the `robot0:` prefix.
pub const JOINTS: [&str; ROBOT_JOINTS] = [
    "WRJ1", "WRJ0", "FFJ3", "FFJ2", "FFJ1", "FFJ0", "MFJ3", "MFJ2", "MFJ1", "MFJ0", "RFJ3", "RFJ2",
    "RFJ1", "RFJ0", "LFJ4", "LFJ3", "LFJ2", "LFJ1", "LFJ0", "THJ4", "THJ3", "THJ2", "THJ1", "THJ0",
];
/// The joints the actuators drive, in action order (actuator `robot0:A_<joint>`).
pub const ACTUATORS: [&str; ACTIONS] = [
    "WRJ1", "WRJ0", "FFJ3", "FFJ2", "FFJ1", "MFJ3", "MFJ2", "MFJ1", "RFJ3", "RFJ2", "RFJ1", "LFJ4",
    "LFJ3", "LFJ2", "LFJ1", "THJ4", "THJ3", "THJ2", "THJ1", "THJ0",
];
/// The fingertip sites, FF, MF, RF, LF, TH: Reach's achieved goal, in this order.
pub const FINGERTIPS: [&str; 5] = [
    "robot0:S_fftip",
    "robot0:S_mftip",
    "robot0:S_rftip",
    "robot0:S_lftip",
    "robot0:S_thtip",
];
/// The index of the thumb in [`FINGERTIPS`].
const THUMB: usize = 4;

/// HandReach's start pose (`DEFAULT_INITIAL_QPOS`), in [`JOINTS`] order; velocities are 0.
pub const REACH_INITIAL_QPOS: [f64; ROBOT_JOINTS] = [
    -0.16514339750464327,
    -0.31973286565062153,
    0.14340512546557435,
    0.32028208333591573,
    0.7126053607727917,
    0.6705281001412586,
    0.000246444303701037,
    0.3152655251085491,
    0.7659800313729842,
    0.7323156897425923,
    0.00038520700007378114,
    0.36743546201985233,
    0.7119514095008576,
    0.6699446327514138,
    0.0525442258033891,
    -0.13615534724474673,
    0.39872030433433003,
    0.7415570009679252,
    0.704096378652974,
    0.003673823825070126,
    0.5506291436028695,
    -0.014515151997119306,
    -0.0015229223564485414,
    -0.7894883021600622,
];

/// Reach: the thumb and the chosen finger meet near `palm + MEETING_OFFSET` (metres, world).
pub const MEETING_OFFSET: [f64; 3] = [0.0, -0.09, 0.05];
/// Reach: the standard deviation of the meeting point's noise, per coordinate (metres).
pub const MEETING_NOISE: f64 = 0.005;
/// Reach: each of the two meeting fingertips' goals stops this far short of the meeting point,
/// on its side (metres).
pub const MEETING_GAP: f64 = 0.005;
/// Reach: the probability that the goal is the start pose's fingertips instead.
pub const INITIAL_GOAL_PROBABILITY: f64 = 0.1;

/// Block, Egg: the standard deviation of the object's start position noise, per coordinate
/// (metres).
pub const POSITION_NOISE: f64 = 0.005;
/// Block, Egg: the goal position is the settled object's position plus a uniform offset in
/// these `[low, high)` ranges for x, y, z (metres).
pub const TARGET_POSITION_RANGE: [[f64; 2]; 3] = [[-0.04, 0.04], [-0.06, 0.02], [0.0, 0.06]];
/// Block, Egg: actions (of [`SUBSTEPS`] simulator steps each) with zero action that let the
/// object settle at reset.
pub const SETTLE_ACTIONS: usize = 10;
/// Block, Egg: a reset is kept only if the settled object's centre is above this height
/// (metres), i.e. it stayed on the palm.
pub const PALM_HEIGHT: f64 = 0.04;
/// Block, Egg: resets tried before the last one is kept even though the object fell
/// (Gymnasium tries forever; see `docs/hand.md`: it practically never falls).
pub const RESET_TRIES: usize = 100;

/// The longest goal (Reach's 15 fingertip coordinates).
const MAX_GOAL_DIM: usize = 15;

/// [`MujocoError::Shape`] for the first `(what, found, expected)` of `checks` that differ.
fn check_shapes(
    env: &'static str,
    checks: &[(&'static str, usize, usize)],
) -> Result<(), MujocoError> {
    match checks.iter().find(|(_, found, expected)| found != expected) {
        Some(&(what, found, expected)) => Err(MujocoError::Shape {
            env,
            what,
            found,
            expected,
        }),
        None => Ok(()),
    }
}

/// `‖a − b‖₂` over the common length.
fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// The quaternion stored at `v[at..at + 4]` (the identity if `v` is too short).
fn quat_at(v: &[f64], at: usize) -> Quat {
    match v.get(at..at + 4) {
        Some(&[w, x, y, z]) => [w, x, y, z],
        _ => quat::IDENTITY,
    }
}

/// The addresses of the manipulated object and the goal marker.
#[derive(Debug, Clone, Copy)]
struct ObjectIds {
    /// `object:joint`'s first coordinate in `qpos` (position, then quaternion).
    qpos: usize,
    /// `object:joint`'s first degree of freedom in `qvel`.
    qvel: usize,
    /// Site `object:center`.
    center: usize,
    /// `target:joint`'s first coordinate in `qpos`.
    target_qpos: usize,
    /// `target:joint`'s first degree of freedom in `qvel`.
    target_qvel: usize,
}

/// Ids and addresses read every step.
#[derive(Debug, Clone)]
struct Ids {
    /// The fingertip sites, in [`FINGERTIPS`] order.
    tips: [usize; 5],
    /// Relative control: the `qpos` address of each actuator's joint, and for the J1 actuators
    /// of FF, MF, RF and LF the address of the coupled J0, whose position Gymnasium adds.
    centers: [(usize, Option<usize>); ACTIONS],
    /// The object and the goal marker (Block, Egg).
    object: Option<ObjectIds>,
}

/// A Shadow-hand task, stepped as Gymnasium-Robotics steps it (see `docs/hand.md`).
///
/// - Step: the action (`[20]`) is clipped to `[−1, 1]` and mapped to the controls,
///   `ctrl = clip(c + a·(hi − lo)/2, lo, hi)` with `c = (lo + hi)/2` (absolute control, the
///   default) or the current joint position (relative control,
///   [`HandEnv::set_relative_control`]); then 20 simulator steps, then the observation and the
///   dense reward. Like Gymnasium, nothing is recomputed after the last simulator step, so
///   Reach's fingertip positions are those MuJoCo computed at the start of that step.
/// - Reset: Reach starts from [`REACH_INITIAL_QPOS`] at rest and draws a goal. Block and Egg
///   start from the model's reference pose (hand joints at 0), turn the object by a random
///   rotation and shift it by a little noise, let it settle for 10 zero actions, and start
///   again while it fell off the palm; then the goal is drawn around where it settled.
/// - Episodes never end by themselves, except when the simulator becomes unstable (a MuJoCo
///   bad-number or overflow warning, or a non-finite state, reward or observation):
///   `terminated`, `info.unstable`,
///   reward 0. The registry adds the time limit.
pub struct HandEnv {
    task: HandTask,
    observation: HandObservation,
    data: Data,
    rng: EnvRng,
    ids: Ids,
    /// Each actuator's control range `[lo, hi]`.
    ctrl_range: [[f64; 2]; ACTIONS],
    relative_control: bool,
    /// The start configuration (`[nq]`).
    init_qpos: Vec<f64>,
    /// The fingertip positions at the start configuration (Reach's `initial_goal`).
    initial_goal: [f64; MAX_GOAL_DIM],
    /// The palm body's position at the start configuration (Reach's `palm_xpos`).
    palm_xpos: [f64; 3],
    /// The palm body (the camera follows it).
    palm: usize,
    /// The desired goal (`[goal_dim]`).
    goal: Vec<f64>,
    observation_space: Space,
    action_space: Space,
    /// Its OpenGL context and scene, made by the first [`Env::render`].
    renderer: SceneRenderer,
}

impl std::fmt::Debug for HandEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HandEnv")
            .field("task", &self.task)
            .field("observation", &self.observation)
            .field("relative_control", &self.relative_control)
            .field("goal", &self.goal)
            .field("data", &self.data)
            .finish_non_exhaustive()
    }
}

impl HandEnv {
    /// Builds `task` with `observation`: takes the task's shared model (compiled on first use)
    /// and checks that it has the hand's joints and actuators in Gymnasium's order, the
    /// fingertip sites, and for Block and Egg the object and target joints. The RNG starts from
    /// OS entropy until the first seeded reset; the state is the start configuration, with the
    /// start pose's fingertips (Reach) or the object's start pose (Block, Egg) as the goal until
    /// then.
    pub fn new(task: HandTask, observation: HandObservation) -> Result<Self, MujocoError> {
        let model = shared_model(task.name(), task.mjcf())?;
        let env = task.name();
        let nq_nv = if task.manipulates() {
            (ROBOT_JOINTS + 14, ROBOT_JOINTS + 12)
        } else {
            (ROBOT_JOINTS, ROBOT_JOINTS)
        };
        check_shapes(
            env,
            &[
                ("nq", model.nq(), nq_nv.0),
                ("nv", model.nv(), nq_nv.1),
                ("nu", model.nu(), ACTIONS),
            ],
        )?;
        let joint = |name: &str| -> Result<(usize, usize, usize), MujocoError> {
            let id = model.id(ObjKind::Joint, name)?;
            let unknown = || MujocoError::UnknownName {
                kind: "joint",
                name: name.to_owned(),
            };
            let qpos = model.joint_qpos_adr(id).ok_or_else(unknown)?;
            let qvel = model.joint_dof_adr(id).ok_or_else(unknown)?;
            Ok((id, qpos, qvel))
        };
        // The observation reads qpos[..24] and qvel[..24] as the hand's joints in this order.
        for (i, name) in JOINTS.iter().enumerate() {
            let (id, qpos, qvel) = joint(format!("robot0:{name}").as_str())?;
            check_shapes(
                env,
                &[
                    ("the index of a hand joint", id, i),
                    ("the qpos address of a hand joint", qpos, i),
                    ("the qvel address of a hand joint", qvel, i),
                ],
            )?;
        }
        let mut centers = [(0, None); ACTIONS];
        let mut ctrl_range = [[0.0; 2]; ACTIONS];
        for (i, name) in ACTUATORS.iter().enumerate() {
            let actuator = format!("robot0:A_{name}");
            let id = model.id(ObjKind::Actuator, &actuator)?;
            if id != i {
                return Err(MujocoError::Shape {
                    env,
                    what: "the index of an actuator",
                    found: id,
                    expected: i,
                });
            }
            let (_, qpos, _) = joint(format!("robot0:{name}").as_str())?;
            let coupled = match name.strip_suffix("J1") {
                Some(finger @ ("FF" | "MF" | "RF" | "LF")) => {
                    Some(joint(format!("robot0:{finger}J0").as_str())?.1)
                }
                _ => None,
            };
            centers[i] = (qpos, coupled);
            ctrl_range[i] = match model.actuator_ctrlrange().get(i) {
                Some(&[lo, hi])
                    if model.actuator_ctrllimited(i)
                        && lo.is_finite()
                        && hi.is_finite()
                        && lo <= hi =>
                {
                    [lo, hi]
                }
                _ => {
                    return Err(MujocoError::InvalidInput(format!(
                        "{env}: actuator {actuator} has no finite control range"
                    )))
                }
            };
        }
        let mut tips = [0; 5];
        for (tip, name) in tips.iter_mut().zip(FINGERTIPS) {
            *tip = model.id(ObjKind::Site, name)?;
        }
        let object = if task.manipulates() {
            let (_, qpos, qvel) = joint("object:joint")?;
            let (_, target_qpos, target_qvel) = joint("target:joint")?;
            let fits = qpos + 7 <= model.nq()
                && target_qpos + 7 <= model.nq()
                && qvel + 6 <= model.nv()
                && target_qvel + 6 <= model.nv();
            if !fits {
                return Err(MujocoError::InvalidInput(format!(
                    "{env}: the object or target joint is not a free joint"
                )));
            }
            Some(ObjectIds {
                qpos,
                qvel,
                center: model.id(ObjKind::Site, "object:center")?,
                target_qpos,
                target_qvel,
            })
        } else {
            None
        };
        let palm = model.id(ObjKind::Body, "robot0:palm")?;
        let mut init_qpos = model.qpos0().to_vec();
        if task == HandTask::Reach {
            for (q, &v) in init_qpos.iter_mut().zip(&REACH_INITIAL_QPOS) {
                *q = v;
            }
        }
        let obs_dim = task.observation_dim(observation);
        let data = Data::new(model)?;
        let mut hand = HandEnv {
            task,
            observation,
            data,
            rng: entropy_rng(),
            ids: Ids {
                tips,
                centers,
                object,
            },
            ctrl_range,
            relative_control: false,
            init_qpos,
            initial_goal: [0.0; MAX_GOAL_DIM],
            palm_xpos: [0.0; 3],
            palm,
            goal: vec![0.0; task.goal_dim()],
            observation_space: Space::uniform_box(obs_dim, f32::NEG_INFINITY, f32::INFINITY),
            action_space: Space::uniform_box(ACTIONS, -1.0, 1.0),
            renderer: SceneRenderer::default(),
        };
        hand.restore_start();
        hand.data.forward();
        hand.initial_goal = hand.fingertip_coordinates();
        hand.palm_xpos = hand.data.xpos().get(palm).copied().unwrap_or_default();
        let start = hand.achieved();
        for (g, &a) in hand.goal.iter_mut().zip(&start) {
            *g = a;
        }
        hand.place_target();
        hand.data.forward();
        Ok(hand)
    }

    /// The task.
    pub fn task(&self) -> HandTask {
        self.task
    }

    /// What the observation holds.
    pub fn observation_mode(&self) -> HandObservation {
        self.observation
    }

    /// The simulation data (read-only).
    pub fn data(&self) -> &Data {
        &self.data
    }

    /// Whether actions are relative to the current joint positions (Gymnasium's
    /// `relative_control`; `false`, absolute targets, in every registered task).
    pub fn relative_control(&self) -> bool {
        self.relative_control
    }

    /// Switches relative control on or off: with it, an action `a` sets actuator `i`'s control
    /// to `clip(q_i + a·(hi − lo)/2, lo, hi)`, `q_i` the current position of its joint (plus that
    /// of the coupled distal joint J0 for the J1 actuators of FF, MF, RF and LF, as Gymnasium
    /// computes it).
    pub fn set_relative_control(&mut self, relative: bool) {
        self.relative_control = relative;
    }

    /// The desired goal (`[goal_dim]`): 5 fingertip positions FF, MF, RF, LF, TH (Reach), or the
    /// object's position and unit quaternion `(w, x, y, z)` (Block, Egg).
    pub fn goal(&self) -> &[f64] {
        &self.goal
    }

    /// The achieved goal (`[goal_dim]`), as observed: the fingertip sites' positions (Reach), or
    /// `object:joint`'s `qpos` (Block, Egg).
    pub fn achieved_goal(&self) -> Vec<f64> {
        self.achieved()[..self.task.goal_dim()].to_vec()
    }

    /// The fingertip positions of the start configuration (`[15]`): Reach's `initial_goal`.
    pub fn initial_fingertips(&self) -> &[f64] {
        &self.initial_goal
    }

    /// The palm body's position in the start configuration (Reach's `palm_xpos`).
    pub fn palm_position(&self) -> [f64; 3] {
        self.palm_xpos
    }

    /// The distances between the achieved and the desired goal: `(‖achieved − desired‖, 0)` for
    /// Reach; `(d_pos, d_rot)` for Block and Egg, with `d_pos` the Euclidean distance of the
    /// positions and `d_rot = 2·arccos(clip(w(q_a ⊗ conj(q_d)), −1, 1))` in `[0, 2π]`.
    pub fn goal_distances(&self) -> (f64, f64) {
        let achieved = self.achieved();
        if self.task.manipulates() {
            let d_pos = distance(&achieved[..3], self.goal.get(..3).unwrap_or_default());
            let d_rot = quat::angle_between(quat_at(&achieved, 3), quat_at(&self.goal, 3));
            (d_pos, d_rot)
        } else {
            (distance(&achieved[..MAX_GOAL_DIM], &self.goal), 0.0)
        }
    }

    /// The dense reward of the current state: `−d` (Reach), `−(10·d_pos + d_rot)` (Block, Egg);
    /// see [`HandEnv::goal_distances`]. A step returns this value for the state after it.
    pub fn dense_reward(&self) -> f64 {
        let (d, d_rot) = self.goal_distances();
        if self.task.manipulates() {
            -(POSITION_WEIGHT * d + d_rot)
        } else {
            -d
        }
    }

    /// Gymnasium's `info["is_success"]` for the current state (after a step or a reset):
    /// `d < 0.01` (Reach); `d_pos < 0.01` and `d_rot < 0.1` (Block, Egg). [`Env::step`] reports
    /// it as `info.success` (`None` after an unstable step).
    pub fn is_success(&self) -> bool {
        let (d, d_rot) = self.goal_distances();
        d < DISTANCE_THRESHOLD && (!self.task.manipulates() || d_rot < ROTATION_THRESHOLD)
    }

    /// The 5 fingertip positions, FF, MF, RF, LF, TH, as MuJoCo last computed them.
    #[doc(hidden)]
    pub fn fingertips(&self) -> [[f64; 3]; 5] {
        let sites = self.data.site_xpos();
        self.ids
            .tips
            .map(|id| sites.get(id).copied().unwrap_or_default())
    }

    /// Replaces the desired goal (for scripted scenes and tests); the next reward, success and
    /// observation use it. For Block and Egg the quaternion is stored as given (not normalised).
    ///
    /// # Errors
    /// [`MujocoError::Shape`] if `goal` is not `goal_dim` long.
    #[doc(hidden)]
    pub fn set_goal(&mut self, goal: &[f64]) -> Result<(), MujocoError> {
        if goal.len() != self.goal.len() {
            return Err(MujocoError::Shape {
                env: self.task.name(),
                what: "goal length",
                found: goal.len(),
                expected: self.goal.len(),
            });
        }
        self.goal.copy_from_slice(goal);
        self.place_target();
        self.data.forward();
        Ok(())
    }

    /// Sets the state to `qpos` (`[nq]`) and `qvel` (`[nv]`) and recomputes the derived
    /// quantities (`mj_forward`), like Gymnasium's `set_state` (for scripted scenes and tests).
    ///
    /// # Errors
    /// [`MujocoError::Shape`] if the lengths are not `nq` and `nv`.
    #[doc(hidden)]
    pub fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> Result<(), MujocoError> {
        let env = self.task.name();
        let (q, v) = self.data.state_mut();
        check_shapes(
            env,
            &[("qpos", qpos.len(), q.len()), ("qvel", qvel.len(), v.len())],
        )?;
        q.copy_from_slice(qpos);
        v.copy_from_slice(qvel);
        self.data.forward();
        Ok(())
    }

    /// Writes the observation of the current state into `obs` (`[observation_dim]`): robot
    /// `qpos` (24), robot `qvel` (24), the object's `qvel` (6; Block, Egg), the achieved goal,
    /// then the desired goal with [`HandObservation::GoalConditioned`].
    pub fn observe(&self, obs: &mut [f32]) {
        let (qpos, qvel) = (self.data.qpos(), self.data.qvel());
        let object_qvel: &[f64] = match self.ids.object {
            Some(o) => qvel.get(o.qvel..o.qvel + 6).unwrap_or_default(),
            None => &[],
        };
        let achieved = self.achieved();
        let desired: &[f64] = match self.observation {
            HandObservation::Paper => &[],
            HandObservation::GoalConditioned => &self.goal,
        };
        let values = qpos
            .get(..ROBOT_JOINTS)
            .unwrap_or_default()
            .iter()
            .chain(qvel.get(..ROBOT_JOINTS).unwrap_or_default())
            .chain(object_qvel)
            .chain(&achieved[..self.task.goal_dim()])
            .chain(desired);
        for (o, &v) in obs.iter_mut().zip(values) {
            *o = v as f32;
        }
    }

    /// The achieved goal, in the first `goal_dim` entries.
    fn achieved(&self) -> [f64; MAX_GOAL_DIM] {
        match self.ids.object {
            Some(o) => {
                let mut goal = [0.0; MAX_GOAL_DIM];
                if let Some(pose) = self.data.qpos().get(o.qpos..o.qpos + 7) {
                    goal[..7].copy_from_slice(pose);
                }
                goal
            }
            None => self.fingertip_coordinates(),
        }
    }

    /// The fingertip positions, flat (`[15]`).
    fn fingertip_coordinates(&self) -> [f64; MAX_GOAL_DIM] {
        let tips = self.fingertips();
        std::array::from_fn(|k| tips[k / 3][k % 3])
    }

    /// Sets the controls for `action` (Gymnasium's `_set_action`): clipped to `[−1, 1]`, mapped
    /// around each range's centre or the joint's position, clipped to the control range. A NaN
    /// action stays NaN, so that MuJoCo flags it (`BadCtrl`) and the step counts as unstable.
    fn set_action(&mut self, action: &[f32]) {
        let qpos = self.data.qpos();
        let at = |adr: usize| qpos.get(adr).copied().unwrap_or_default();
        let mut ctrl = [0.0; ACTIONS];
        for (((c, &a), &[lo, hi]), &(joint, coupled)) in ctrl
            .iter_mut()
            .zip(action)
            .zip(&self.ctrl_range)
            .zip(&self.ids.centers)
        {
            let center = if self.relative_control {
                at(joint) + coupled.map_or(0.0, at)
            } else {
                (lo + hi) / 2.0
            };
            let a = f64::from(a).clamp(-1.0, 1.0);
            // `lo <= hi` was checked when the environment was built.
            *c = (center + a * (hi - lo) / 2.0).clamp(lo, hi);
        }
        for (c, &v) in self.data.ctrl_mut().iter_mut().zip(&ctrl) {
            *c = v;
        }
    }

    /// Resets the simulation to the start configuration at rest (`mj_resetData`, then the start
    /// `qpos`), without `mj_forward`.
    fn restore_start(&mut self) {
        self.data.reset();
        for (q, &v) in self.data.qpos_mut().iter_mut().zip(&self.init_qpos) {
            *q = v;
        }
    }

    /// Writes the goal pose into the target marker at rest (Block, Egg): what Gymnasium's
    /// render callback does. The marker touches nothing and is not observed.
    fn place_target(&mut self) {
        let Some(o) = self.ids.object else {
            return;
        };
        let (qpos, qvel) = self.data.state_mut();
        if let (Some(slot), Some(pose)) = (
            qpos.get_mut(o.target_qpos..o.target_qpos + 7),
            self.goal.get(..7),
        ) {
            slot.copy_from_slice(pose);
        }
        if let Some(slot) = qvel.get_mut(o.target_qvel..o.target_qvel + 6) {
            slot.fill(0.0);
        }
    }

    /// Reach's `_sample_goal`: the thumb and a uniformly chosen finger (FF, MF, RF or LF) meet
    /// at `palm + (0, −0.09, 0.05) + N(0, 0.005²)`, each stopping 0.005 short of the meeting
    /// point on its side; the other fingertips keep their start positions. With probability 0.1
    /// the goal is the start positions instead.
    fn sample_reach_goal(&mut self) {
        let rng = &mut self.rng;
        let finger = rng.random_range(0..THUMB);
        let meeting: [f64; 3] = std::array::from_fn(|k| {
            self.palm_xpos[k]
                + MEETING_OFFSET[k]
                + MEETING_NOISE * rng.sample::<f64, _>(StandardNormal)
        });
        let mut goal = self.initial_goal;
        for tip in [THUMB, finger] {
            let Some(p) = goal.get_mut(3 * tip..3 * tip + 3) else {
                continue;
            };
            let d: [f64; 3] = std::array::from_fn(|k| meeting[k] - p[k]);
            let n = distance(&d, &[0.0; 3]);
            if n > 0.0 {
                for ((x, m), d) in p.iter_mut().zip(meeting).zip(d) {
                    *x = m - MEETING_GAP * d / n;
                }
            }
        }
        if rng.random::<f64>() < INITIAL_GOAL_PROBABILITY {
            goal = self.initial_goal;
        }
        for (g, &v) in self.goal.iter_mut().zip(&goal) {
            *g = v;
        }
    }

    /// One try of the manipulate tasks' `_reset_sim`: the start configuration, the object turned
    /// by a random rotation (angle `U(−π, π)`, axis `U(−1, 1)³` normalised, composed after the
    /// start orientation) and shifted by `N(0, 0.005²)` per coordinate, then 10 zero actions.
    /// Returns whether the object's centre is above [`PALM_HEIGHT`] and the simulation stayed
    /// stable.
    fn try_manipulate_reset(&mut self, object: ObjectIds) -> bool {
        self.restore_start();
        let rng = &mut self.rng;
        let start = self
            .data
            .qpos()
            .get(object.qpos..object.qpos + 7)
            .map(|p| ([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]]));
        let Some((position, orientation)) = start else {
            return false;
        };
        let angle = rng.random_range(-PI..PI);
        let axis: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let orientation =
            quat::normalized(quat::mul(orientation, quat::from_angle_axis(angle, axis)));
        let position: [f64; 3] = std::array::from_fn(|k| {
            position[k] + POSITION_NOISE * rng.sample::<f64, _>(StandardNormal)
        });
        if let Some(slot) = self.data.qpos_mut().get_mut(object.qpos..object.qpos + 7) {
            slot[..3].copy_from_slice(&position);
            slot[3..].copy_from_slice(&orientation);
        }
        let warnings = self.data.unstable_warnings();
        for _ in 0..SETTLE_ACTIONS {
            self.set_action(&[0.0; ACTIONS]);
            for _ in 0..SUBSTEPS {
                self.data.step();
            }
        }
        if self.data.unstable_since(warnings) {
            return false;
        }
        self.data.forward();
        self.data
            .site_xpos()
            .get(object.center)
            .is_some_and(|c| c[2] > PALM_HEIGHT)
    }

    /// The manipulate tasks' `_sample_goal` (`target_position="random"`,
    /// `target_rotation="xyz"`): the object's position plus a uniform offset in
    /// [`TARGET_POSITION_RANGE`], and a rotation of angle `U(−π, π)` about an axis `U(−1, 1)³`
    /// normalised (not composed with the object's orientation).
    fn sample_manipulate_goal(&mut self, object: ObjectIds) {
        let rng = &mut self.rng;
        let position = self
            .data
            .qpos()
            .get(object.qpos..object.qpos + 3)
            .map_or([0.0; 3], |p| [p[0], p[1], p[2]]);
        let target: [f64; 3] = std::array::from_fn(|k| {
            let [lo, hi] = TARGET_POSITION_RANGE[k];
            position[k] + rng.random_range(lo..hi)
        });
        let angle = rng.random_range(-PI..PI);
        let axis: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let orientation = quat::normalized(quat::from_angle_axis(angle, axis));
        for (g, &v) in self.goal.iter_mut().zip(target.iter().chain(&orientation)) {
            *g = v;
        }
    }
}

impl Env for HandEnv {
    fn observation_space(&self) -> &Space {
        &self.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.action_space
    }

    /// Reach: the start pose at rest, then a new goal. Block and Egg: tries the object's random
    /// start until it settles on the palm (at most [`RESET_TRIES`] times; the last try is kept
    /// otherwise), then a new goal. `Some(seed)` reseeds the RNG first.
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        reseed(&mut self.rng, seed);
        match self.ids.object {
            None => {
                self.restore_start();
                self.data.forward();
                self.sample_reach_goal();
            }
            Some(object) => {
                for _ in 0..RESET_TRIES {
                    if self.try_manipulate_reset(object) {
                        break;
                    }
                }
                self.sample_manipulate_goal(object);
                self.place_target();
                self.data.forward();
            }
        }
        self.observe(obs);
    }

    /// # Panics
    /// If the action is not continuous with [`ACTIONS`] values, or `obs` has the wrong length.
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let name = self.task.name();
        let Action::Continuous(action) = action else {
            panic!("{name}: expects a continuous action");
        };
        assert_eq!(action.len(), ACTIONS, "{name}: action has the wrong length");
        assert_eq!(
            obs.len(),
            self.observation_space.flat_dim(),
            "{name}: observation buffer has the wrong length"
        );
        self.set_action(action);
        let warnings = self.data.unstable_warnings();
        for _ in 0..SUBSTEPS {
            self.data.step();
        }
        // The marker fell freely during the step; put it back (it is not observed).
        self.place_target();
        let outcome = (!self.data.unstable_since(warnings)).then(|| (self.dense_reward(), false));
        self.observe(obs);
        let mut step = transition(outcome, obs);
        if !step.info.unstable {
            step.info.success = Some(self.is_success());
        }
        step
    }

    /// The hand; Reach's goal fingertip positions as small spheres (the manipulate tasks show
    /// their goal pose with the model's `target` body).
    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        let decor: Vec<Decor> = if self.task.manipulates() {
            Vec::new()
        } else {
            self.goal
                .chunks_exact(3)
                .map(|p| Decor {
                    shape: Shape::Sphere,
                    size: [0.008, 0.0, 0.0],
                    pos: [p[0], p[1], p[2]],
                    rgba: [0.95, 0.2, 0.2, 0.8],
                })
                .collect()
        };
        let track = TrackView {
            body: self.palm,
            distance: 0.5,
            azimuth: 55.0,
            elevation: -25.0,
            grid: false,
        };
        self.renderer
            .render(&mut self.data, camera, track, &decor, frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_and_quaternion_slices_are_safe_on_short_input() {
        assert_eq!(distance(&[3.0, 4.0], &[0.0, 0.0]), 5.0);
        assert_eq!(distance(&[1.0, 2.0, 3.0], &[1.0]), 0.0);
        assert_eq!(quat_at(&[0.0; 5], 3), quat::IDENTITY);
        assert_eq!(quat_at(&[9.0, 0.5, 0.5, 0.5, 0.5], 1), [0.5; 4]);
    }

    #[test]
    fn the_tables_agree_with_each_other() {
        // Every actuated joint is a hand joint, in the same relative order.
        let mut last = None;
        for name in ACTUATORS {
            let at = JOINTS.iter().position(|j| *j == name);
            assert!(at.is_some(), "{name}");
            assert!(at > last, "{name} out of order");
            last = at;
        }
        // The four unactuated joints are the coupled distal joints.
        let unactuated: Vec<&str> = JOINTS
            .into_iter()
            .filter(|j| !ACTUATORS.contains(j))
            .collect();
        assert_eq!(unactuated, ["FFJ0", "MFJ0", "RFJ0", "LFJ0"]);
        for [lo, hi] in TARGET_POSITION_RANGE {
            assert!(lo < hi);
        }
    }
}
