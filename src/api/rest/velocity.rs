//! REST handlers of velocity and inverse kinematics: `POST
//! /v1/robots/{name}/jacobian`, `/jacobian/batch`, `/ik`, `/ik/batch`.
//! Validate → call the service → convert back, like the FK handlers; IK runs
//! on the blocking pool. Depends on the service, the model and `api::velocity`.

use axum::Json;
use axum::extract::State;

use super::AppState;
use super::dto::{JacobianBatchRequest, JacobianRequest};
use super::extract::{JsonBody, RobotName};
use super::problem::{ApiError, Problem};
use crate::api::velocity::{
    IkBatchOutput, IkItem, IkOutput, JacobianBatchOutput, JacobianItem, JacobianOutput,
};
use crate::model::{IkBatchSpec, IkSpec};

type ApiResult<T> = Result<T, ApiError>;

/// Geometric Jacobian of one configuration, with manipulability, condition
/// number and singular flag. Columns are per rad (revolute) or per length
/// unit (prismatic) whatever `angle_unit` the request used.
#[utoipa::path(post, path = "/v1/robots/{name}/jacobian", tag = "velocity", request_body = JacobianRequest,
    params(("name" = String, Path, description = "Robot name")),
    responses(
        (status = 200, description = "The Jacobian of the tool point in the asked frame, its measures and the tool pose", body = JacobianOutput,
            example = json!({"robot": "planar_2dof", "length_unit": "m", "frame": "base",
                "jacobian": [[-0.3, -0.3], [0.4, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [1.0, 1.0]],
                "manipulability": 0.12, "condition_number": 4.2, "singular": false,
                "pose": {"matrix": [[0, -1, 0, 0.4], [1, 0, 0, 0.3], [0, 0, 1, 0], [0, 0, 0, 1]],
                    "position": [0.4, 0.3, 0.0], "quaternion": {"w": 0.7071, "x": 0, "y": 0, "z": 0.7071}, "rpy": [0, 0, 1.5708]}})),
        (status = 400, description = "Malformed JSON or wrong types", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:malformed-request", "title": "Malformed request", "status": 400,
                "detail": "malformed input: frame: unknown variant `world`, expected `base` or `tool`",
                "errors": [{"field": "frame", "message": "unknown variant `world`, expected `base` or `tool`"}]})),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:not-found", "title": "Robot not found", "status": 404, "detail": "robot 'r2d2' not found"})),
        (status = 413, description = "Body over the size limit", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:too-large", "title": "Request too large", "status": 413, "detail": "too large: request body is over the limit of 1048576 bytes"})),
        (status = 415, description = "Not a JSON body", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:unsupported-media-type", "title": "Unsupported media type", "status": 415, "detail": "unsupported media type: expected Content-Type application/json, got 'text/plain'"})),
        (status = 422, description = "Wrong joint count or a value outside the limits", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:invalid-input", "title": "Invalid input", "status": 422,
                "detail": "invalid input: joints: robot 'planar_2dof' has 2 movable joints, got 3 values",
                "errors": [{"field": "joints", "message": "robot 'planar_2dof' has 2 movable joints, got 3 values"}]})),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:overloaded", "title": "Server overloaded", "status": 503, "detail": "server overloaded, retry later"}))))]
pub async fn jacobian(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    JsonBody(req): JsonBody<JacobianRequest>,
) -> ApiResult<Json<JacobianOutput>> {
    let entry = state.service.robot(&name)?;
    let robot = &entry.robot;
    let answer = state
        .service
        .jacobian(robot, &req.joints, &req.options(), req.frame)?;
    Ok(Json(JacobianOutput {
        robot: robot.name().to_string(),
        length_unit: robot.length_unit(),
        result: JacobianItem::from(&answer),
    }))
}

