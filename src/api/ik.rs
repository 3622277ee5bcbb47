//! The IK results as REST, WebSocket and the CLI return them (gRPC's
//! messages come from `kinserve-api`), built from the model's answers.
//! Depends on the model crate and `api::pose` only.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::pose::Pose;
use crate::model::{
    AngleUnit, IkAnswer, IkBranch, IkPathAnswer, IkSolutionItem, IkSolverUsed, LengthUnit,
    PathStop, Singularity,
};

/// One IK answer: the joints found (or the best attempt) and their errors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "joints": [0.04323781905251354, 1.186399552468544], "converged": true,
    "position_error": 3.261475666182992e-11, "orientation_error": null, "iterations": 7,
    "solver": "numeric", "branch": null, "singular": [],
    "pose": {"matrix": [[0.3345794784216446, -0.9423675358473999, 0.0, 0.4999999999746447],
            [0.9423675358473999, 0.3345794784216446, 0.0, 0.2999999999794858], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
        "position": [0.4999999999746447, 0.2999999999794858, 0.0],
        "quaternion": {"w": 0.8168780442702707, "x": 0.0, "y": 0.0, "z": 0.5768104201461497}, "rpy": [0.0, 0.0, 1.2296373715210576]}
}))]
pub struct IkItem {
    /// Joint values: revolute in the request's `angle_unit`, prismatic in the
    /// robot's length unit; always within the joint limits.
    pub joints: Vec<f64>,
    /// Whether both errors are within the tolerance (position only: the position error).
    pub converged: bool,
    /// Distance from the target position, robot length unit.
    pub position_error: f64,
    /// Angle from the target orientation, rad; `null` when the target gave none.
    pub orientation_error: Option<f64>,
    /// Solver iterations over all attempts.
    pub iterations: u32,
    /// Tool pose at `joints`.
    pub pose: Pose,
    /// The solver that produced `joints` (`analytic`: the arm's closed form,
    /// 0 iterations).
    pub solver: IkSolverUsed,
    /// The closed-form branch of `joints`; `null` from the numeric solver.
    pub branch: Option<IkBranch>,
    /// Singularities `joints` stands at (`shoulder`, `wrist`; closed form only).
    pub singular: Vec<Singularity>,
    /// With `solutions: "all"` only: every solution inside the limits,
    /// nearest the seed first (`joints` is the first); empty when none fits.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solutions: Option<Vec<IkSolutionItem>>,
    /// With `solutions: "all"` only: whether more solutions fit the limits
    /// than `max_solutions`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truncated: Option<bool>,
}

impl From<&IkAnswer> for IkItem {
    fn from(a: &IkAnswer) -> Self {
        IkItem {
            joints: a.joints.clone(),
            converged: a.converged,
            position_error: a.position_error,
            orientation_error: a.orientation_error,
            iterations: a.iterations,
            pose: Pose::from(&a.pose),
            solver: a.solver,
            branch: a.branch,
            singular: a.singular.clone(),
            solutions: a.solutions.clone(),
            truncated: a.solutions.is_some().then_some(a.truncated),
        }
    }
}

/// `POST /v1/robots/{name}/ik` response and `kinserve ik` output.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct IkOutput {
    /// Robot name.
    pub robot: String,
    /// Length unit of the positions and of `position_error`.
    pub length_unit: LengthUnit,
    /// Unit of the revolute values in `joints`.
    pub angle_unit: AngleUnit,
    /// The answer.
    #[serde(flatten)]
    pub result: IkItem,
}

/// `POST /v1/robots/{name}/ik/batch` response: every target answered, in
/// request order, converged or not (see each `converged`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct IkBatchOutput {
    /// Robot name.
    pub robot: String,
    /// Length unit of the positions and of `position_error`.
    pub length_unit: LengthUnit,
    /// Unit of the revolute values in `joints`.
    pub angle_unit: AngleUnit,
    /// One answer per target, in request order.
    pub results: Vec<IkItem>,
}

/// `POST /v1/robots/{name}/ik/path` response (and the WebSocket's
/// `ik_path` reply): the joints of every step taken, start first; a path
/// that stopped early is still a 200 with `stop` saying where and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({"robot": "puma560", "length_unit": "m", "angle_unit": "rad",
    "points": [[0.1, -0.4, 0.6, 0.2, 0.5, -0.3], [0.0987, -0.4108, 0.6203, 0.2008, 0.4894, -0.2983]],
    "fraction": 1.0, "waypoints_reached": 1, "stop": null}))]
pub struct IkPathOutput {
    /// Robot name.
    pub robot: String,
    /// Length unit of the robot.
    pub length_unit: LengthUnit,
    /// Unit of the revolute values in `points`.
    pub angle_unit: AngleUnit,
    /// Joint values per step: the start, then each step taken.
    pub points: Vec<Vec<f64>>,
    /// Steps taken ÷ steps planned (1 when complete).
    pub fraction: f64,
    /// Waypoints fully reached.
    pub waypoints_reached: usize,
    /// `null` when complete; else the step not taken, its waypoint and why
    /// (`unreachable`, `joint_limits`, `joint_jump`, `singularity`, `time_limit`).
    pub stop: Option<PathStop>,
}

impl IkPathOutput {
    /// The answer with its robot's names and units.
    pub fn new(
        robot: &str,
        length_unit: LengthUnit,
        angle_unit: AngleUnit,
        a: IkPathAnswer,
    ) -> Self {
        IkPathOutput {
            robot: robot.to_string(),
            length_unit,
            angle_unit,
            points: a.points,
            fraction: a.fraction,
            waypoints_reached: a.waypoints_reached,
            stop: a.stop,
        }
    }
}
