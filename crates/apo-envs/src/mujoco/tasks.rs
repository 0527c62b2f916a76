//! The Gym MuJoCo locomotion tasks, following the Gymnasium v4 definitions of observation,
//! reward, termination, frame skip and reset noise. Each task is a small [`Task`]; the shared
//! machinery is in [`super::MujocoEnv`]. The models are this project's own MJCF files under
//! `crates/apo-envs/assets/`, embedded in the binary.

use super::env::{uniform, ResetNoise, Sizes, StepContext, Task};
use super::error::MujocoError;
use super::model::{Data, Model, ObjKind};
use super::scene::TrackView;
use crate::rng::EnvRng;

/// Writes consecutive values into an observation buffer.
struct ObsWriter<'a> {
    obs: &'a mut [f32],
    at: usize,
}

impl<'a> ObsWriter<'a> {
    fn new(obs: &'a mut [f32]) -> Self {
        ObsWriter { obs, at: 0 }
    }

    fn put(&mut self, values: impl IntoIterator<Item = f64>) {
        for v in values {
            self.obs[self.at] = v as f32;
            self.at += 1;
        }
    }

    fn put_clipped(&mut self, values: &[f64], limit: f64) {
        self.put(values.iter().map(|v| v.clamp(-limit, limit)));
    }

    fn put_rows<const N: usize>(&mut self, rows: &[[f64; N]]) {
        self.put(rows.iter().flatten().copied());
    }
}

/// `Σ a²` over the action.
fn sum_sq(action: &[f32]) -> f64 {
    action.iter().map(|&a| f64::from(a) * f64::from(a)).sum()
}

/// Body `id`'s frame position, `[0; 3]` if out of range.
fn body_xpos(data: &Data, id: usize) -> [f64; 3] {
    data.xpos().get(id).copied().unwrap_or_default()
}

/// Gymnasium's `mass_center`: the mass-weighted mean of the bodies' centres of mass.
fn mass_center(data: &Data) -> [f64; 3] {
    let masses = data.model().body_mass();
    let total: f64 = masses.iter().sum();
    let mut c = [0.0; 3];
    for (m, p) in masses.iter().zip(data.xipos()) {
        for k in 0..3 {
            c[k] += m * p[k];
        }
    }
    c.map(|x| x / total)
}

/// The root's x position `qpos[0]`, as [`Task::before_step`] of the tasks that reward the
/// root's forward velocity.
fn root_x(data: &Data) -> [f64; 3] {
    [data.qpos()[0], 0.0, 0.0]
}

/// The forward velocity over the step of a point whose x is now `x` and was `ctx.before[0]`.
fn x_velocity(x: f64, ctx: &StepContext<'_>) -> f64 {
    (x - ctx.before[0]) / ctx.dt
}

/// `lo < x < hi`.
fn within(x: f64, (lo, hi): (f64, f64)) -> bool {
    lo < x && x < hi
}

/// InvertedPendulum-v4: keep the pole upright; +1 per step; ends when |pole angle| > 0.2.
/// Observation (4): `qpos`, `qvel`. Frame skip 2 (dt 0.04 s).
#[derive(Debug, Clone, Copy, Default)]
pub struct InvertedPendulum;

impl Task for InvertedPendulum {
    const NAME: &'static str = "InvertedPendulum";
    const TRACK: TrackView = TrackView {
        body: 0,
        distance: 2.5,
        azimuth: 90.0,
        elevation: -10.0,
        grid: false,
    };
    const MJCF: &'static str = include_str!("../../assets/inverted_pendulum.xml");
    const SIZES: Sizes = Sizes {
        nq: 2,
        nv: 2,
        nu: 1,
        nbody: 3,
    };
    const OBS_DIM: usize = 4;
    const FRAME_SKIP: usize = 2;

    fn new(_model: &Model) -> Result<Self, MujocoError> {
        Ok(InvertedPendulum)
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        ResetNoise::Uniform {
            qpos: 0.01,
            qvel: 0.01,
        }
        .apply(rng, qpos, qvel);
    }

