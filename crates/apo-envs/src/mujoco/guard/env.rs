//! [`GuardEnv`]: one GUARD suite (a task on a robot) as an [`Env`].
//!
//! Each environment compiles its own copy of the robot's model (plus the ball for Push), so
//! that a reset can move and turn the robot's root body in the model, as GUARD's engine does
//! by writing a new MJCF file every episode, without compiling again. The goal, the 3D hazards
//! and the robbers never touch anything, so they are positions kept here, not bodies.

use std::f64::consts::TAU;
use std::ops::Range;
use std::sync::Arc;

use rand::Rng;

use super::layout::{
    draw, uniform_xy, Placed, BALL_KEEPOUT, DRAWS_PER_OBJECT, GOAL_KEEPOUT, GOAL_TRIES,
    HAZARD3D_KEEPOUT, LAYOUT_TRIES, ROBBER_KEEPOUT, ROBOT_KEEPOUT,
};
use super::robot::{Robot, Root};
use super::sensing::{
    compass, lidar_2d, lidar_3d, LIDAR3D_AZIMUTH_BINS, LIDAR3D_ELEVATION_BINS, LIDAR_BINS,
};
use super::{Suite, TaskKind};
use crate::env::{Action, Env, Transition};
use crate::mujoco::env::transition;
use crate::mujoco::error::MujocoError;
use crate::mujoco::model::{Data, Model, ObjKind};
use crate::mujoco::render::SceneRenderer;
use crate::mujoco::scene::{Decor, Shape, TrackView};
use crate::render::{Camera, Frame, RenderError};
use crate::rng::{entropy_rng, reseed, EnvRng};
use crate::space::Space;

/// Simulator steps per environment step.
pub const SUBSTEPS: usize = 10;
/// Distance at which a goal counts as reached (robot to goal, or ball to goal for Push).
pub const GOAL_SIZE: f64 = 0.5;
/// The bonus for reaching a goal, added after clipping.
pub const GOAL_BONUS: f64 = 1.0;
/// The dense reward of a step is clipped to `±REWARD_CLIP`.
pub const REWARD_CLIP: f64 = 10.0;
/// Height of a floor goal's centre (a cylinder of half-height 0.25).
pub const GOAL_Z_2D: f64 = 0.26;
/// Range of a 3D goal's (and 3D hazard's) height.
pub const Z_RANGE_3D: Range<f64> = 0.5..1.5;
/// Radius of the Push ball; the robot-to-ball reward is gated off within twice this.
pub const BALL_RADIUS: f64 = 0.2;
/// The 3D hazards of the Arm3 and Drone suites.
pub const HAZARD3D_COUNT: usize = 8;
/// Radius of a 3D hazard sphere.
pub const HAZARD3D_RADIUS: f64 = 0.3;
/// The Chase robbers.
pub const ROBBER_COUNT: usize = 2;
/// A robber's step per simulator step when drifting; it flees at ten times this.
pub const ROBBER_SPEED: f64 = 1e-4;
/// Robbers closer than this push each other apart (twice their radius 0.3).
pub const ROBBER_SPACING: f64 = 0.6;
/// A robber beyond this distance from the origin drifts back.
pub const ROBBER_TRAVEL: f64 = 2.0;
/// A robber flees a robot within this xy distance.
pub const CHASE_RANGE: f64 = 3.0;
/// Robber height at reset and after the first simulator step (an artefact of GUARD's mocap
/// bodies, kept because the Chase reward measures 3D distances).
const ROBBER_Z: [f64; 2] = [0.02, 0.04];
/// The Drone's gravity compensation stops above this height.
const DRONE_CEILING: f64 = 3.0;
/// The Drone's thrust per unit of action, per rotor.
const DRONE_THRUST_GAIN: f64 = 0.1;
/// Arm3's goals lie within this 3D distance of the origin...
const ARM_REACH: f64 = 2.0;
/// ... and at least this far from the end effector.
const ARM_GOAL_CLEARANCE: f64 = 0.5;
/// Layout rebuilds while the robot starts inside a 3D hazard.
const HAZARD_FREE_TRIES: usize = 100;
/// Gravity's magnitude (the Drone's hover thrust).
const GRAVITY: f64 = 9.81;

