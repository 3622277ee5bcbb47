//! REST handlers of inverse kinematics: `POST /v1/robots/{name}/ik` and
//! `/ik/batch`, solved on the blocking pool. Depends on the service, the
//! model and `api::ik`.

use axum::Json;
use axum::extract::State;
use axum::response::{IntoResponse, Response};

use super::AppState;
use super::binary::{self, BatchBody, IkBatch, Media};
use super::extract::{Client, JsonBody, RobotName};
use super::problem::{ApiError, Problem};
use crate::api::ik::{IkBatchOutput, IkItem, IkOutput, IkPathOutput};
use crate::model::{IkBatchSpec, IkPathSpec, IkSpec};

type ApiResult<T> = Result<T, ApiError>;

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
                "joints": [19.99999999999998, -30.000000000000018, 44.99999999999997, 10.000000000000009, 50.00000000000005, -19.99999999999999],
                "converged": true, "position_error": 6.206335383118183e-17, "orientation_error": 1.4946834900704541e-16, "iterations": 0,
                "pose": {"matrix": [[0.4980868739040637, -0.34488317188776374, -0.7955910154049708, 0.3161255029988694],
                        [-0.0655330153422936, 0.8999065002531891, -0.4311307396860072, -0.044619601375991164],
                        [0.8646472633071962, 0.26687804059287484, 0.4256303813224379, 0.8782707984072009], [0.0, 0.0, 0.0, 1.0]],
                    "position": [0.3161255029988694, -0.044619601375991164, 0.8782707984072009],
                    "quaternion": {"w": 0.8401820867347284, "x": 0.20769568623856685, "y": -0.4940114485076959, "z": 0.0831219092134934},
                    "rpy": [0.5600493649478945, -1.0444478148342726, -0.13081805892381246]},
                "solver": "analytic", "branch": {"shoulder": 0, "elbow": 1, "wrist": 1}, "singular": []})),
        (status = 400, description = "Malformed JSON, wrong types or unknown fields", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:malformed-request", "title": "Malformed request", "status": 400,
                "detail": "malformed input: target.position: invalid length 2, expected an array of length 3",
                "errors": [{"field": "target.position", "message": "invalid length 2, expected an array of length 3"}]})),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body over the size limit", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:too-large", "title": "Request too large", "status": 413, "detail": "too large: request body is over the limit of 1048576 bytes"})),
        (status = 415, description = "Not a JSON body", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid request (`invalid-input`, with field paths such as `target.matrix[3]` or `tolerance`), or a target not reached within the tolerance (`ik-not-converged`, with the best attempt)", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:ik-not-converged", "title": "Inverse kinematics did not converge", "status": 422,
                "detail": "inverse kinematics did not converge: best attempt has position error 1.082e0 m, orientation error 1.017e-1 rad after 170 iterations",
                "best_attempt": {"joints": [176.4802771001353, -5.610316775642131, 0.3762242550042261, -92.48713721774861, -111.96305121382099, -96.40982700719717],
                    "converged": false, "position_error": 1.081721351577331, "orientation_error": 0.1016732021781089, "iterations": 170,
                    "pose": {"matrix": [[0.9948370471320815, 0.003996838061649628, 0.10140648371297278, 0.9288876399735971],
                            [0.04254226180718372, -0.923615270928858, -0.38095273626441, 0.03909610533614434],
                            [0.09213797053250904, 0.3832999564212355, -0.9190167233481823, 0.16168835814823396], [0.0, 0.0, 0.0, 1.0]],
                        "position": [0.9288876399735971, 0.03909610533614434, 0.16168835814823396],
                        "quaternion": {"w": 0.1950673299498414, "x": 0.9794729502912679, "y": 0.011878607738731815, "z": 0.04940015295673227},
                        "rpy": [2.746452676058684, -0.09226883719332134, 0.04273700734403348]},
                    "solver": "numeric", "branch": null, "singular": []}})),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn ik(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    Client(client): Client,
    JsonBody(req): JsonBody<IkSpec>,
) -> ApiResult<Json<IkOutput>> {
    let entry = state.service.robot(&name)?;
    let angle_unit = req.angle_unit;
    let answer = state.service.ik_on_pool(client, entry.clone(), req).await?;
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
///
/// Also as protobuf: `application/x-protobuf` takes and (by `Accept`) gives
/// gRPC's `InverseKinematicsBatch` messages.
#[utoipa::path(post, path = "/v1/robots/{name}/ik/batch", tag = "ik",
    request_body(description = binary::IK_BATCH_BODY, content(
        (IkBatchSpec = "application/json"),
        (binary::Binary = "application/x-protobuf"))),
    params(("name" = String, Path, description = "Robot name")),
    responses(
        (status = 200, description = "One answer per target, in request order, converged or not: JSON, or with `Accept: application/x-protobuf` the `InverseKinematicsBatchResponse` message", content(
            (IkBatchOutput = "application/json"),
            (binary::Binary = "application/x-protobuf")),
            example = json!({"robot": "planar_2dof", "length_unit": "m", "angle_unit": "rad", "results": [
                {"joints": [0.04323781905251354, 1.186399552468544], "converged": true, "position_error": 3.261475666182992e-11,
                 "orientation_error": null, "iterations": 7,
                 "pose": {"matrix": [[0.3345794784216446, -0.9423675358473999, 0.0, 0.4999999999746447],
                        [0.9423675358473999, 0.3345794784216446, 0.0, 0.2999999999794858], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
                    "position": [0.4999999999746447, 0.2999999999794858, 0.0],
                    "quaternion": {"w": 0.8168780442702707, "x": 0.0, "y": 0.0, "z": 0.5768104201461497}, "rpy": [0.0, 0.0, 1.2296373715210576]},
                 "solver": "numeric", "branch": null, "singular": []},
                {"joints": [0.0946322604796601, 1.1299924165992894], "converged": true, "position_error": 4.661523989577213e-11,
                 "orientation_error": null, "iterations": 3,
                 "pose": {"matrix": [[0.33929905565032625, -0.9406785587196067, 0.0, 0.4999999999642441],
                        [0.9406785587196067, 0.33929905565032625, 0.0, 0.3199999999700919], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
                    "position": [0.4999999999642441, 0.3199999999700919, 0.0],
                    "quaternion": {"w": 0.818321164229035, "x": 0.0, "y": 0.0, "z": 0.574761230577391}, "rpy": [0.0, 0.0, 1.2246246770789495]},
                 "solver": "numeric", "branch": null, "singular": []}]})),
        (status = 400, description = "Malformed JSON, wrong types or unknown fields", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:malformed-request", "title": "Malformed request", "status": 400,
                "detail": "malformed input: targets[0].matrix: invalid length 3, expected an array of length 4",
                "errors": [{"field": "targets[0].matrix", "message": "invalid length 3, expected an array of length 4"}]})),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json"),
        (status = 406, description = "`Accept` names none of the answer formats", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "More targets than the batch limit, or body over the size limit", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:too-large", "title": "Request too large", "status": 413,
                "detail": "too large: a batch holds at most 10000 targets, got 10001",
                "errors": [{"field": "targets", "message": "a batch holds at most 10000 targets, got 10001"}]})),
        (status = 415, description = "Not a JSON body", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid request, with field paths such as `targets[3].quaternion`", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:invalid-input", "title": "Invalid input", "status": 422,
                "detail": "invalid input: targets[1].quaternion: is required unless position_only is true",
                "errors": [{"field": "targets[1].quaternion", "message": "is required unless position_only is true"}]})),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn ik_batch(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    Client(client): Client,
    body: BatchBody<IkBatch>,
) -> ApiResult<Response> {
    let entry = state.service.robot(&name)?;
    let answer = body.answer;
    let req = body.spec(&state.service, &entry.robot)?;
    let angle_unit = req.angle_unit;
    let answers = state
        .service
        .ik_batch_on_pool(client, entry.clone(), req)
        .await?;
    if answer != Media::Json {
        return Ok(binary::ik_answer(&entry.robot, angle_unit, &answers));
    }
    Ok(Json(IkBatchOutput {
        robot: entry.robot.name().to_string(),
        length_unit: entry.robot.length_unit(),
        angle_unit,
        results: answers.iter().map(IkItem::from).collect(),
    })
    .into_response())
}

