//! gRPC side of velocity and inverse kinematics: conversions between the
//! `Jacobian*` / `InverseKinematics*` messages and the model's requests and
//! answers, with the same field paths as REST (`target.matrix[3]`, `seed[2]`,
//! `tolerance`), and the calls themselves (`GrpcService::jacobian_one`,
//! `ik_one`, …) used by the unary RPCs and the stream. Depends on the service,
//! the model and `grpc::convert`; nothing here is REST.

use std::sync::Arc;

use super::convert::{length_unit_to_pb, options_from_pb, pose_to_pb};
use super::{GrpcService, pb};
use crate::error::{Error, FieldViolation, Result};
use crate::model::{
    AngleUnit, IkAnswer, IkBatchSpec, IkSpec, IkTargetSpec, JacobianAnswer, QuaternionSpec,
    ReferenceFrame,
};
use crate::registry::Entry;
use crate::service::Configurations;
use crate::telemetry::Protocol;

/// Proto frame → model frame (unspecified: base).
pub fn frame_from_pb(frame: i32, field: &str) -> Result<ReferenceFrame> {
    match pb::JacobianFrame::try_from(frame) {
        Ok(pb::JacobianFrame::Unspecified | pb::JacobianFrame::Base) => Ok(ReferenceFrame::Base),
        Ok(pb::JacobianFrame::Tool) => Ok(ReferenceFrame::Tool),
        Err(_) => Err(Error::malformed_field(
            field,
            "unknown frame: use JACOBIAN_FRAME_BASE or JACOBIAN_FRAME_TOOL",
        )),
    }
}

fn frame_to_pb(frame: ReferenceFrame) -> pb::JacobianFrame {
    match frame {
        ReferenceFrame::Base => pb::JacobianFrame::Base,
        ReferenceFrame::Tool => pb::JacobianFrame::Tool,
    }
}

fn angle_unit_from_pb(unit: i32, field: &str) -> Result<AngleUnit> {
    match pb::AngleUnit::try_from(unit) {
        Ok(pb::AngleUnit::Unspecified | pb::AngleUnit::Rad) => Ok(AngleUnit::Rad),
        Ok(pb::AngleUnit::Deg) => Ok(AngleUnit::Deg),
        Err(_) => Err(Error::malformed_field(
            field,
            "unknown angle unit: use ANGLE_UNIT_RAD or ANGLE_UNIT_DEG",
        )),
    }
}

fn angle_unit_to_pb(unit: AngleUnit) -> pb::AngleUnit {
    match unit {
        AngleUnit::Rad => pb::AngleUnit::Rad,
        AngleUnit::Deg => pb::AngleUnit::Deg,
    }
}

/// A Jacobian answer as its message (6 × n values, row-major).
pub fn jacobian_to_pb(a: &JacobianAnswer) -> pb::JacobianResult {
    let c = a.measures.condition_number;
    pb::JacobianResult {
        frame: frame_to_pb(a.frame) as i32,
        columns: a.jacobian.dof() as u32,
        values: a.jacobian.rows().into_iter().flatten().collect(),
        manipulability: a.measures.manipulability,
        condition_number: c.is_finite().then_some(c),
        singular: a.measures.singular,
        pose: Some(pose_to_pb(&a.pose)),
    }
}

/// An IK answer as its message.
pub fn ik_result_to_pb(a: &IkAnswer) -> pb::InverseKinematicsResult {
    pb::InverseKinematicsResult {
        joints: a.joints.clone(),
        converged: a.converged,
        position_error: a.position_error,
        orientation_error: a.orientation_error,
        iterations: a.iterations,
        pose: Some(pose_to_pb(&a.pose)),
    }
}

/// A proto target → the model's target spec (shape errors under `field`).
fn target_from_pb(
    t: Option<pb::IkTarget>,
    field: &str,
    v: &mut Vec<FieldViolation>,
) -> IkTargetSpec {
    let Some(t) = t else {
        return IkTargetSpec::default();
    };
    let matrix = t.matrix.and_then(|m| {
        let mut out = [[0.0; 4]; 4];
        if m.values.len() != 16 {
            v.push(FieldViolation::new(
                format!("{field}.matrix"),
                format!(
                    "must hold 16 values (row-major 4x4), got {}",
                    m.values.len()
                ),
            ));
            return None;
        }
        for (slot, x) in out.iter_mut().flatten().zip(&m.values) {
            *slot = *x;
        }
        Some(out)
    });
    IkTargetSpec {
        matrix,
        position: t.position.map(|p| [p.x, p.y, p.z]),
        quaternion: t.quaternion.map(|q| QuaternionSpec {
            w: q.w,
            x: q.x,
            y: q.y,
            z: q.z,
        }),
    }
}

/// `InverseKinematicsRequest` → the REST body it means.
pub fn ik_spec_from_pb(r: pb::InverseKinematicsRequest) -> Result<IkSpec> {
    let mut v = Vec::new();
    let target = target_from_pb(r.target, "target", &mut v);
    if !v.is_empty() {
        return Err(Error::invalid(v));
    }
    Ok(IkSpec {
        target,
        seed: r.seed.map(|s| s.joints),
        angle_unit: angle_unit_from_pb(r.angle_unit, "angle_unit")?,
        position_only: r.position_only,
        tolerance: r.tolerance,
        max_iterations: r.max_iterations,
        restarts: r.restarts,
    })
}

