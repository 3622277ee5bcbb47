//! Velocity kinematics of a validated joint vector: the geometric Jacobian in
//! the world (`base`) or tool frame with its manipulability, condition number
//! and singular flag ([`JointVector::jacobian`]).
//!
//! Units: linear rows in the robot's length unit, columns per rad for revolute
//! joints and per length unit for prismatic joints, whatever angle unit the
//! joint values were given in. Depends on the kinematics crate (its
//! `nalgebra` feature) and serde only.

use kinserve_kinematics::{Jacobian, JacobianFrame, Transform, VelocityMeasures};
use serde::{Deserialize, Serialize};

use crate::joints::JointVector;

/// The frame a Jacobian is expressed in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum ReferenceFrame {
    /// The world frame FK poses are given in, base transform included (the default).
    #[default]
    Base,
    /// The tool frame: the same twist in the tool's own axes.
    Tool,
}

impl ReferenceFrame {
    /// Short name as written in JSON (`base`, `tool`).
    pub fn as_str(self) -> &'static str {
        match self {
            ReferenceFrame::Base => "base",
            ReferenceFrame::Tool => "tool",
        }
    }

    /// The kinematics crate's frame.
    pub fn to_kinematics(self) -> JacobianFrame {
        match self {
            ReferenceFrame::Base => JacobianFrame::Base,
            ReferenceFrame::Tool => JacobianFrame::Tool,
        }
    }
}

/// A Jacobian evaluation: the tool pose, the Jacobian and its measures.
#[derive(Clone, Debug, PartialEq)]
pub struct JacobianAnswer {
    /// The frame the rows are expressed in.
    pub frame: ReferenceFrame,
    /// Tool pose `^world T_tool`.
    pub pose: Transform,
    /// 6 × dof geometric Jacobian of the tool point.
    pub jacobian: Jacobian,
    /// Manipulability, condition number, singular flag (see
    /// [`kinserve_kinematics::VelocityMeasures`] for the rows used with
    /// fewer than 6 joints and the singularity threshold).
    pub measures: VelocityMeasures,
}

impl JointVector<'_> {
    /// The geometric Jacobian at these joint values in `frame`, with its
    /// measures. Costs one FK with frames plus an SVD of a 6 × dof matrix.
    pub fn jacobian(&self, frame: ReferenceFrame) -> JacobianAnswer {
        let (pose, jacobian) =
            self.robot()
                .chain()
                .jacobian(self.values(), self.angle_scale(), frame.to_kinematics());
        let measures = jacobian.measures();
        JacobianAnswer {
            frame,
            pose,
            jacobian,
            measures,
        }
    }
}