/// A Cartesian path: from `start` through the waypoints along straight lines
/// (positions linear, orientations slerped) in steps of at most
/// `max_step_length` / `max_step_angle`, each solved by IK seeded with the
/// previous step. Stops at the first step no solution within the limits
/// reaches, that would move a joint more than `max_joint_step`, or that
/// stands at a singularity: still a 200, `stop` says which step and why and
/// `fraction` how much was achieved (MoveIt's `computeCartesianPath`).
#[utoipa::path(post, path = "/v1/robots/{name}/ik/path", tag = "ik", request_body = IkPathSpec,
    params(("name" = String, Path, description = "Robot name")),
    responses(
        (status = 200, description = "The joints of every step taken, start first; `stop` when it ended early", body = IkPathOutput),
        (status = 400, description = "Malformed JSON, wrong types or unknown fields", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "More steps than the batch limit at this step size (`max_step_length`), more waypoints than the limit, or body over the size limit", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Not a JSON body", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid request, with field paths such as `start[2]` or `waypoints[1].quaternion`", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:invalid-input", "title": "Invalid input", "status": 422,
                "detail": "invalid input: max_step_length: must be a number above 0 and at most 1000000000, got 0",
                "errors": [{"field": "max_step_length", "message": "must be a number above 0 and at most 1000000000, got 0"}]})),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn ik_path(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    Client(client): Client,
    JsonBody(req): JsonBody<IkPathSpec>,
) -> ApiResult<Response> {
    let entry = state.service.robot(&name)?;
    let angle_unit = req.angle_unit;
    let answer = state
        .service
        .ik_path_on_pool(client, entry.clone(), req)
        .await?;
    Ok(super::streamed::path_answer(IkPathOutput::new(
        entry.robot.name(),
        entry.robot.length_unit(),
        angle_unit,
        answer,
    ))?)
}