/// Where an observation block's values come from.
#[derive(Debug, Clone)]
enum Source {
    /// A sensor's values; `angle`: a hinge position, shown as `(sin θ, cos θ)`.
    Sensor { range: Range<usize>, angle: bool },
    /// The compass of each lidar body towards the goal.
    GoalCompass,
    /// The robot's compass towards the ball.
    BoxCompass,
    /// The 2D hazard lidar of the 2D suites; there are no 2D hazards, so it reads 0.
    HazardsLidar,
    /// The 3D lidar of each lidar body over the 3D hazards.
    Hazard3DsLidar,
    /// The robot's 2D lidar over the robbers.
    RobbersLidar,
}

/// One observation block: its key (blocks are ordered by key), length and source.
#[derive(Debug, Clone)]
struct Block {
    key: String,
    len: usize,
    source: Source,
}

/// The engine keys of `suite`'s observation with their lengths.
fn engine_blocks(suite: Suite) -> Vec<(&'static str, usize, Source)> {
    let robot = suite.robot;
    let bodies = robot.lidar_bodies().len();
    let mut blocks = Vec::new();
    if suite.task != TaskKind::Chase {
        blocks.push((
            "goal_compass",
            bodies * robot.compass_dim(),
            Source::GoalCompass,
        ));
    }
    if suite.task == TaskKind::Push {
        blocks.push(("box_compass", 2, Source::BoxCompass));
    }
    if robot.goal_3d() {
        let bins = LIDAR3D_AZIMUTH_BINS * LIDAR3D_ELEVATION_BINS;
        blocks.push(("hazard3Ds_lidar", bodies * bins, Source::Hazard3DsLidar));
    } else {
        blocks.push(("hazards_lidar", LIDAR_BINS, Source::HazardsLidar));
    }
    if suite.task == TaskKind::Chase {
        blocks.push(("robbers_lidar", LIDAR_BINS, Source::RobbersLidar));
    }
    blocks
}

/// The observation length of `suite`: the robot's sensors and the engine's blocks.
pub(crate) fn observation_dim(suite: Suite) -> usize {
    suite.robot.sensor_obs_dim() + engine_blocks(suite).iter().map(|b| b.1).sum::<usize>()
}

/// The MJCF text of `suite`: the robot's model, with the ball for Push.
pub(crate) fn mjcf(suite: Suite) -> String {
    let robot = suite.robot.mjcf();
    if suite.task != TaskKind::Push {
        return robot.to_owned();
    }
    let ball = format!(
        "    <body name=\"box\" pos=\"0 0 {BALL_RADIUS}\">\n      <freejoint name=\"box\"/>\n      \
         <geom name=\"box\" type=\"sphere\" size=\"{BALL_RADIUS}\" density=\"0.001\" \
         friction=\"1 0.005 0.05\"/>\n    </body>\n  </worldbody>"
    );
    robot.replacen("</worldbody>", &ball, 1)
}

/// The unit quaternion of a turn by `yaw` about z.
fn yaw_quat(yaw: f64) -> [f64; 4] {
    let (s, c) = (yaw / 2.0).sin_cos();
    [c, 0.0, 0.0, s]
}

