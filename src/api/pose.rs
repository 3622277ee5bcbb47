//! The pose representations returned to clients over REST, WebSocket and the
//! CLI (gRPC has its own messages in `grpc::convert`): the full [`Pose`]
//! object, and the compact ones ([`PoseMatrix`], [`PosePosition`]) as the
//! OpenAPI document names them. Depends on the model and kinematics crates
//! only (not on [`crate::api::pose_format`], which writes answers in these
//! shapes straight from the transforms).

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

/// A pose in `"pose_format": "matrix"`: the top three rows of the
/// homogeneous matrix, row-major (`[r11, r12, r13, x, r21, r22, r23, y, r31,
/// r32, r33, z]`), the same numbers as the first 12 of the full pose's
/// `matrix`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(min_items = 12, max_items = 12, example = json!([0.8253356149096783, -0.5646424733950354, 0.0, 0.5986337092290526, 0.5646424733950354, 0.8253356149096783, 0.0, 0.36116295746019184, 0.0, 0.0, 1.0, 0.0]))]
pub struct PoseMatrix(pub [f64; 12]);

/// A pose in `"pose_format": "position"`: `[x, y, z]` in the robot's
/// length unit, the full pose's `position`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(min_items = 3, max_items = 3, example = json!([0.5986337092290526, 0.36116295746019184, 0.0]))]
pub struct PosePosition(pub [f64; 3]);

/// Several poses in `"pose_format": "matrix"`, each a `PoseMatrix` (12
/// numbers).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!([[0.8253356149096783, -0.5646424733950354, 0.0, 0.5986337092290526, 0.5646424733950354, 0.8253356149096783, 0.0, 0.36116295746019184, 0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.7, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]]))]
pub struct PoseMatrices(pub Vec<PoseMatrix>);

/// Several poses in `"pose_format": "position"`, each a `PosePosition`
/// (`[x, y, z]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!([[0.5986337092290526, 0.36116295746019184, 0.0], [0.7, 0.0, 0.0]]))]
pub struct PosePositions(pub Vec<PosePosition>);

/// Result of one FK evaluation, as REST and the CLI return it. Each pose
/// comes in exactly one field, chosen by the request's `pose_format`: `pose`
/// and `frames` (`full`, the default, and always from the CLI), `matrix` and
/// `frame_matrices` (`matrix`) or `position` and `frame_positions`
/// (`position`). The frame fields are present only with `"frames": true`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({"robot": "planar_2dof", "length_unit": "m", "pose": {"matrix": [[0.8253356149096783, -0.5646424733950354, 0.0, 0.5986337092290526], [0.5646424733950354, 0.8253356149096783, 0.0, 0.36116295746019184], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], "position": [0.5986337092290526, 0.36116295746019184, 0.0], "quaternion": {"w": 0.955336489125606, "x": 0.0, "y": 0.0, "z": 0.2955202066613396}, "rpy": [0.0, -0.0, 0.6]}}))]
pub struct FkOutput {
    /// Robot name.
    pub robot: String,
    /// Length unit of every position in this result.
    pub length_unit: LengthUnit,
    /// Tool pose `^world T_tool` as the full pose object. Present when
    /// `pose_format` is `full` (the default); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Pose)]
    pub pose: Option<Pose>,
    /// Tool pose as 12 numbers. Present only when `pose_format` is `matrix`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PoseMatrix)]
    pub matrix: Option<PoseMatrix>,
    /// Tool position `[x, y, z]`. Present only when `pose_format` is
    /// `position`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PosePosition)]
    pub position: Option<PosePosition>,
    /// `^world T_i` for `i = 0..=rows` (0 = base frame, last = flange) as full
    /// pose objects. Present when `"frames": true` and `pose_format` is `full`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Vec<Pose>)]
    pub frames: Option<Vec<Pose>>,
    /// The frames (as `frames`) as 12 numbers each. Present only when
    /// `"frames": true` and `pose_format` is `matrix`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PoseMatrices)]
    pub frame_matrices: Option<PoseMatrices>,
    /// The frames' positions (as `frames`), `[x, y, z]` each. Present only
    /// when `"frames": true` and `pose_format` is `position`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PosePositions)]
    pub frame_positions: Option<PosePositions>,
}