    fn reward(&self, data: &Data, _ctx: &StepContext<'_>) -> (f64, bool) {
        (1.0, data.qpos()[1].abs() > 0.2)
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        let mut w = ObsWriter::new(obs);
        w.put(data.qpos().iter().copied());
        w.put(data.qvel().iter().copied());
    }
}

/// InvertedDoublePendulum-v4: balance two stacked poles. Reward
/// `10 − (0.01·x² + (y − 2)²) − (1e-3·ω1² + 5e-3·ω2²)` with `(x, y)` the tip of the second pole
/// and `ω1, ω2` the hinge velocities; ends when `y ≤ 1`. Observation (11): cart position,
/// sin and cos of the two hinge angles, `clip(qvel, ±10)`, `clip(qfrc_constraint, ±10)`.
/// Frame skip 5 (dt 0.05 s).
#[derive(Debug, Clone, Copy)]
pub struct InvertedDoublePendulum {
    tip: usize,
}

impl Task for InvertedDoublePendulum {
    const NAME: &'static str = "InvertedDoublePendulum";
    const TRACK: TrackView = TrackView {
        body: 0,
        distance: 3.5,
        azimuth: 90.0,
        elevation: -10.0,
        grid: false,
    };
    const MJCF: &'static str = include_str!("../../assets/inverted_double_pendulum.xml");
    const SIZES: Sizes = Sizes {
        nq: 3,
        nv: 3,
        nu: 1,
        nbody: 4,
    };
    const OBS_DIM: usize = 11;
    const FRAME_SKIP: usize = 5;

    fn new(model: &Model) -> Result<Self, MujocoError> {
        Ok(InvertedDoublePendulum {
            tip: model.id(ObjKind::Site, "tip")?,
        })
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        ResetNoise::UniformNormal {
            qpos: 0.1,
            qvel_std: 0.1,
        }
        .apply(rng, qpos, qvel);
    }

    fn reward(&self, data: &Data, _ctx: &StepContext<'_>) -> (f64, bool) {
        let [x, _, y] = data.site_xpos().get(self.tip).copied().unwrap_or_default();
        let dist_penalty = 0.01 * x * x + (y - 2.0).powi(2);
        let (v1, v2) = (data.qvel()[1], data.qvel()[2]);
        let vel_penalty = 1e-3 * v1 * v1 + 5e-3 * v2 * v2;
        (10.0 - dist_penalty - vel_penalty, y <= 1.0)
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        let q = data.qpos();
        let mut w = ObsWriter::new(obs);
        w.put([q[0]]);
        w.put(q[1..].iter().map(|a| a.sin()));
        w.put(q[1..].iter().map(|a| a.cos()));
        w.put_clipped(data.qvel(), 10.0);
        w.put_clipped(data.qfrc_constraint(), 10.0);
    }
}

/// Reacher-v4: move the fingertip to a random target. Reward `−‖fingertip − target‖ − Σ a²`,
/// the distance taken before the step (as Gymnasium does); never terminates. Observation (11):
/// cos and sin of the two arm angles, target position, arm velocities,
/// fingertip − target (3). Frame skip 2 (dt 0.02 s). The target is drawn uniformly in the disc
/// of radius 0.2 around the arm's base.
#[derive(Debug, Clone, Copy)]
pub struct Reacher {
    fingertip: usize,
    target: usize,
}

impl Reacher {
    fn fingertip_to_target(&self, data: &Data) -> [f64; 3] {
        let (f, t) = (
            body_xpos(data, self.fingertip),
            body_xpos(data, self.target),
        );
        [f[0] - t[0], f[1] - t[1], f[2] - t[2]]
    }
}

impl Task for Reacher {
    const NAME: &'static str = "Reacher";
    const TRACK: TrackView = TrackView {
        body: 0,
        distance: 0.9,
        azimuth: 90.0,
        elevation: -70.0,
        grid: false,
    };
    const MJCF: &'static str = include_str!("../../assets/reacher.xml");
    const SIZES: Sizes = Sizes {
        nq: 4,
        nv: 4,
        nu: 2,
        nbody: 5,
    };
    const OBS_DIM: usize = 11;
    const FRAME_SKIP: usize = 2;