fn dist3(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Ids the engine reads every step.
#[derive(Debug, Clone)]
struct Ids {
    /// Body `robot`.
    robot: usize,
    /// The body whose origin is the robot's position in rewards.
    position: usize,
    /// The bodies with a compass and a 3D lidar.
    lidar: Vec<usize>,
    /// The ball's body and the address of its free joint in `qpos` (Push).
    ball: Option<(usize, usize)>,
    /// The address of the robot's free joint in `qpos` (Ant).
    free_root: Option<usize>,
    /// The Drone's rotor bodies.
    rotors: Option<[usize; 4]>,
}

/// A GUARD suite: `task` on `robot`, stepped as GUARD's engine steps it (see `docs/guard.md`).
///
/// - Reset: a new layout from the environment's RNG (robot place and heading, goal, ball,
///   3D hazards, robbers, with keep-outs), the robot at rest in its reference configuration.
/// - Step: the controls are the action clipped to the actuators' ranges (the Drone's four
///   values are rotor thrusts), then 10 simulator steps (robbers move before each), then the
///   reward, the goal check and the observation.
/// - Episodes never end by themselves, except when no new goal can be placed after a success
///   (practically never) or the simulator becomes unstable (a MuJoCo warning, or a non-finite
///   state, reward or observation: `info.unstable`, reward 0); the registry adds the
///   1000-step limit.
pub struct GuardEnv {
    suite: Suite,
    data: Data,
    rng: EnvRng,
    ids: Ids,
    blocks: Vec<Block>,
    /// The root body's height in the model.
    root_z: f64,
    /// Each actuator's control range.
    ctrl_range: Vec<[f64; 2]>,
    /// The Drone's mass, for its hover thrust.
    drone_mass: f64,
    goal: [f64; 3],
    hazards: [[f64; 3]; HAZARD3D_COUNT],
    robbers: [[f64; 3]; ROBBER_COUNT],
    /// The distances the dense reward differences: robot–goal; robot–ball and ball–goal for
    /// Push; robot–nearest robber for Chase (`None` until the first step).
    last: [Option<f64>; 2],
    placed: Vec<Placed>,
    observation_space: Space,
    action_space: Space,
    /// Its OpenGL context and scene, made by the first [`Env::render`].
    renderer: SceneRenderer,
}

impl std::fmt::Debug for GuardEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GuardEnv")
            .field("suite", &self.suite.name())
            .field("goal", &self.goal)
            .field("data", &self.data)
            .finish_non_exhaustive()
    }
}

impl GuardEnv {
    /// Builds `suite`: compiles its model (this environment's own copy) and checks that it
    /// has every sensor, body and actuator the engine reads.
    pub fn new(suite: Suite) -> Result<Self, MujocoError> {
        let model = Model::from_xml_str(&suite.mjcf())?;
        let robot = suite.robot;
        let body = |name: &str| model.id(ObjKind::Body, name);
        let joint_qpos = |name: &str| {
            let id = model.id(ObjKind::Joint, name)?;
            model
                .joint_qpos_adr(id)
                .ok_or_else(|| MujocoError::UnknownName {
                    kind: "joint",
                    name: name.into(),
                })
        };
        let ids = Ids {
            robot: body("robot")?,
            position: body(robot.position_body())?,
            lidar: robot
                .lidar_bodies()
                .iter()
                .map(|b| body(b))
                .collect::<Result<_, _>>()?,
            ball: match suite.task {
                TaskKind::Push => Some((body("box")?, joint_qpos("box")?)),
                _ => None,
            },
            free_root: match robot.root() {
                // The free joint is the root body's first joint.
                Root::Free => Some(0),
                _ => None,
            },
            rotors: match robot {
                Robot::Drone => Some([body("p1")?, body("p2")?, body("p3")?, body("p4")?]),
                _ => None,
            },
        };
        let nu = if robot == Robot::Drone {
            0
        } else {
            robot.action_dim()
        };
        if model.nu() != nu {
            return Err(MujocoError::Shape {
                env: robot.name(),
                what: "nu",
                found: model.nu(),
                expected: nu,
            });
        }
        let mut blocks = Vec::new();
        let mut sensordata = 0;
        for name in robot.sensors() {
            let id = model.id(ObjKind::Sensor, &name)?;
            let range = model
                .sensor_range(id)
                .ok_or_else(|| MujocoError::UnknownName {
                    kind: "sensor",
                    name: name.clone(),
                })?;
            let angle = name.starts_with("jointpos_");
            let expected = if name.starts_with("touch") || name.starts_with("joint") {
                1
            } else {
                3
            };
            if range.len() != expected {
                return Err(MujocoError::Shape {
                    env: robot.name(),
                    what: "sensor values",
                    found: range.len(),
                    expected,
                });
            }
            sensordata += range.len();
            let len = if angle { 2 } else { range.len() };
            blocks.push(Block {
                key: name,
                len,
                source: Source::Sensor { range, angle },
            });
        }
        if sensordata != model.nsensordata() {
            return Err(MujocoError::Shape {
                env: robot.name(),
                what: "nsensordata",
                found: model.nsensordata(),
                expected: sensordata,
            });
        }
        for (key, len, source) in engine_blocks(suite) {
            blocks.push(Block {
                key: key.to_owned(),
                len,
                source,
            });
        }
        // GUARD flattens its observation dictionary in the byte order of the keys.
        blocks.sort_by(|a, b| a.key.cmp(&b.key));
        let root_z = model.body_pos().get(ids.robot).map_or(0.0, |p| p[2]);
        let drone_mass = ids.rotors.map_or(0.0, |rotors| {
            std::iter::once(ids.robot)
                .chain(rotors)
                .map(|b| model.body_mass().get(b).copied().unwrap_or(0.0))
                .sum()
        });
        let ctrl_range = (0..model.nu())
            .map(|i| match model.actuator_ctrlrange().get(i) {
                Some(&range) if model.actuator_ctrllimited(i) => range,
                _ => [f64::NEG_INFINITY, f64::INFINITY],
            })
            .collect();
        let obs_dim = observation_dim(suite);
        let data = Data::new(Arc::new(model))?;
        Ok(GuardEnv {
            suite,
            data,
            rng: entropy_rng(),
            ids,
            blocks,
            root_z,
            ctrl_range,
            drone_mass,
            goal: [0.0, 0.0, GOAL_Z_2D],
            hazards: [[0.0; 3]; HAZARD3D_COUNT],
            robbers: [[0.0; 3]; ROBBER_COUNT],
            last: [None; 2],
            placed: Vec::with_capacity(16),
            observation_space: Space::uniform_box(obs_dim, f32::NEG_INFINITY, f32::INFINITY),
            action_space: Space::uniform_box(robot.action_dim(), -1.0, 1.0),
            renderer: SceneRenderer::default(),
        })
    }