/// `InverseKinematicsBatchRequest` → the REST body it means.
pub fn ik_batch_spec_from_pb(r: pb::InverseKinematicsBatchRequest) -> Result<IkBatchSpec> {
    let mut v = Vec::new();
    let targets = r
        .targets
        .into_iter()
        .enumerate()
        .map(|(i, t)| target_from_pb(Some(t), &format!("targets[{i}]"), &mut v))
        .collect();
    if !v.is_empty() {
        return Err(Error::invalid(v));
    }
    Ok(IkBatchSpec {
        targets,
        seed: r.seed.map(|s| s.joints),
        angle_unit: angle_unit_from_pb(r.angle_unit, "angle_unit")?,
        position_only: r.position_only,
        tolerance: r.tolerance,
        max_iterations: r.max_iterations,
        restarts: r.restarts,
    })
}

impl GrpcService {
    /// The Jacobian of one configuration (unary call and stream).
    pub(super) fn jacobian_one(
        &self,
        entry: &Entry,
        joints: &[f64],
        options: Option<&pb::FkOptions>,
        frame: i32,
        frame_field: &str,
    ) -> Result<pb::JacobianResult> {
        let frame = frame_from_pb(frame, frame_field)?;
        let (opts, _) = options_from_pb(options)?;
        let a = self.service.jacobian(&entry.robot, joints, &opts, frame)?;
        entry.count_poses(Protocol::Grpc, 1);
        Ok(jacobian_to_pb(&a))
    }

    /// `JacobianBatch`.
    pub(super) fn jacobian_batch_call(
        &self,
        req: pb::JacobianBatchRequest,
    ) -> Result<pb::JacobianBatchResponse> {
        self.service.check_batch_size(req.configurations.len())?;
        let entry = self.service.robot_at(&req.robot, "robot")?;
        let frame = frame_from_pb(req.frame, "frame")?;
        let (opts, _) = options_from_pb(req.options.as_ref())?;
        let mut configs = Configurations::default();
        for c in &req.configurations {
            configs.push(&c.joints);
        }
        let answers = self
            .service
            .jacobian_batch(&entry.robot, &configs, &opts, frame)?;
        entry.count_poses(Protocol::Grpc, answers.len() as u64);
        Ok(pb::JacobianBatchResponse {
            robot: req.robot,
            length_unit: length_unit_to_pb(entry.robot.length_unit()) as i32,
            results: answers.iter().map(jacobian_to_pb).collect(),
        })
    }

    /// One IK request (unary call and stream), on the blocking pool.
    pub(super) async fn ik_one(
        &self,
        entry: Arc<Entry>,
        req: pb::InverseKinematicsRequest,
    ) -> Result<(pb::InverseKinematicsResult, AngleUnit)> {
        let spec = ik_spec_from_pb(req)?;
        let unit = spec.angle_unit;
        let answer = self.service.ik_blocking(entry, spec).await?;
        Ok((ik_result_to_pb(&answer), unit))
    }

    /// `InverseKinematicsBatch`, on the blocking pool.
    pub(super) async fn ik_batch_call(
        &self,
        req: pb::InverseKinematicsBatchRequest,
    ) -> Result<pb::InverseKinematicsBatchResponse> {
        let robot = req.robot.clone();
        let entry = self.service.robot_at(&robot, "robot")?;
        let spec = ik_batch_spec_from_pb(req)?;
        let unit = spec.angle_unit;
        let answers = self.service.ik_batch_blocking(entry.clone(), spec).await?;
        Ok(pb::InverseKinematicsBatchResponse {
            robot,
            length_unit: length_unit_to_pb(entry.robot.length_unit()) as i32,
            angle_unit: angle_unit_to_pb(unit) as i32,
            results: answers.iter().map(ik_result_to_pb).collect(),
        })
    }

    /// `InverseKinematics`.
    pub(super) async fn ik_call(
        &self,
        req: pb::InverseKinematicsRequest,
    ) -> Result<pb::InverseKinematicsResponse> {
        let robot = req.robot.clone();
        let entry = self.service.robot_at(&robot, "robot")?;
        let unit_pb = length_unit_to_pb(entry.robot.length_unit());
        let (result, unit) = self.ik_one(entry, req).await?;
        Ok(pb::InverseKinematicsResponse {
            robot,
            length_unit: unit_pb as i32,
            angle_unit: angle_unit_to_pb(unit) as i32,
            result: Some(result),
        })
    }

    /// `Jacobian`.
    pub(super) fn jacobian_call(&self, req: pb::JacobianRequest) -> Result<pb::JacobianResponse> {
        let entry = self.service.robot_at(&req.robot, "robot")?;
        let result = self.jacobian_one(
            &entry,
            &req.joints,
            req.options.as_ref(),
            req.frame,
            "frame",
        )?;
        Ok(pb::JacobianResponse {
            robot: req.robot,
            length_unit: length_unit_to_pb(entry.robot.length_unit()) as i32,
            result: Some(result),
        })
    }
}
