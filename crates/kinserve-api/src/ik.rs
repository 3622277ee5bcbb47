//! Inverse kinematics on the wire: `InverseKinematicsRequest` /
//! `InverseKinematicsBatchRequest` → [`IkSpec`] / [`IkBatchSpec`] (field
//! paths as REST's: `target.matrix`, `targets[2].matrix`), [`IkAnswer`] →
//! `InverseKinematicsResult`. Depends on the model, [`crate::pose`] and
//! [`crate::pb`].

use kinserve_model::{
    AngleUnit, AxisTolerancesSpec, FieldViolation, IkAnswer, IkBatchSpec, IkBranch, IkPathAnswer,
    IkPathSpec, IkSolutionItem, IkSolutionsMode, IkSolverChoice, IkSolverUsed, IkSpec,
    IkTargetSpec, ModelError, PathStopReason, PoseAxis, PostureSpec, QuaternionSpec, Result,
    Singularity,
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

impl TryFrom<pb::InverseKinematicsPathRequest> for IkPathSpec {
    type Error = ModelError;
    fn try_from(r: pb::InverseKinematicsPathRequest) -> Result<IkPathSpec> {
        ik_path_spec_from_pb(r)
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
        solver: solver_used_to_pb(a.solver) as i32,
        branch: a.branch.map(branch_to_pb),
        singular: singular_to_pb(&a.singular),
        solutions: a.solutions.iter().flatten().map(solution_to_pb).collect(),
        truncated: a.solutions.is_some().then_some(a.truncated),
    }
}

fn solver_used_to_pb(s: IkSolverUsed) -> pb::IkSolver {
    match s {
        IkSolverUsed::Analytic => pb::IkSolver::Analytic,
        IkSolverUsed::Numeric => pb::IkSolver::Numeric,
    }
}

fn branch_to_pb(b: IkBranch) -> pb::IkBranch {
    pb::IkBranch {
        shoulder: b.shoulder.into(),
        elbow: b.elbow.into(),
        wrist: b.wrist.into(),
    }
}

fn singular_to_pb(s: &[Singularity]) -> Vec<i32> {
    s.iter()
        .map(|x| match x {
            Singularity::Shoulder => pb::Singularity::Shoulder as i32,
            Singularity::Wrist => pb::Singularity::Wrist as i32,
        })
        .collect()
}

fn solution_to_pb(s: &IkSolutionItem) -> pb::IkSolution {
    pb::IkSolution {
        joints: s.joints.clone(),
        branch: s.branch.map(branch_to_pb),
        singular: singular_to_pb(&s.singular),
        distance: s.distance,
        position_error: s.position_error,
        orientation_error: s.orientation_error,
    }
}

fn solver_from_pb(v: i32) -> Result<IkSolverChoice> {
    match pb::IkSolver::try_from(v) {
        Ok(pb::IkSolver::Unspecified | pb::IkSolver::Auto) => Ok(IkSolverChoice::Auto),
        Ok(pb::IkSolver::Analytic) => Ok(IkSolverChoice::Analytic),
        Ok(pb::IkSolver::Numeric) => Ok(IkSolverChoice::Numeric),
        Err(_) => Err(ModelError::malformed_field(
            "solver",
            "unknown solver: use IK_SOLVER_AUTO, IK_SOLVER_ANALYTIC or IK_SOLVER_NUMERIC",
        )),
    }
}

fn solutions_from_pb(v: i32) -> Result<IkSolutionsMode> {
    match pb::IkSolutions::try_from(v) {
        Ok(pb::IkSolutions::Unspecified | pb::IkSolutions::Best) => Ok(IkSolutionsMode::Best),
        Ok(pb::IkSolutions::All) => Ok(IkSolutionsMode::All),
        Err(_) => Err(ModelError::malformed_field(
            "solutions",
            "unknown solutions: use IK_SOLUTIONS_BEST or IK_SOLUTIONS_ALL",
        )),
    }
}

/// The objective fields of a proto IK request → the model's (`free_axes[i]`
/// names an unknown axis).
type Objectives = (
    Option<PostureSpec>,
    Option<AxisTolerancesSpec>,
    Vec<PoseAxis>,
);

fn objectives_from_pb(
    posture: Option<pb::IkPosture>,
    axes: Option<pb::AxisTolerances>,
    free: &[i32],
) -> Result<Objectives> {
    let posture = posture.map(|p| PostureSpec {
        joints: p.joints,
        weights: (!p.weights.is_empty()).then_some(p.weights),
    });
    let axes = axes.map(|a| AxisTolerancesSpec {
        x: a.x,
        y: a.y,
        z: a.z,
        rx: a.rx,
        ry: a.ry,
        rz: a.rz,
    });
    let free = free
        .iter()
        .enumerate()
        .map(|(i, v)| match pb::PoseAxis::try_from(*v) {
            Ok(pb::PoseAxis::X) => Ok(PoseAxis::X),
            Ok(pb::PoseAxis::Y) => Ok(PoseAxis::Y),
            Ok(pb::PoseAxis::Z) => Ok(PoseAxis::Z),
            Ok(pb::PoseAxis::Rx) => Ok(PoseAxis::Rx),
            Ok(pb::PoseAxis::Ry) => Ok(PoseAxis::Ry),
            Ok(pb::PoseAxis::Rz) => Ok(PoseAxis::Rz),
            Ok(pb::PoseAxis::Unspecified) | Err(_) => Err(ModelError::malformed_field(
                format!("free_axes[{i}]"),
                "unknown axis: use POSE_AXIS_X, _Y, _Z, _RX, _RY or _RZ",
            )),
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((posture, axes, free))
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
    let (posture, axis_tolerances, free_axes) =
        objectives_from_pb(r.posture, r.axis_tolerances, &r.free_axes)?;
    Ok(IkSpec {
        target,
        seed: r.seed.map(|s| s.joints),
        angle_unit: angle_unit_from_pb(r.angle_unit, "angle_unit")?,
        position_only: r.position_only,
        tolerance: r.tolerance,
        max_iterations: r.max_iterations,
        restarts: r.restarts,
        solver: solver_from_pb(r.solver)?,
        solutions: solutions_from_pb(r.solutions)?,
        max_solutions: r.max_solutions,
        posture,
        axis_tolerances,
        free_axes,
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
    let (posture, axis_tolerances, free_axes) =
        objectives_from_pb(r.posture, r.axis_tolerances, &r.free_axes)?;
    Ok(IkBatchSpec {
        targets,
        seed: r.seed.map(|s| s.joints),
        angle_unit: angle_unit_from_pb(r.angle_unit, "angle_unit")?,
        position_only: r.position_only,
        tolerance: r.tolerance,
        max_iterations: r.max_iterations,
        restarts: r.restarts,
        solver: solver_from_pb(r.solver)?,
        solutions: solutions_from_pb(r.solutions)?,
        max_solutions: r.max_solutions,
        posture,
        axis_tolerances,
        free_axes,
    })
}

/// `InverseKinematicsPathRequest` → the REST body it means.
pub fn ik_path_spec_from_pb(r: pb::InverseKinematicsPathRequest) -> Result<IkPathSpec> {
    let mut v = Vec::new();
    let waypoints = r
        .waypoints
        .into_iter()
        .enumerate()
        .map(|(i, t)| target_from_pb(Some(t), &format!("waypoints[{i}]"), &mut v))
        .collect();
    if !v.is_empty() {
        return Err(ModelError::invalid(v));
    }
    let (posture, axis_tolerances, free_axes) =
        objectives_from_pb(r.posture, r.axis_tolerances, &r.free_axes)?;
    Ok(IkPathSpec {
        start: r.start.map(|s| s.joints).unwrap_or_default(),
        waypoints,
        angle_unit: angle_unit_from_pb(r.angle_unit, "angle_unit")?,
        position_only: r.position_only,
        max_step_length: r.max_step_length,
        max_step_angle: r.max_step_angle,
        max_joint_step: r.max_joint_step,
        tolerance: r.tolerance,
        solver: solver_from_pb(r.solver)?,
        max_iterations: r.max_iterations,
        restarts: r.restarts,
        posture,
        axis_tolerances,
        free_axes,
    })
}

/// A path answer's points, fraction and stop as the response's fields.
pub fn ik_path_to_pb(
    a: &IkPathAnswer,
    robot: String,
    length_unit: i32,
    angle_unit: AngleUnit,
) -> pb::InverseKinematicsPathResponse {
    pb::InverseKinematicsPathResponse {
        robot,
        length_unit,
        angle_unit: angle_unit_to_pb(angle_unit) as i32,
        points: a
            .points
            .iter()
            .map(|q| pb::JointConfiguration { joints: q.clone() })
            .collect(),
        fraction: a.fraction,
        waypoints_reached: a.waypoints_reached as u32,
        stop: a.stop.as_ref().map(|s| pb::PathStop {
            step: s.step as u32,
            waypoint: s.waypoint as u32,
            reason: match s.reason {
                PathStopReason::Unreachable => pb::PathStopReason::Unreachable,
                PathStopReason::JointLimits => pb::PathStopReason::JointLimits,
                PathStopReason::JointJump => pb::PathStopReason::JointJump,
                PathStopReason::Singularity => pb::PathStopReason::Singularity,
                PathStopReason::TimeLimit => pb::PathStopReason::TimeLimit,
            } as i32,
            detail: s.detail.clone(),
        }),
    }
}