    /// The suite.
    pub fn suite(&self) -> Suite {
        self.suite
    }

    /// The simulation data (read-only).
    pub fn data(&self) -> &Data {
        &self.data
    }

    /// The goal's centre (unused by Chase).
    pub fn goal(&self) -> [f64; 3] {
        self.goal
    }

    /// The 3D hazards' centres (Arm3 and Drone; empty otherwise).
    pub fn hazards(&self) -> &[[f64; 3]] {
        if self.suite.robot.goal_3d() {
            &self.hazards
        } else {
            &[]
        }
    }

    /// The robbers' positions (Chase; empty otherwise).
    pub fn robbers(&self) -> &[[f64; 3]] {
        if self.suite.task == TaskKind::Chase {
            &self.robbers
        } else {
            &[]
        }
    }

    /// The robot's position in rewards: body `robot`'s origin (Arm3: the end effector's).
    pub fn robot_position(&self) -> [f64; 3] {
        self.body_pos(self.ids.position)
    }

    /// The ball's centre (Push), or `None`.
    pub fn ball(&self) -> Option<[f64; 3]> {
        self.ids.ball.map(|(body, _)| self.body_pos(body))
    }

    /// The block layout of the observation: each key with its length, in observation order.
    pub fn observation_keys(&self) -> Vec<(&str, usize)> {
        self.blocks
            .iter()
            .map(|b| (b.key.as_str(), b.len))
            .collect()
    }

    /// Moves the goal to `goal` (for scripted scenes and tests); the next step's reward
    /// differences distances to it.
    pub fn set_goal(&mut self, goal: [f64; 3]) {
        self.goal = goal;
        self.remember_distances();
    }

    /// Moves the robbers to `robbers` (for scripted scenes and tests).
    pub fn set_robbers(&mut self, robbers: [[f64; 3]; ROBBER_COUNT]) {
        self.robbers = robbers;
    }

    fn body_pos(&self, id: usize) -> [f64; 3] {
        self.data.xpos().get(id).copied().unwrap_or_default()
    }

    fn body_mat(&self, id: usize) -> [f64; 9] {
        self.data.xmat().get(id).copied().unwrap_or_default()
    }