    fn new(model: &Model) -> Result<Self, MujocoError> {
        Ok(Reacher {
            fingertip: model.id(ObjKind::Body, "fingertip")?,
            target: model.id(ObjKind::Body, "target")?,
        })
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        ResetNoise::Uniform {
            qpos: 0.1,
            qvel: 0.005,
        }
        .apply(rng, qpos, qvel);
        let goal = loop {
            let g = [uniform(rng, 0.2), uniform(rng, 0.2)];
            if g[0].hypot(g[1]) < 0.2 {
                break g;
            }
        };
        qpos[2..4].copy_from_slice(&goal);
        qvel[2..4].fill(0.0);
    }

    fn before_step(&self, data: &Data, _action: &[f32]) -> [f64; 3] {
        let d = self.fingertip_to_target(data);
        [-(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt(), 0.0, 0.0]
    }

    fn reward(&self, _data: &Data, ctx: &StepContext<'_>) -> (f64, bool) {
        (ctx.before[0] - sum_sq(ctx.action), false)
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        let (q, v) = (data.qpos(), data.qvel());
        let mut w = ObsWriter::new(obs);
        w.put(q[..2].iter().map(|a| a.cos()));
        w.put(q[..2].iter().map(|a| a.sin()));
        w.put(q[2..].iter().copied());
        w.put(v[..2].iter().copied());
        w.put(self.fingertip_to_target(data));
    }
}

/// Swimmer-v4: swim forward in a viscous fluid. Reward `vx − 1e-4·Σ a²` with `vx` the head's
/// x velocity over the step; never terminates. Observation (8): `qpos[2..]`, `qvel`.
/// Frame skip 4 (dt 0.04 s).
#[derive(Debug, Clone, Copy, Default)]
pub struct Swimmer;

impl Task for Swimmer {
    const NAME: &'static str = "Swimmer";
    const TRACK: TrackView = TrackView {
        distance: 3.5,
        elevation: -55.0,
        ..TrackView::SIDE
    };
    const MJCF: &'static str = include_str!("../../assets/swimmer.xml");
    const SIZES: Sizes = Sizes {
        nq: 5,
        nv: 5,
        nu: 2,
        nbody: 4,
    };
    const OBS_DIM: usize = 8;
    const FRAME_SKIP: usize = 4;

    fn new(_model: &Model) -> Result<Self, MujocoError> {
        Ok(Swimmer)
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        ResetNoise::Uniform {
            qpos: 0.1,
            qvel: 0.1,
        }
        .apply(rng, qpos, qvel);
    }

    fn before_step(&self, data: &Data, _action: &[f32]) -> [f64; 3] {
        root_x(data)
    }

