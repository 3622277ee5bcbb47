//! Inverse kinematics on the wire: `InverseKinematicsRequest` /
//! `InverseKinematicsBatchRequest` → [`IkSpec`] / [`IkBatchSpec`] (field
//! paths as REST's: `target.matrix`, `targets[2].matrix`), [`IkAnswer`] →
//! `InverseKinematicsResult`. Depends on the model, [`crate::pose`] and
//! [`crate::pb`].

use kinserve_model::{
    AngleUnit, FieldViolation, IkAnswer, IkBatchSpec, IkSpec, IkTargetSpec, ModelError,
    QuaternionSpec, Result,
};

use crate::pb;
use crate::pose::pose_to_pb;

impl TryFrom<pb::InverseKinematicsRequest> for IkSpec {
    type Error = ModelError;
    fn try_from(r: pb::InverseKinematicsRequest) -> Result<IkSpec> {
        ik_spec_from_pb(r)
    }
}

impl TryFrom<pb::InverseKinematicsBatchRequest> for IkBatchSpec {
    type Error = ModelError;
    fn try_from(r: pb::InverseKinematicsBatchRequest) -> Result<IkBatchSpec> {
        ik_batch_spec_from_pb(r)
    }
}

impl From<&IkAnswer> for pb::InverseKinematicsResult {
    fn from(a: &IkAnswer) -> Self {
        ik_result_to_pb(a)
    }
}

impl From<AngleUnit> for pb::AngleUnit {
    fn from(unit: AngleUnit) -> Self {
        angle_unit_to_pb(unit)
    }
}

fn angle_unit_from_pb(unit: i32, field: &str) -> Result<AngleUnit> {
    match pb::AngleUnit::try_from(unit) {
        Ok(pb::AngleUnit::Unspecified | pb::AngleUnit::Rad) => Ok(AngleUnit::Rad),
        Ok(pb::AngleUnit::Deg) => Ok(AngleUnit::Deg),
        Err(_) => Err(ModelError::malformed_field(
            field,
            "unknown angle unit: use ANGLE_UNIT_RAD or ANGLE_UNIT_DEG",
        )),
    }
}

/// Angle unit → proto enum.
pub fn angle_unit_to_pb(unit: AngleUnit) -> pb::AngleUnit {
    match unit {
        AngleUnit::Rad => pb::AngleUnit::Rad,
        AngleUnit::Deg => pb::AngleUnit::Deg,
    }
}

/// An IK answer as its message.
fn ik_result_to_pb(a: &IkAnswer) -> pb::InverseKinematicsResult {
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
        return Err(ModelError::invalid(v));
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
        return Err(ModelError::invalid(v));
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