    /// Draws a layout, places the robot and the ball in the simulation, and draws the goal.
    /// Returns `false` if some object found no place.
    fn build_layout(&mut self) -> bool {
        let suite = self.suite;
        let robot = suite.robot;
        let rng = &mut self.rng;
        let placed = &mut self.placed;
        placed.clear();
        let robot_xy = if robot.root() == Root::Fixed {
            placed.push(Placed {
                xy: [0.0, 0.0],
                keepout: ROBOT_KEEPOUT,
            });
            Some([0.0, 0.0])
        } else {
            draw(rng, placed, ROBOT_KEEPOUT, DRAWS_PER_OBJECT, |_| true)
        };
        let Some(robot_xy) = robot_xy else {
            return false;
        };
        if suite.task != TaskKind::Chase
            && draw(rng, placed, GOAL_KEEPOUT, DRAWS_PER_OBJECT, |_| true).is_none()
        {
            return false;
        }
        let mut ball_xy = [0.0; 2];
        if suite.task == TaskKind::Push {
            match draw(rng, placed, BALL_KEEPOUT, DRAWS_PER_OBJECT, |_| true) {
                Some(xy) => ball_xy = xy,
                None => return false,
            }
        }
        if robot.goal_3d() {
            // Arm3's hazards stay within its reach.
            let within = |xy: [f64; 2]| robot != Robot::Arm3 || xy[0].hypot(xy[1]) <= ARM_REACH;
            for i in 0..HAZARD3D_COUNT {
                match draw(rng, placed, HAZARD3D_KEEPOUT, DRAWS_PER_OBJECT, within) {
                    Some(xy) => self.hazards[i] = [xy[0], xy[1], 0.0],
                    None => return false,
                }
            }
        }
        if suite.task == TaskKind::Chase {
            for i in 0..ROBBER_COUNT {
                match draw(rng, placed, ROBBER_KEEPOUT, DRAWS_PER_OBJECT, |_| true) {
                    Some(xy) => self.robbers[i] = [xy[0], xy[1], ROBBER_Z[0]],
                    None => return false,
                }
            }
        }
        let yaw = rng.random_range(0.0..TAU);
        let ball_yaw = rng.random_range(0.0..TAU);
        if robot.goal_3d() {
            self.goal[2] = rng.random_range(Z_RANGE_3D);
            for hazard in &mut self.hazards {
                hazard[2] = rng.random_range(Z_RANGE_3D);
            }
        } else {
            self.goal[2] = GOAL_Z_2D;
        }
        self.place_robot(robot_xy, yaw, ball_xy, ball_yaw);
        // The goal drawn with the layout only reserved its place; draw it again against the
        // objects where they now are, as after a success.
        suite.task == TaskKind::Chase || self.place_goal()
    }

    /// Resets the simulation with the robot at `xy` turned by `yaw` and the ball at `ball_xy`.
    fn place_robot(&mut self, xy: [f64; 2], yaw: f64, ball_xy: [f64; 2], ball_yaw: f64) {
        let pose = ([xy[0], xy[1], self.root_z], yaw_quat(yaw));
        let (robot, free_root) = (self.ids.robot, self.ids.free_root);
        if free_root.is_none() {
            if let Some(model) = self.data.model_mut() {
                model.set_body_pose(robot, pose.0, pose.1);
            }
        }
        self.data.reset();
        let qpos = self.data.qpos_mut();
        let mut put = |adr: usize, pos: [f64; 3], quat: [f64; 4]| {
            if let Some(slot) = qpos.get_mut(adr..adr + 7) {
                slot[..3].copy_from_slice(&pos);
                slot[3..].copy_from_slice(&quat);
            }
        };
        if let Some(adr) = free_root {
            put(adr, pose.0, pose.1);
        }
        if let Some((_, adr)) = self.ids.ball {
            put(
                adr,
                [ball_xy[0], ball_xy[1], BALL_RADIUS],
                yaw_quat(ball_yaw),
            );
        }
        self.data.forward();
    }