    fn reward(&self, data: &Data, ctx: &StepContext<'_>) -> (f64, bool) {
        let vx = x_velocity(data.qpos()[0], ctx);
        (vx - 1e-4 * sum_sq(ctx.action), false)
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        let mut w = ObsWriter::new(obs);
        w.put(data.qpos()[2..].iter().copied());
        w.put(data.qvel().iter().copied());
    }
}

/// The reset noise of [`Hopper`] and [`Walker2d`].
const PLANAR_WALKER_NOISE: ResetNoise = ResetNoise::Uniform {
    qpos: 5e-3,
    qvel: 5e-3,
};

/// The reward and termination of [`Hopper`] and [`Walker2d`]: `vx + 1 − 1e-3·Σ a²` with `vx`
/// the root's x velocity over the step; terminal when not `healthy`.
fn planar_walker_reward(data: &Data, ctx: &StepContext<'_>, healthy: bool) -> (f64, bool) {
    let vx = x_velocity(data.qpos()[0], ctx);
    (vx + 1.0 - 1e-3 * sum_sq(ctx.action), !healthy)
}

/// The observation of [`Hopper`] and [`Walker2d`]: `qpos[1..]`, `clip(qvel, ±10)`.
fn planar_walker_obs(data: &Data, obs: &mut [f32]) {
    let mut w = ObsWriter::new(obs);
    w.put(data.qpos()[1..].iter().copied());
    w.put_clipped(data.qvel(), 10.0);
}

/// Hopper-v4: hop forward. Reward `vx + 1 − 1e-3·Σ a²`. Healthy while the torso height
/// `qpos[1] > 0.7`, its angle `|qpos[2]| < 0.2` and every entry of `qpos[2..]` and `qvel`
/// lies in (−100, 100); ends when unhealthy. Observation (11): `qpos[1..]`,
/// `clip(qvel, ±10)`. Frame skip 4 (dt 0.008 s).
#[derive(Debug, Clone, Copy, Default)]
pub struct Hopper;

impl Hopper {
    /// Whether the state is healthy (see the type's doc).
    pub fn is_healthy(data: &Data) -> bool {
        let q = data.qpos();
        let state_ok = q[2..]
            .iter()
            .chain(data.qvel())
            .all(|&x| within(x, (-100.0, 100.0)));
        state_ok && q[1] > 0.7 && within(q[2], (-0.2, 0.2))
    }
}

impl Task for Hopper {
    const NAME: &'static str = "Hopper";
    const TRACK: TrackView = TrackView::side(4.0);
    const MJCF: &'static str = include_str!("../../assets/hopper.xml");
    const SIZES: Sizes = Sizes {
        nq: 6,
        nv: 6,
        nu: 3,
        nbody: 5,
    };
    const OBS_DIM: usize = 11;
    const FRAME_SKIP: usize = 4;

    fn new(_model: &Model) -> Result<Self, MujocoError> {
        Ok(Hopper)
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        PLANAR_WALKER_NOISE.apply(rng, qpos, qvel);
    }

    fn before_step(&self, data: &Data, _action: &[f32]) -> [f64; 3] {
        root_x(data)
    }

    fn reward(&self, data: &Data, ctx: &StepContext<'_>) -> (f64, bool) {
        planar_walker_reward(data, ctx, Self::is_healthy(data))
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        planar_walker_obs(data, obs);
    }
}

/// HalfCheetah-v4: run forward. Reward `vx − 0.1·Σ a²`; never terminates. Observation (17):
/// `qpos[1..]`, `qvel`. Frame skip 5 (dt 0.05 s); reset noise uniform 0.1 on positions,
/// normal 0.1 on velocities.
#[derive(Debug, Clone, Copy, Default)]
pub struct HalfCheetah;

impl Task for HalfCheetah {
    const NAME: &'static str = "HalfCheetah";
    const TRACK: TrackView = TrackView::side(4.0);
    const MJCF: &'static str = include_str!("../../assets/half_cheetah.xml");
    const SIZES: Sizes = Sizes {
        nq: 9,
        nv: 9,
        nu: 6,
        nbody: 8,
    };
    const OBS_DIM: usize = 17;
    const FRAME_SKIP: usize = 5;

    fn new(_model: &Model) -> Result<Self, MujocoError> {
        Ok(HalfCheetah)
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        ResetNoise::UniformNormal {
            qpos: 0.1,
            qvel_std: 0.1,
        }
        .apply(rng, qpos, qvel);
    }

    fn before_step(&self, data: &Data, _action: &[f32]) -> [f64; 3] {
        root_x(data)
    }

