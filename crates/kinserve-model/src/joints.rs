//! Validated joint vectors: made only by [`Robot::check_joints`] and
//! [`Robot::check_batch`], and the only input a robot's FK accepts.

use kinserve_kinematics::Transform;

use crate::robot::Robot;

/// One joint vector that passed [`Robot::check_joints`] for its robot: right
/// length, finite, within limits when they were checked. Revolute values are
/// in the request's angle unit (the scale to rad is carried along),
/// prismatic ones in the model's length unit.
#[derive(Clone, Copy, Debug)]
pub struct JointVector<'a> {
    robot: &'a Robot,
    q: &'a [f64],
    angle_scale: f64,
}

impl<'a> JointVector<'a> {
    pub(crate) fn new(robot: &'a Robot, q: &'a [f64], angle_scale: f64) -> Self {
        Self {
            robot,
            q,
            angle_scale,
        }
    }

    /// The values as given.
    pub fn values(&self) -> &'a [f64] {
        self.q
    }

    /// The robot they were checked for.
    pub fn robot(&self) -> &'a Robot {
        self.robot
    }

    /// Factor from the values' angle unit to rad (1 for rad, π/180 for deg).
    pub fn angle_scale(&self) -> f64 {
        self.angle_scale
    }

    /// World pose of the tool tip, `base · A_1 ⋯ A_n · tool`. Allocates nothing.
    pub fn fk(&self) -> Transform {
        self.robot.chain().forward(self.q, self.angle_scale)
    }

    /// The tool pose and every frame: `frames[0]` is the base frame
    /// `^world T_0`, `frames[i]` the frame after DH row `i` (the last is the
    /// flange).
    pub fn fk_frames(&self) -> (Transform, Vec<Transform>) {
        self.robot.chain().forward_frames(self.q, self.angle_scale)
    }

    /// The tool pose, and every frame when `frames` is set: the one single-FK
    /// entry point that every front door and the CLI call.
    pub fn fk_with_frames(&self, frames: bool) -> (Transform, Option<Vec<Transform>>) {
        if frames {
            let (tool, all) = self.fk_frames();
            (tool, Some(all))
        } else {
            (self.fk(), None)
        }
    }
}

/// Many configurations that all passed [`Robot::check_batch`], back to back.
#[derive(Clone, Copy, Debug)]
pub struct JointBatch<'a> {
    robot: &'a Robot,
    values: &'a [f64],
    count: usize,
    angle_scale: f64,
}

impl<'a> JointBatch<'a> {
    pub(crate) fn new(robot: &'a Robot, values: &'a [f64], count: usize, angle_scale: f64) -> Self {
        Self {
            robot,
            values,
            count,
            angle_scale,
        }
    }

    /// Number of configurations.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Tool poses into `out` (one per configuration, up to `out.len()`), by
    /// the vectorised batch path. Allocates nothing.
    pub fn fk_into(&self, out: &mut [Transform]) {
        self.robot
            .chain()
            .forward_batch(self.values, self.angle_scale, out);
    }

    /// Each configuration as the joint vector it was checked as, in order
    /// (each was validated once, by [`Robot::check_batch`]).
    pub fn vectors(&self) -> impl ExactSizeIterator<Item = JointVector<'a>> + 'a {
        let (robot, scale, values) = (self.robot, self.angle_scale, self.values);
        let dof = robot.dof();
        (0..self.count).map(move |i| {
            let q = values.get(i * dof..(i + 1) * dof).unwrap_or(&[]);
            JointVector::new(robot, q, scale)
        })
    }

    /// Tool poses, in order.
    pub fn fk(&self) -> Vec<Transform> {
        let mut out = vec![Transform::IDENTITY; self.count];
        self.fk_into(&mut out);
        out
    }
}