    /// Draws a new goal clear of the robot, the ball and the hazards where they are now (and,
    /// for Arm3, within reach and away from the end effector); resets the remembered
    /// distances. Returns `false` if no place was found.
    fn place_goal(&mut self) -> bool {
        let robot = self.suite.robot;
        self.placed.clear();
        let robot_xy = if robot.root() == Root::Fixed {
            [0.0, 0.0]
        } else {
            let p = self.body_pos(self.ids.robot);
            [p[0], p[1]]
        };
        self.placed.push(Placed {
            xy: robot_xy,
            keepout: ROBOT_KEEPOUT,
        });
        if let Some(ball) = self.ball() {
            self.placed.push(Placed {
                xy: [ball[0], ball[1]],
                keepout: BALL_KEEPOUT,
            });
        }
        if robot.goal_3d() {
            for h in &self.hazards {
                self.placed.push(Placed {
                    xy: [h[0], h[1]],
                    keepout: HAZARD3D_KEEPOUT,
                });
            }
        }
        let end_effector = self.robot_position();
        let z = self.goal[2];
        for _ in 0..GOAL_TRIES {
            let xy = uniform_xy(&mut self.rng, GOAL_KEEPOUT);
            let goal = [xy[0], xy[1], z];
            let clear = self.placed.iter().all(|p| p.clear_of(xy, GOAL_KEEPOUT));
            let reachable = robot != Robot::Arm3
                || (dist3(&goal, &[0.0; 3]) <= ARM_REACH
                    && dist3(&goal, &end_effector) >= ARM_GOAL_CLEARANCE);
            if clear && reachable {
                self.goal = goal;
                self.remember_distances();
                return true;
            }
        }
        false
    }

    /// The robot-to-goal distance: xy for the floor robots, 3D for Arm3 and the Drone.
    fn goal_distance(&self) -> f64 {
        let p = self.robot_position();
        if self.suite.robot.goal_3d() {
            dist3(&p, &self.goal)
        } else {
            dist2(&p, &self.goal)
        }
    }

    /// The distances the dense reward differences, now (see [`GuardEnv::last`]).
    fn distances(&self) -> [f64; 2] {
        let p = self.robot_position();
        match self.suite.task {
            TaskKind::Goal => [self.goal_distance(), 0.0],
            TaskKind::Push => {
                let ball = self.ball().unwrap_or_default();
                [dist3(&p, &ball), dist3(&ball, &self.goal)]
            }
            TaskKind::Chase => [
                self.robbers
                    .iter()
                    .map(|r| dist3(&p, r))
                    .fold(f64::INFINITY, f64::min),
                0.0,
            ],
        }
    }

    fn remember_distances(&mut self) {
        let now = self.distances();
        self.last = [Some(now[0]), Some(now[1])];
    }

    /// Whether the robot's position is inside a 3D hazard (GUARD's reset redraws then).
    fn in_hazard(&self) -> bool {
        let p = self.robot_position();
        self.hazards()
            .iter()
            .any(|h| dist3(&p, h) <= HAZARD3D_RADIUS)
    }

    /// Moves each robber one simulator step: away from a robot within [`CHASE_RANGE`] at ten
    /// times [`ROBBER_SPEED`]; back towards the origin (and apart from a too-close robber) when
    /// beyond [`ROBBER_TRAVEL`]; else it stays.
    fn move_robbers(&mut self) {
        let robot = self.robot_position();
        let last = self.robbers;
        for (i, robber) in self.robbers.iter_mut().enumerate() {
            let p = [last[i][0], last[i][1]];
            let radius = p[0].hypot(p[1]);
            let mut next = p;
            if radius > ROBBER_TRAVEL {
                for (j, other) in last.iter().enumerate() {
                    let d = [p[0] - other[0], p[1] - other[1]];
                    let n = d[0].hypot(d[1]);
                    if j != i && n < ROBBER_SPACING && n > 0.0 {
                        next[0] += ROBBER_SPEED * d[0] / n;
                        next[1] += ROBBER_SPEED * d[1] / n;
                    }
                }
                next[0] -= ROBBER_SPEED * p[0] / radius;
                next[1] -= ROBBER_SPEED * p[1] / radius;
            } else {
                let d = [robot[0] - p[0], robot[1] - p[1]];
                let n = d[0].hypot(d[1]);
                if n <= CHASE_RANGE && n > 0.0 {
                    next[0] -= 10.0 * ROBBER_SPEED * d[0] / n;
                    next[1] -= 10.0 * ROBBER_SPEED * d[1] / n;
                }
            }
            *robber = [next[0], next[1], ROBBER_Z[1]];
        }
    }

