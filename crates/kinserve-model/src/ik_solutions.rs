//! How an IK request is solved and how much it answers: the solver asked for
//! ([`IkSolverChoice`]: `auto`, `analytic`, `numeric`), how many solutions
//! ([`IkSolutionsMode`]: `best` or `all`), the solver that ran
//! ([`IkSolverUsed`]), and each analytic solution as answered
//! ([`IkSolutionItem`]: joints, branch, singularity flags, distance to the
//! reference, errors). [`analytic_solutions`] solves one oriented target with
//! the robot's closed form (classified once, at registration: see
//! [`Robot::analytic_ik`]) and gives the solutions in the request's units.
//!
//! Units: joints in the request's angle unit (revolute; the closed forms are
//! for 6R arms only), `distance` and `orientation_error` in rad,
//! `position_error` in the robot's length unit. Depends on the kinematics
//! crate (`analytic_ik`, `ik::rotation_error`), serde and the robot module;
//! must not depend on the `ik` module (which uses this one).

use kinserve_kinematics::Transform;
use kinserve_kinematics::analytic_ik::{AnalyticIk, AnalyticOptions, AnalyticSolution};
use kinserve_kinematics::ik::rotation_error;
use serde::{Deserialize, Serialize};

use crate::robot::Robot;
use crate::spec::AngleUnit;

/// Default `max_solutions` of `solutions: "all"`.
pub const IK_DEFAULT_MAX_SOLUTIONS: u32 = 64;
/// Largest `max_solutions` accepted.
pub const IK_MAX_SOLUTIONS: u32 = 1024;
/// Most solutions one batch with `solutions: "all"` may answer in all
/// (`targets × max_solutions`); past it the batch is refused before solving.
pub const IK_MAX_BATCH_SOLUTIONS: u64 = 100_000;

/// Which solver a request asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum IkSolverChoice {
    /// The closed form where the arm has one (6R arms of the classes in
    /// `GET /v1/robots/{name}`'s `ik_class`) and the target has an
    /// orientation, else the numeric solver; also numeric when the closed
    /// form finds no solution inside the limits (the best attempt is then
    /// numeric's).
    #[default]
    Auto,
    /// The closed form only: refused (422 on `solver`) for arms without one
    /// or position-only targets.
    Analytic,
    /// Damped least squares with restarts, for every arm.
    Numeric,
}

/// How many solutions a request wants.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum IkSolutionsMode {
    /// One answer: the solution nearest the seed (or the middle of the limits).
    #[default]
    Best,
    /// Every solution inside the joint limits (2π copies included), nearest
    /// the seed first, in `solutions`; needs the closed form.
    All,
}

/// The solver that produced an answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum IkSolverUsed {
    /// The arm's closed form (every solution; no iterations).
    Analytic,
    /// Damped least squares.
    Numeric,
}

impl IkSolverUsed {
    /// `"analytic"` or `"numeric"` (metric labels, logs).
    pub fn as_str(self) -> &'static str {
        match self {
            IkSolverUsed::Analytic => "analytic",
            IkSolverUsed::Numeric => "numeric",
        }
    }
}

/// Which root of each subproblem a closed-form solution took (0 or 1):
/// `shoulder` joint 1 (lefty / righty), `elbow` joint 3 (up / down), `wrist`
/// joints 4–5 (flip / no flip). Along a path away from singularities equal
/// branches mean no shoulder, elbow or wrist flip.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct IkBranch {
    /// Shoulder root, 0 or 1.
    pub shoulder: u8,
    /// Elbow root, 0 or 1.
    pub elbow: u8,
    /// Wrist root, 0 or 1.
    pub wrist: u8,
}

/// A singularity at which a closed-form solution stands for a one-parameter
/// family (the free joint takes its value from the seed).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum Singularity {
    /// The wrist centre on axis 1: joint 1 is free.
    Shoulder,
    /// Axes 4 and 6 aligned (or axis 6 parallel to 2–4): a wrist joint is free.
    Wrist,
}

/// One solution of `solutions: "all"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct IkSolutionItem {
    /// Joint values in the request's `angle_unit`, within the joint limits.
    pub joints: Vec<f64>,
    /// Its branch (`null` for a numeric answer).
    pub branch: Option<IkBranch>,
    /// Singularities it stands at (empty almost always).
    pub singular: Vec<Singularity>,
    /// Limits-aware distance to the seed (or the middle of the limits), rad:
    /// `√Σ dᵢ²` with `dᵢ = qᵢ − seedᵢ` (2π copies count as far as they are).
    pub distance: f64,
    /// Distance from the target position, robot length unit.
    pub position_error: f64,
    /// Angle from the target orientation, rad.
    pub orientation_error: f64,
}

/// A closed-form solution with its pose, in internal units too.
#[derive(Clone, Debug)]
pub(crate) struct AnalyticHit {
    /// Joint values, rad.
    pub q: [f64; 6],
    /// Tool pose at `q`.
    pub pose: Transform,
    /// The solution as answered.
    pub item: IkSolutionItem,
}

/// Every closed-form solution of `target` inside the limits within
/// `tolerance` (position, length unit; orientation, rad), at most `max`,
/// nearest `reference` (rad; `None`: the middle of the limits) first, and
/// whether more would have fit.
pub(crate) fn analytic_solutions(
    robot: &Robot,
    ik: &AnalyticIk,
    target: &Transform,
    reference: Option<&[f64]>,
    tolerance: f64,
    max: usize,
    unit: AngleUnit,
) -> (Vec<AnalyticHit>, bool) {
    let opts = AnalyticOptions {
        tolerance,
        max_solutions: max,
    };
    let answer = ik.solve(target, robot.limits(), reference, &opts);
    let hits = answer
        .solutions
        .iter()
        .filter_map(|s| hit(robot, s, target, tolerance, unit))
        .collect();
    (hits, answer.truncated)
}

/// One solution as answered, unless its FK misses the target by more than
/// `tolerance` (the closed form checks matrix entries; the answer, angles).
fn hit(
    robot: &Robot,
    s: &AnalyticSolution,
    target: &Transform,
    tolerance: f64,
    unit: AngleUnit,
) -> Option<AnalyticHit> {
    let pose = robot.chain().forward(&s.q, 1.0);
    let (position_error, orientation_error) = pose_errors(target, &pose);
    if position_error > tolerance || orientation_error > tolerance {
        return None;
    }
    let mut singular = Vec::new();
    if s.singular.shoulder {
        singular.push(Singularity::Shoulder);
    }
    if s.singular.wrist {
        singular.push(Singularity::Wrist);
    }
    let item = IkSolutionItem {
        joints: robot.to_request_unit(&s.q, unit),
        branch: Some(IkBranch {
            shoulder: u8::from(s.branch.shoulder),
            elbow: u8::from(s.branch.elbow),
            wrist: u8::from(s.branch.wrist),
        }),
        singular,
        distance: s.distance,
        position_error,
        orientation_error,
    };
    Some(AnalyticHit { q: s.q, pose, item })
}

/// Position error (length unit) and orientation error (rad) of `pose`
/// against `target`, as the numeric solver measures them.
pub(crate) fn pose_errors(target: &Transform, pose: &Transform) -> (f64, f64) {
    let d = [0, 1, 2].map(|i| target.translation[i] - pose.translation[i]);
    let r = rotation_error(target, pose);
    (
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt(),
        (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt(),
    )
}