/// Jacobians of many configurations, in request order; one bad configuration
/// fails the batch, naming it (`configurations[17][2]`).
#[utoipa::path(post, path = "/v1/robots/{name}/jacobian/batch", tag = "velocity", request_body = JacobianBatchRequest,
    params(("name" = String, Path, description = "Robot name")),
    responses(
        (status = 200, description = "One Jacobian with its measures and pose per configuration, in request order", body = JacobianBatchOutput,
            example = json!({"robot": "planar_2dof", "length_unit": "m", "results": [{"frame": "tool",
                "jacobian": [[0.0, 0.0], [0.7, 0.3], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [1.0, 1.0]],
                "manipulability": 0.0, "condition_number": null, "singular": true,
                "pose": {"matrix": [[1, 0, 0, 0.7], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
                    "position": [0.7, 0.0, 0.0], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}, "rpy": [0, 0, 0]}}]})),
        (status = 400, description = "Malformed JSON or wrong types", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:malformed-request", "title": "Malformed request", "status": 400,
                "detail": "malformed input: configurations[0][1]: invalid type: string \"x\", expected f64",
                "errors": [{"field": "configurations[0][1]", "message": "invalid type: string \"x\", expected f64"}]})),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:not-found", "title": "Robot not found", "status": 404, "detail": "robot 'r2d2' not found"})),
        (status = 413, description = "More configurations than the batch limit, or body over the size limit", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:too-large", "title": "Request too large", "status": 413,
                "detail": "too large: a batch holds at most 10000 configurations, got 10001",
                "errors": [{"field": "configurations", "message": "a batch holds at most 10000 configurations, got 10001"}]})),
        (status = 415, description = "Not a JSON body", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:unsupported-media-type", "title": "Unsupported media type", "status": 415, "detail": "unsupported media type: expected Content-Type application/json, got 'text/plain'"})),
        (status = 422, description = "A configuration with the wrong joint count or a value outside the limits", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:invalid-input", "title": "Invalid input", "status": 422,
                "detail": "invalid input: configurations[1][0]: 4 rad is outside the limits [-2.96706, 2.96706] rad of joint 'joint1'",
                "errors": [{"field": "configurations[1][0]", "message": "4 rad is outside the limits [-2.96706, 2.96706] rad of joint 'joint1'"}]})),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:overloaded", "title": "Server overloaded", "status": 503, "detail": "server overloaded, retry later"}))))]
pub async fn jacobian_batch(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    JsonBody(req): JsonBody<JacobianBatchRequest>,
) -> ApiResult<Json<JacobianBatchOutput>> {
    let entry = state.service.robot(&name)?;
    let robot = &entry.robot;
    let answers =
        state
            .service
            .jacobian_batch(robot, &req.configurations, &req.options(), req.frame)?;
    Ok(Json(JacobianBatchOutput {
        robot: robot.name().to_string(),
        length_unit: robot.length_unit(),
        results: answers.iter().map(JacobianItem::from).collect(),
    }))
}

/// Inverse kinematics of one target: joints (in the request's angle unit,
/// within the joint limits) that put the tool at the target. Numerical
/// (damped least squares with deterministic restarts), capped in time; a
/// target it cannot reach within the tolerance is a 422 `ik-not-converged`
/// carrying the best attempt.
#[utoipa::path(post, path = "/v1/robots/{name}/ik", tag = "ik", request_body = IkSpec,
    params(("name" = String, Path, description = "Robot name")),
    responses(
        (status = 200, description = "Converged: the joints, their errors against the target and the pose they give", body = IkOutput,
            example = json!({"robot": "puma560", "length_unit": "m", "angle_unit": "deg",
                "joints": [10.0, -30.0, 45.0, 5.0, 60.0, -15.0], "converged": true,
                "position_error": 1.1e-16, "orientation_error": 2.2e-16, "iterations": 12,
                "pose": {"matrix": [[0, 0, 1, 0.4], [0, -1, 0, 0.1], [1, 0, 0, 0.3], [0, 0, 0, 1]],
                    "position": [0.4, 0.1, 0.3], "quaternion": {"w": 0, "x": 0.7071, "y": 0, "z": 0.7071}, "rpy": [3.1416, -1.5708, 0]}})),
        (status = 400, description = "Malformed JSON, wrong types or unknown fields", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:malformed-request", "title": "Malformed request", "status": 400,
                "detail": "malformed input: target.position: invalid length 2, expected an array of length 3",
                "errors": [{"field": "target.position", "message": "invalid length 2, expected an array of length 3"}]})),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:not-found", "title": "Robot not found", "status": 404, "detail": "robot 'r2d2' not found"})),
        (status = 413, description = "Body over the size limit", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:too-large", "title": "Request too large", "status": 413, "detail": "too large: request body is over the limit of 1048576 bytes"})),
        (status = 415, description = "Not a JSON body", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:unsupported-media-type", "title": "Unsupported media type", "status": 415, "detail": "unsupported media type: expected Content-Type application/json, got 'text/plain'"})),
        (status = 422, description = "Invalid request (`invalid-input`, with field paths such as `target.matrix[3]` or `tolerance`), or a target not reached within the tolerance (`ik-not-converged`, with the best attempt)", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:ik-not-converged", "title": "Inverse kinematics did not converge", "status": 422,
                "detail": "inverse kinematics did not converge: best attempt has position error 1.064e0 m, orientation error 1.571e0 rad after 2416 iterations",
                "best_attempt": {"joints": [0.0, -80.1, 90.0, 0.0, 0.0, 0.0], "converged": false,
                    "position_error": 1.064, "orientation_error": 1.571, "iterations": 2416,
                    "pose": {"matrix": [[1, 0, 0, 0.9], [0, 1, 0, 0.1], [0, 0, 1, 0.6], [0, 0, 0, 1]],
                        "position": [0.9, 0.1, 0.6], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}, "rpy": [0, 0, 0]}}})),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:overloaded", "title": "Server overloaded", "status": 503, "detail": "server overloaded, retry later"}))))]