    /// Sets the Drone's rotor forces for `action`: each rotor pushes along the body's z axis
    /// with a quarter of the hover thrust (none above [`DRONE_CEILING`]) plus 0.1 × its action.
    fn drive_drone(&mut self, action: &[f32], rotors: [usize; 4]) {
        let r = self.body_mat(self.ids.robot);
        let height = self.body_pos(self.ids.robot)[2];
        let hover = if height > DRONE_CEILING {
            0.0
        } else {
            GRAVITY * self.drone_mass
        };
        let forces = self.data.xfrc_applied_mut();
        for (&body, &a) in rotors.iter().zip(action) {
            let thrust = hover / 4.0 + DRONE_THRUST_GAIN * f64::from(a).clamp(-1.0, 1.0);
            if let Some(f) = forces.get_mut(body) {
                *f = [r[2] * thrust, r[5] * thrust, r[8] * thrust, 0.0, 0.0, 0.0];
            }
        }
    }

    /// The step's reward and whether the episode must end (no place for a new goal).
    fn reward(&mut self) -> (f64, bool) {
        let now = self.distances();
        let gain = |last: Option<f64>, now: f64| last.map_or(0.0, |l| l - now);
        let dense = match self.suite.task {
            TaskKind::Goal | TaskKind::Chase => gain(self.last[0], now[0]),
            TaskKind::Push => {
                let toward_ball = if self.last[0].is_some_and(|l| l > 2.0 * BALL_RADIUS) {
                    gain(self.last[0], now[0])
                } else {
                    0.0
                };
                toward_ball + gain(self.last[1], now[1])
            }
        };
        self.last = [Some(now[0]), Some(now[1])];
        let mut reward = dense.clamp(-REWARD_CLIP, REWARD_CLIP);
        let reached = match self.suite.task {
            TaskKind::Goal => now[0] <= GOAL_SIZE,
            TaskKind::Push => now[1] <= GOAL_SIZE,
            TaskKind::Chase => false,
        };
        let mut end = false;
        if reached {
            reward += GOAL_BONUS;
            end = !self.place_goal();
        }
        (reward, end)
    }

    /// Writes the observation of the current state into `obs` (`[observation_dim]`), for
    /// example after [`GuardEnv::set_goal`] or [`GuardEnv::set_robbers`].
    pub fn observe(&self, obs: &mut [f32]) {
        let sensordata = self.data.sensordata();
        let mut at = 0;
        for block in &self.blocks {
            let Some(out) = obs.get_mut(at..at + block.len) else {
                return;
            };
            at += block.len;
            match &block.source {
                Source::Sensor { range, angle } => {
                    let values = sensordata.get(range.clone()).unwrap_or_default();
                    if *angle {
                        let theta = values.first().copied().unwrap_or_default();
                        out[0] = theta.sin() as f32;
                        out[1] = theta.cos() as f32;
                    } else {
                        for (o, &v) in out.iter_mut().zip(values) {
                            *o = v as f32;
                        }
                    }
                }
                Source::GoalCompass => {
                    let d = self.suite.robot.compass_dim();
                    for (chunk, &body) in out.chunks_mut(d).zip(&self.ids.lidar) {
                        let (r, p) = (self.body_mat(body), self.body_pos(body));
                        compass(&r, &p, &self.goal, chunk);
                    }
                }
                Source::BoxCompass => {
                    let (r, p) = (self.body_mat(self.ids.robot), self.body_pos(self.ids.robot));
                    compass(&r, &p, &self.ball().unwrap_or_default(), out);
                }
                Source::HazardsLidar => out.fill(0.0),
                Source::Hazard3DsLidar => {
                    let bins = LIDAR3D_AZIMUTH_BINS * LIDAR3D_ELEVATION_BINS;
                    for (chunk, &body) in out.chunks_mut(bins).zip(&self.ids.lidar) {
                        let (r, p) = (self.body_mat(body), self.body_pos(body));
                        lidar_3d(&r, &p, &self.hazards, true, chunk);
                    }
                }
                Source::RobbersLidar => {
                    let (r, p) = (self.body_mat(self.ids.robot), self.body_pos(self.ids.robot));
                    lidar_2d(&r, &p, &self.robbers, true, out);
                }
            }
        }
    }
}