    fn reward(&self, data: &Data, ctx: &StepContext<'_>) -> (f64, bool) {
        let vx = x_velocity(data.qpos()[0], ctx);
        (vx - 0.1 * sum_sq(ctx.action), false)
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        let mut w = ObsWriter::new(obs);
        w.put(data.qpos()[1..].iter().copied());
        w.put(data.qvel().iter().copied());
    }
}

/// Walker2d-v4: walk forward. Reward `vx + 1 − 1e-3·Σ a²`. Healthy while the torso height
/// lies in (0.8, 2.0) and its angle in (−1, 1); ends when unhealthy. Observation (17):
/// `qpos[1..]`, `clip(qvel, ±10)`. Frame skip 4 (dt 0.008 s).
#[derive(Debug, Clone, Copy, Default)]
pub struct Walker2d;

impl Walker2d {
    /// Whether the state is healthy (see the type's doc).
    pub fn is_healthy(data: &Data) -> bool {
        let q = data.qpos();
        within(q[1], (0.8, 2.0)) && within(q[2], (-1.0, 1.0))
    }
}

impl Task for Walker2d {
    const NAME: &'static str = "Walker2d";
    const TRACK: TrackView = TrackView::side(3.5);
    const MJCF: &'static str = include_str!("../../assets/walker2d.xml");
    const SIZES: Sizes = Sizes {
        nq: 9,
        nv: 9,
        nu: 6,
        nbody: 8,
    };
    const OBS_DIM: usize = 17;
    const FRAME_SKIP: usize = 4;

    fn new(_model: &Model) -> Result<Self, MujocoError> {
        Ok(Walker2d)
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        PLANAR_WALKER_NOISE.apply(rng, qpos, qvel);
    }

    fn before_step(&self, data: &Data, _action: &[f32]) -> [f64; 3] {
        root_x(data)
    }

    fn reward(&self, data: &Data, ctx: &StepContext<'_>) -> (f64, bool) {
        planar_walker_reward(data, ctx, Self::is_healthy(data))
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        planar_walker_obs(data, obs);
    }
}

/// Ant-v4 (default arguments, contact forces off): walk forward. Reward
/// `vx + 1 − 0.5·Σ a²` with `vx` the torso's x velocity over the step. Healthy while the
/// torso height `qpos[2]` lies in [0.2, 1.0]; ends when unhealthy. Observation (27):
/// `qpos[2..]`, `qvel`. Frame skip 5 (dt 0.05 s); reset noise uniform 0.1 on positions,
/// normal 0.1 on velocities.
#[derive(Debug, Clone, Copy)]
pub struct Ant {
    torso: usize,
}

impl Task for Ant {
    const NAME: &'static str = "Ant";
    const TRACK: TrackView = TrackView {
        distance: 5.0,
        elevation: -35.0,
        ..TrackView::SIDE
    };
    const MJCF: &'static str = include_str!("../../assets/ant.xml");
    const SIZES: Sizes = Sizes {
        nq: 15,
        nv: 14,
        nu: 8,
        nbody: 14,
    };
    const OBS_DIM: usize = 27;
    const FRAME_SKIP: usize = 5;

    fn new(model: &Model) -> Result<Self, MujocoError> {
        Ok(Ant {
            torso: model.id(ObjKind::Body, "torso")?,
        })
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        ResetNoise::UniformNormal {
            qpos: 0.1,
            qvel_std: 0.1,
        }
        .apply(rng, qpos, qvel);
    }

    fn before_step(&self, data: &Data, _action: &[f32]) -> [f64; 3] {
        body_xpos(data, self.torso)
    }