pub async fn ik(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    JsonBody(req): JsonBody<IkSpec>,
) -> ApiResult<Json<IkOutput>> {
    let entry = state.service.robot(&name)?;
    let angle_unit = req.angle_unit;
    let answer = state.service.ik_blocking(entry.clone(), req).await?;
    Ok(Json(IkOutput {
        robot: entry.robot.name().to_string(),
        length_unit: entry.robot.length_unit(),
        angle_unit,
        result: IkItem::from(&answer),
    }))
}

/// Inverse kinematics of many targets, solved in order, each seeded with the
/// previous converged answer (tracking a path). Every target is answered
/// (`converged` says which were reached); the batch as a whole is capped in
/// time, targets left when the cap runs out are answered unsolved.
#[utoipa::path(post, path = "/v1/robots/{name}/ik/batch", tag = "ik", request_body = IkBatchSpec,
    params(("name" = String, Path, description = "Robot name")),
    responses(
        (status = 200, description = "One answer per target, in request order, converged or not", body = IkBatchOutput,
            example = json!({"robot": "planar_2dof", "length_unit": "m", "angle_unit": "rad", "results": [
                {"joints": [0.2, 0.5], "converged": true, "position_error": 0.0, "orientation_error": null, "iterations": 5,
                 "pose": {"matrix": [[0.6967, -0.7174, 0, 0.5994], [0.7174, 0.6967, 0, 0.2946], [0, 0, 1, 0], [0, 0, 0, 1]],
                    "position": [0.5994, 0.2946, 0.0], "quaternion": {"w": 0.9394, "x": 0, "y": 0, "z": 0.3429}, "rpy": [0, 0, 0.7]}}]})),
        (status = 400, description = "Malformed JSON, wrong types or unknown fields", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:malformed-request", "title": "Malformed request", "status": 400,
                "detail": "malformed input: targets[0].matrix: invalid length 3, expected an array of length 4",
                "errors": [{"field": "targets[0].matrix", "message": "invalid length 3, expected an array of length 4"}]})),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:not-found", "title": "Robot not found", "status": 404, "detail": "robot 'r2d2' not found"})),
        (status = 413, description = "More targets than the batch limit, or body over the size limit", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:too-large", "title": "Request too large", "status": 413,
                "detail": "too large: a batch holds at most 10000 targets, got 10001",
                "errors": [{"field": "targets", "message": "a batch holds at most 10000 targets, got 10001"}]})),
        (status = 415, description = "Not a JSON body", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:unsupported-media-type", "title": "Unsupported media type", "status": 415, "detail": "unsupported media type: expected Content-Type application/json, got 'text/plain'"})),
        (status = 422, description = "Invalid request, with field paths such as `targets[3].quaternion`", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:invalid-input", "title": "Invalid input", "status": 422,
                "detail": "invalid input: targets[1].quaternion: is required unless position_only is true",
                "errors": [{"field": "targets[1].quaternion", "message": "is required unless position_only is true"}]})),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:overloaded", "title": "Server overloaded", "status": 503, "detail": "server overloaded, retry later"}))))]
pub async fn ik_batch(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    JsonBody(req): JsonBody<IkBatchSpec>,
) -> ApiResult<Json<IkBatchOutput>> {
    let entry = state.service.robot(&name)?;
    let angle_unit = req.angle_unit;
    let answers = state.service.ik_batch_blocking(entry.clone(), req).await?;
    Ok(Json(IkBatchOutput {
        robot: entry.robot.name().to_string(),
        length_unit: entry.robot.length_unit(),
        angle_unit,
        results: answers.iter().map(IkItem::from).collect(),
    }))
}
