//! The Jacobian results as REST, WebSocket and the CLI return them (gRPC's
//! messages come from `kinserve-api`), built from the model's answers.
//! Depends on the model crate and `api::pose` only.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::pose::Pose;
use crate::model::{JacobianAnswer, LengthUnit, ReferenceFrame};

/// The Jacobian of one configuration and what its singular values say.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "frame": "tool", "jacobian": [[0.0, 0.0], [0.7, 0.29999999999999993], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [1.0, 1.0]],
    "manipulability": 0.0, "condition_number": null, "singular": true,
    "pose": {"matrix": [[1.0, 0.0, 0.0, 0.7], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
        "position": [0.7, 0.0, 0.0], "quaternion": {"w": 1.0, "x": 0.0, "y": 0.0, "z": 0.0}, "rpy": [0.0, 0.0, 0.0]}
}))]
pub struct JacobianItem {
    /// Frame of the rows: `base` (world frame, base transform included) or `tool`.
    pub frame: ReferenceFrame,
    /// Geometric Jacobian of the tool point: 6 rows `vx, vy, vz, ωx, ωy, ωz`,
    /// one column per movable joint. Linear rows in the robot's length unit;
    /// columns per rad (revolute) or per length unit (prismatic), whatever
    /// `angle_unit` the request used.
    pub jacobian: Vec<Vec<f64>>,
    /// Yoshikawa's `√det(J Jᵀ)` over all six rows for 6 or more joints;
    /// `√det(Jᵀ J)` over all six rows for 4 or 5 joints; over the three linear
    /// rows only for arms of up to 3 joints (`√det(J_v J_vᵀ)` for 3,
    /// `√det(J_vᵀ J_v)` for 1 or 2). Always the product of the singular
    /// values of those rows.
    pub manipulability: f64,
    /// Largest over smallest singular value of the same rows; `null` when the
    /// smallest is exactly 0.
    pub condition_number: Option<f64>,
    /// The smallest singular value of the same rows is below 1e-6 (in the
    /// Jacobian's units: length unit per rad for linear rows).
    pub singular: bool,
    /// Tool pose at these joint values.
    pub pose: Pose,
}

impl From<&JacobianAnswer> for JacobianItem {
    fn from(a: &JacobianAnswer) -> Self {
        let c = a.measures.condition_number;
        JacobianItem {
            frame: a.frame,
            jacobian: a.jacobian.rows().into(),
            manipulability: a.measures.manipulability,
            condition_number: c.is_finite().then_some(c),
            singular: a.measures.singular,
            pose: Pose::from(&a.pose),
        }
    }
}

/// `POST /v1/robots/{name}/jacobian` response and `kinserve jacobian` output.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JacobianOutput {
    /// Robot name.
    pub robot: String,
    /// Length unit of the positions and of the linear rows.
    pub length_unit: LengthUnit,
    /// The Jacobian and its measures.
    #[serde(flatten)]
    pub result: JacobianItem,
}

/// `POST /v1/robots/{name}/jacobian/batch` response.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JacobianBatchOutput {
    /// Robot name.
    pub robot: String,
    /// Length unit of the positions and of the linear rows.
    pub length_unit: LengthUnit,
    /// One result per configuration, in request order.
    pub results: Vec<JacobianItem>,
}
