//! The seven GUARD robots: their models and what the engine needs to know about them
//! (sensors, actuators, how they are placed, which bodies see and which one counts as "the
//! robot"). The models are this project's own MJCF files under `assets/guard/`.

/// How a robot's root is put at its sampled place and heading at reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Root {
    /// Slide and hinge joints inside body `robot`: the body itself is moved and turned (its
    /// joints stay at 0), as compiling the model with the body there would.
    Jointed,
    /// A free joint: its `qpos` (position and heading quaternion) is set.
    Free,
    /// A fixed base pinned at the origin: only turned.
    Fixed,
}

/// One of GUARD's robots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Robot {
    /// A sphere pushed along its heading and turned by a velocity servo (2 actions).
    Point,
    /// A three-link swimmer on the floor (2 actions).
    Swimmer,
    /// A 3-joint arm on a fixed base, without gravity; its end effector seeks 3D goals (3 actions).
    Arm3,
    /// A quadrotor driven by forces on its four rotors (4 actions); seeks 3D goals.
    Drone,
    /// A one-legged hopper whose torso slides at a fixed height (6 actions).
    Hopper,
    /// A four-legged ant on a free joint (8 actions).
    Ant,
    /// A two-legged walker whose torso slides at a fixed height (10 actions).
    Walker,
}

impl Robot {
    /// Every robot.
    pub const ALL: [Robot; 7] = [
        Robot::Point,
        Robot::Swimmer,
        Robot::Arm3,
        Robot::Drone,
        Robot::Hopper,
        Robot::Ant,
        Robot::Walker,
    ];

    /// The name in suite names (`Goal_Point`).
    pub fn name(self) -> &'static str {
        match self {
            Robot::Point => "Point",
            Robot::Swimmer => "Swimmer",
            Robot::Arm3 => "Arm3",
            Robot::Drone => "Drone",
            Robot::Hopper => "Hopper",
            Robot::Ant => "Ant",
            Robot::Walker => "Walker",
        }
    }

    /// The MJCF model (embedded text).
    pub(crate) fn mjcf(self) -> &'static str {
        match self {
            Robot::Point => include_str!("../../../assets/guard/point.xml"),
            Robot::Swimmer => include_str!("../../../assets/guard/swimmer.xml"),
            Robot::Arm3 => include_str!("../../../assets/guard/arm3.xml"),
            Robot::Drone => include_str!("../../../assets/guard/drone.xml"),
            Robot::Hopper => include_str!("../../../assets/guard/hopper.xml"),
            Robot::Ant => include_str!("../../../assets/guard/ant.xml"),
            Robot::Walker => include_str!("../../../assets/guard/walker.xml"),
        }
    }

    /// The action dimension: the actuators, or the Drone's four rotor commands.
    pub fn action_dim(self) -> usize {
        match self {
            Robot::Point | Robot::Swimmer => 2,
            Robot::Arm3 => 3,
            Robot::Drone => 4,
            Robot::Hopper => 6,
            Robot::Ant => 8,
            Robot::Walker => 10,
        }
    }

    /// Whether goals are 3D spheres in the air (Arm3, Drone) rather than floor cylinders.
    pub fn goal_3d(self) -> bool {
        matches!(self, Robot::Arm3 | Robot::Drone)
    }

    pub(crate) fn root(self) -> Root {
        match self {
            Robot::Ant => Root::Free,
            Robot::Arm3 => Root::Fixed,
            _ => Root::Jointed,
        }
    }

    /// The suffixes of the IMU sensor names (`accelerometer<suffix>` …) and of their sites.
    fn imu_suffixes(self) -> &'static [&'static str] {
        match self {
            Robot::Arm3 => &["_link_1", "_link_2", "_link_3", "_link_4", "_link_5"],
            _ => &[""],
        }
    }

    /// The touch sensors' names.
    fn touch(self) -> &'static [&'static str] {
        match self {
            Robot::Point => &[],
            Robot::Swimmer => &[
                "touch_point1",
                "touch_point2",
                "touch_point3",
                "touch_point4",
            ],
            Robot::Arm3 => &["touch_end_effector"],
            Robot::Drone => &[
                "touch_p1a",
                "touch_p1b",
                "touch_p2a",
                "touch_p2b",
                "touch_p3a",
                "touch_p3b",
                "touch_p4a",
                "touch_p4b",
            ],
            Robot::Hopper => &["touch_foot"],
            Robot::Ant => &[
                "touch_ankle_1a",
                "touch_ankle_1b",
                "touch_ankle_2a",
                "touch_ankle_2b",
                "touch_ankle_3a",
                "touch_ankle_3b",
                "touch_ankle_4a",
                "touch_ankle_4b",
            ],
            Robot::Walker => &["touch_left_foot", "touch_right_foot"],
        }
    }

    /// The observed (non-root) hinge joints.
    fn joints(self) -> &'static [&'static str] {
        match self {
            Robot::Point | Robot::Drone => &[],
            Robot::Swimmer => &["motor1_rot", "motor2_rot"],
            Robot::Arm3 => &["joint_1", "joint_2", "joint_3"],
            Robot::Hopper => &["foot", "hip_x", "hip_y", "hip_z", "leg", "thigh"],
            Robot::Ant => &[
                "ankle_1", "ankle_2", "ankle_3", "ankle_4", "hip_1", "hip_2", "hip_3", "hip_4",
            ],
            Robot::Walker => &[
                "left_foot",
                "left_hip_x",
                "left_hip_y",
                "left_hip_z",
                "left_leg",
                "right_foot",
                "right_hip_x",
                "right_hip_y",
                "right_hip_z",
                "right_leg",
            ],
        }
    }

    /// Every sensor of the model, by name: the IMU (accelerometer, velocimeter, gyro,
    /// magnetometer, 3 values each), the touch sensors and `jointpos_<j>` / `jointvel_<j>` of
    /// each observed joint (1 value each). The observation shows each `jointpos` as
    /// `(sin θ, cos θ)`.
    pub fn sensors(self) -> Vec<String> {
        let imu = self.imu_suffixes().iter().flat_map(|s| {
            ["accelerometer", "velocimeter", "gyro", "magnetometer"].map(|k| format!("{k}{s}"))
        });
        let touch = self.touch().iter().map(|t| (*t).to_owned());
        let joints = self
            .joints()
            .iter()
            .flat_map(|j| [format!("jointpos_{j}"), format!("jointvel_{j}")]);
        imu.chain(touch).chain(joints).collect()
    }

    /// The length of the robot's sensor block in the observation (`|S|`).
    pub fn sensor_obs_dim(self) -> usize {
        12 * self.imu_suffixes().len() + self.touch().len() + 3 * self.joints().len()
    }

    /// The bodies whose compass and 3D lidar the observation carries (`robot`, or Arm3's
    /// `link_1`, `link_3`, `link_5`).
    pub(crate) fn lidar_bodies(self) -> &'static [&'static str] {
        match self {
            Robot::Arm3 => &["link_1", "link_3", "link_5"],
            _ => &["robot"],
        }
    }

    /// The body whose origin is "the robot's position" in rewards (Arm3: its end effector).
    pub(crate) fn position_body(self) -> &'static str {
        match self {
            Robot::Arm3 => "link_5",
            _ => "robot",
        }
    }

    /// Components each compass keeps: 3 for the robots with 3D goals, else 2.
    pub(crate) fn compass_dim(self) -> usize {
        if self.goal_3d() {
            3
        } else {
            2
        }
    }
}