    fn reward(&self, data: &Data, ctx: &StepContext<'_>) -> (f64, bool) {
        let vx = x_velocity(body_xpos(data, self.torso)[0], ctx);
        let z = data.qpos()[2];
        let healthy = (0.2..=1.0).contains(&z);
        (vx + 1.0 - 0.5 * sum_sq(ctx.action), !healthy)
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        let mut w = ObsWriter::new(obs);
        w.put(data.qpos()[2..].iter().copied());
        w.put(data.qvel().iter().copied());
    }
}

/// The observation shared by Humanoid and HumanoidStandup (376 for 14 bodies, 23 dofs):
/// `qpos[2..]`, `qvel`, `cinert`, `cvel`, `qfrc_actuator`, `cfrc_ext`, world body included.
fn humanoid_obs(data: &Data, obs: &mut [f32]) {
    let mut w = ObsWriter::new(obs);
    w.put(data.qpos()[2..].iter().copied());
    w.put(data.qvel().iter().copied());
    w.put_rows(data.cinert());
    w.put_rows(data.cvel());
    w.put(data.qfrc_actuator().iter().copied());
    w.put_rows(data.cfrc_ext());
}

const HUMANOID_SIZES: Sizes = Sizes {
    nq: 24,
    nv: 23,
    nu: 17,
    nbody: 14,
};
const HUMANOID_OBS: usize = 22 + 23 + 14 * 10 + 14 * 6 + 23 + 14 * 6;
/// The reset noise of Humanoid and HumanoidStandup.
const HUMANOID_NOISE: ResetNoise = ResetNoise::Uniform {
    qpos: 1e-2,
    qvel: 1e-2,
};

/// Humanoid-v4: walk forward. Reward `1.25·vx + 5 − 0.1·Σ a²` with `vx` the x velocity of the
/// centre of mass over the step (Gymnasium v4's code computes no contact cost, whatever its
/// docs say). Healthy while the torso height `qpos[2]` lies in (1, 2); ends when unhealthy.
/// Observation (376): see [`HumanoidStandup`]. Frame skip 5 (dt 0.015 s).
#[derive(Debug, Clone, Copy, Default)]
pub struct Humanoid;

impl Task for Humanoid {
    const NAME: &'static str = "Humanoid";
    const TRACK: TrackView = TrackView::side(4.0);
    const MJCF: &'static str = include_str!("../../assets/humanoid.xml");
    const SIZES: Sizes = HUMANOID_SIZES;
    const OBS_DIM: usize = HUMANOID_OBS;
    const FRAME_SKIP: usize = 5;
    const CONTACT_FORCES: bool = true;

    fn new(_model: &Model) -> Result<Self, MujocoError> {
        Ok(Humanoid)
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        HUMANOID_NOISE.apply(rng, qpos, qvel);
    }

    fn before_step(&self, data: &Data, _action: &[f32]) -> [f64; 3] {
        mass_center(data)
    }

    fn reward(&self, data: &Data, ctx: &StepContext<'_>) -> (f64, bool) {
        let vx = x_velocity(mass_center(data)[0], ctx);
        let healthy = within(data.qpos()[2], (1.0, 2.0));
        (1.25 * vx + 5.0 - 0.1 * sum_sq(ctx.action), !healthy)
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        humanoid_obs(data, obs);
    }
}

/// HumanoidStandup-v4: stand up from lying on the back (the model's keyframe `lying`).
/// Reward `qpos[2] / timestep − 0.1·Σ a² − min(0.5e-6·Σ cfrc_ext², 10) + 1`; never terminates.
/// Observation (376): `qpos[2..]` (22), `qvel` (23), `cinert` (140), `cvel` (84),
/// `qfrc_actuator` (23), `cfrc_ext` (84). Frame skip 5 (dt 0.015 s).
#[derive(Debug, Clone, Copy, Default)]
pub struct HumanoidStandup;

impl Task for HumanoidStandup {
    const NAME: &'static str = "HumanoidStandup";
    const TRACK: TrackView = TrackView::side(4.0);
    const MJCF: &'static str = include_str!("../../assets/humanoid.xml");
    const SIZES: Sizes = HUMANOID_SIZES;
    const OBS_DIM: usize = HUMANOID_OBS;
    const FRAME_SKIP: usize = 5;
    const CONTACT_FORCES: bool = true;
    const INIT_KEY: Option<&'static str> = Some("lying");

    fn new(_model: &Model) -> Result<Self, MujocoError> {
        Ok(HumanoidStandup)
    }

    fn reset_state(&mut self, rng: &mut EnvRng, qpos: &mut [f64], qvel: &mut [f64]) {
        HUMANOID_NOISE.apply(rng, qpos, qvel);
    }

    fn reward(&self, data: &Data, ctx: &StepContext<'_>) -> (f64, bool) {
        let uph = data.qpos()[2] / data.model().timestep();
        let ctrl = 0.1 * sum_sq(ctx.action);
        let impact: f64 = data.cfrc_ext().iter().flatten().map(|f| f * f).sum::<f64>() * 0.5e-6;
        (uph - ctrl - impact.min(10.0) + 1.0, false)
    }

    fn observe(&self, data: &Data, obs: &mut [f32]) {
        humanoid_obs(data, obs);
    }
}
