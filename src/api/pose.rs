//! The pose representation returned to clients over REST, WebSocket and the
//! CLI (gRPC has its own messages in `grpc::convert`). Depends on the model
//! and kinematics crates only.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::kinematics::Transform;
use crate::model::LengthUnit;

/// Unit quaternion `w + xi + yj + zk` with `w ≥ 0`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Quaternion {
    /// Scalar part (≥ 0).
    pub w: f64,
    /// i component.
    pub x: f64,
    /// j component.
    pub y: f64,
    /// k component.
    pub z: f64,
}

/// A pose in the world frame, in the robot's length unit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({"matrix": [[0.8253356149096783, -0.5646424733950354, 0.0, 0.5986337092290526], [0.5646424733950354, 0.8253356149096783, 0.0, 0.36116295746019184], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], "position": [0.5986337092290526, 0.36116295746019184, 0.0], "quaternion": {"w": 0.955336489125606, "x": 0.0, "y": 0.0, "z": 0.2955202066613396}, "rpy": [0.0, -0.0, 0.6]}))]
pub struct Pose {
    /// Homogeneous 4×4 matrix, row-major: `[[r11,r12,r13,x],[r21,r22,r23,y],[r31,r32,r33,z],[0,0,0,1]]`.
    pub matrix: [[f64; 4]; 4],
    /// `[x, y, z]`, robot length unit.
    pub position: [f64; 3],
    /// Orientation as a unit quaternion with `w ≥ 0`.
    pub quaternion: Quaternion,
    /// `[roll, pitch, yaw]` in rad, `R = Rz(yaw)·Ry(pitch)·Rx(roll)`.
    pub rpy: [f64; 3],
}

impl From<&Transform> for Pose {
    fn from(t: &Transform) -> Self {
        let [w, x, y, z] = t.quaternion();
        Pose {
            matrix: t.matrix(),
            position: t.position(),
            quaternion: Quaternion { w, x, y, z },
            rpy: t.rpy(),
        }
    }
}

impl Pose {
    /// The rigid transform this pose describes (from its matrix).
    pub fn transform(&self) -> Transform {
        Transform::from_matrix(&self.matrix)
    }
}

/// Result of one FK evaluation, as REST and the CLI return it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({"robot": "planar_2dof", "length_unit": "m", "pose": {"matrix": [[0.8253356149096783, -0.5646424733950354, 0.0, 0.5986337092290526], [0.5646424733950354, 0.8253356149096783, 0.0, 0.36116295746019184], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], "position": [0.5986337092290526, 0.36116295746019184, 0.0], "quaternion": {"w": 0.955336489125606, "x": 0.0, "y": 0.0, "z": 0.2955202066613396}, "rpy": [0.0, -0.0, 0.6]}}))]
pub struct FkOutput {
    /// Robot name.
    pub robot: String,
    /// Length unit of every position in this result.
    pub length_unit: LengthUnit,
    /// Tool pose `^world T_tool`, in the request's `pose_format` (over REST;
    /// the CLI always gives the full object).
    #[schema(value_type = crate::api::pose_format::PoseValue)]
    pub pose: Pose,
    /// Only when asked for: `^world T_i` for `i = 0..=rows` (0 = base frame,
    /// last = flange), in the same format as `pose`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<crate::api::pose_format::PoseValue>>)]
    pub frames: Option<Vec<Pose>>,
}
