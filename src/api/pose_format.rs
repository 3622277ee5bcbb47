//! Compact pose formats (`pose_format`), the same on every front door: `full`
//! (the default: the [`Pose`] object), `matrix` (12 numbers: the top three
//! rows of the homogeneous matrix, row-major) or `position` (`[x, y, z]`).
//!
//! The compact formats are written straight from the [`Transform`]: no
//! quaternion or roll-pitch-yaw is computed and nothing is allocated per pose
//! (JSON numbers are written by serde_json's shortest round-trip formatter;
//! gRPC gets one pre-sized `Vec<f64>` per reply). Depends on the kinematics
//! crate and [`crate::api::pose`] only.

use serde::ser::SerializeSeq;
use serde::{Serialize, Serializer};
use utoipa::ToSchema;

use crate::api::pose::Pose;
use crate::kinematics::Transform;

pub use crate::model::{PoseFormat, matrix12};

/// One pose, serialised in a format: the [`Pose`] object for `full`, a flat
/// array of numbers otherwise.
#[derive(Clone, Copy, Debug)]
pub struct FormattedPose {
    /// The format.
    pub format: PoseFormat,
    /// The pose.
    pub pose: Transform,
}

impl FormattedPose {
    /// `pose` in `format`.
    pub fn new(format: PoseFormat, pose: Transform) -> FormattedPose {
        FormattedPose { format, pose }
    }
}

impl Serialize for FormattedPose {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        serialize_pose(self.format, &self.pose, s)
    }
}

fn serialize_pose<S: Serializer>(
    format: PoseFormat,
    t: &Transform,
    s: S,
) -> Result<S::Ok, S::Error> {
    match format {
        PoseFormat::Full => Pose::from(t).serialize(s),
        PoseFormat::Matrix => matrix12(t).serialize(s),
        PoseFormat::Position => t.translation.serialize(s),
    }
}

/// Many poses, serialised in a format as an array, without building them in
/// memory first.
#[derive(Clone, Copy, Debug)]
pub struct FormattedPoses<'a> {
    /// The format.
    pub format: PoseFormat,
    /// The poses.
    pub poses: &'a [Transform],
}

impl Serialize for FormattedPoses<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut seq = s.serialize_seq(Some(self.poses.len()))?;
        for t in self.poses {
            seq.serialize_element(&FormattedPose::new(self.format, *t))?;
        }
        seq.end()
    }
}

/// A pose in `"pose_format": "matrix"`: the top three rows of the
/// homogeneous matrix, row-major (`[r11, r12, r13, x, r21, r22, r23, y, r31,
/// r32, r33, z]`). Documentation only.
#[derive(Serialize, ToSchema)]
#[schema(min_items = 12, max_items = 12, example = json!([0.8253356149096783, -0.5646424733950354, 0.0, 0.5986337092290526, 0.5646424733950354, 0.8253356149096783, 0.0, 0.36116295746019184, 0.0, 0.0, 1.0, 0.0]))]
pub struct PoseMatrix(pub Vec<f64>);

/// A pose in `"pose_format": "position"`: `[x, y, z]` in the robot's length
/// unit. Documentation only.
#[derive(Serialize, ToSchema)]
#[schema(min_items = 3, max_items = 3, example = json!([0.5986337092290526, 0.36116295746019184, 0.0]))]
pub struct PosePosition(pub Vec<f64>);

/// A pose in the format the request asked for (`pose_format`): the [`Pose`]
/// object (`full`, the default), 12 numbers (`matrix`) or 3 (`position`).
/// Documentation only.
#[derive(Serialize, ToSchema)]
#[serde(untagged)]
pub enum PoseValue {
    /// `full`.
    Full(Pose),
    /// `matrix`.
    Matrix(PoseMatrix),
    /// `position`.
    Position(PosePosition),
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Transform {
        Transform::rot_z(0.6).compose(&Transform::translation(0.3, -0.2, 0.1))
    }

    #[test]
    fn matrix12_is_the_top_of_matrix_bit_for_bit() {
        let t = sample();
        let full: Vec<f64> = t.matrix().iter().flatten().copied().take(12).collect();
        assert_eq!(
            matrix12(&t).map(f64::to_bits).to_vec(),
            full.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }

    #[test]
    fn compact_json_is_a_flat_array_and_full_is_the_pose_object() {
        let t = sample();
        let json = |f| serde_json::to_value(FormattedPose::new(f, t)).unwrap();
        assert_eq!(
            json(PoseFormat::Full),
            serde_json::to_value(Pose::from(&t)).unwrap()
        );
        assert_eq!(json(PoseFormat::Matrix).as_array().unwrap().len(), 12);
        assert_eq!(json(PoseFormat::Position), serde_json::json!(t.translation));
        let packed = PoseFormat::Matrix.pack([t, t].iter());
        assert_eq!(packed.len(), 24);
        assert!(PoseFormat::Full.pack([t].iter()).is_empty());
    }
}