impl Env for GuardEnv {
    fn observation_space(&self) -> &Space {
        &self.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.action_space
    }

    /// Draws a new layout (from the reseeded RNG with `Some(seed)`), redrawing it while the
    /// robot would start inside a 3D hazard.
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        reseed(&mut self.rng, seed);
        for _ in 0..HAZARD_FREE_TRIES {
            let mut built = false;
            for _ in 0..LAYOUT_TRIES {
                if self.build_layout() {
                    built = true;
                    break;
                }
            }
            if !built || !self.in_hazard() {
                break;
            }
        }
        self.remember_distances();
        if self.suite.task == TaskKind::Chase {
            // GUARD's Chase reward is 0 on the first step after a reset.
            self.last = [None; 2];
        }
        self.observe(obs);
    }

    /// # Panics
    /// If the action is not continuous with [`Robot::action_dim`] values, or `obs` has the
    /// wrong length.
    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let Action::Continuous(action) = action else {
            panic!("{}: expects a continuous action", self.suite.name());
        };
        assert_eq!(
            action.len(),
            self.suite.robot.action_dim(),
            "{}: action has the wrong length",
            self.suite.name()
        );
        assert_eq!(
            obs.len(),
            self.observation_space.flat_dim(),
            "{}: observation buffer has the wrong length",
            self.suite.name()
        );
        if let Some(rotors) = self.ids.rotors {
            self.drive_drone(action, rotors);
        } else {
            for ((c, &a), range) in self
                .data
                .ctrl_mut()
                .iter_mut()
                .zip(action)
                .zip(&self.ctrl_range)
            {
                *c = f64::from(a).clamp(range[0], range[1]);
            }
        }
        let warnings = self.data.unstable_warnings();
        for _ in 0..SUBSTEPS {
            if self.suite.task == TaskKind::Chase {
                self.move_robbers();
            }
            self.data.step();
        }
        let outcome = (!self.data.unstable_since(warnings)).then(|| {
            self.data.forward();
            self.reward()
        });
        self.observe(obs);
        transition(outcome, obs)
    }

    /// The scene with what the simulation does not hold as geoms: the goal (green), the 3D
    /// hazards (blue) and the robbers (red), followed from above the robot.
    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        let mut decor = Vec::with_capacity(1 + HAZARD3D_COUNT + ROBBER_COUNT);
        if self.suite.task != TaskKind::Chase {
            decor.push(if self.suite.robot.goal_3d() {
                Decor {
                    shape: Shape::Sphere,
                    size: [GOAL_SIZE * 0.5, 0.0, 0.0],
                    pos: self.goal,
                    rgba: [0.2, 0.9, 0.3, 0.6],
                }
            } else {
                Decor {
                    shape: Shape::Cylinder,
                    size: [GOAL_SIZE, 0.01, 0.0],
                    pos: [self.goal[0], self.goal[1], 0.01],
                    rgba: [0.2, 0.9, 0.3, 0.6],
                }
            });
        }
        decor.extend(self.hazards().iter().map(|&pos| Decor {
            shape: Shape::Sphere,
            size: [HAZARD3D_RADIUS, 0.0, 0.0],
            pos,
            rgba: [0.25, 0.35, 1.0, 0.45],
        }));
        decor.extend(self.robbers().iter().map(|&[x, y, _]| Decor {
            shape: Shape::Sphere,
            size: [ROBBER_SPACING / 2.0, 0.0, 0.0],
            pos: [x, y, ROBBER_SPACING / 2.0],
            rgba: [0.95, 0.2, 0.2, 0.8],
        }));
        let track = TrackView {
            body: self.ids.robot,
            distance: 6.0,
            azimuth: 90.0,
            elevation: -55.0,
            grid: true,
        };
        self.renderer
            .render(&mut self.data, camera, track, &decor, frame)
    }
}
