//! REST handlers of the Jacobian: `POST /v1/robots/{name}/jacobian` and
//! `/jacobian/batch`. Convert → call the service → convert back, like the FK
//! handlers. Depends on the service, the model and `api::jacobian`.

use axum::Json;
use axum::extract::State;

use axum::response::{IntoResponse, Response};

use super::AppState;
use super::binary::{self, BatchBody, JacobianBatch, Media};
use super::dto::{JacobianBatchRequest, JacobianRequest};
use super::extract::{Client, JsonBody, RobotName};
use super::problem::{ApiError, Problem};
use crate::api::jacobian::{JacobianBatchOutput, JacobianItem, JacobianOutput};
use crate::error::Error;
use crate::model::JacobianSpec;

type ApiResult<T> = Result<T, ApiError>;

/// Geometric Jacobian of one configuration, with manipulability, condition
/// number and singular flag. Columns are per rad (revolute) or per length
/// unit (prismatic) whatever `angle_unit` the request used.
#[utoipa::path(post, path = "/v1/robots/{name}/jacobian", tag = "velocity", request_body = JacobianRequest,
    params(("name" = String, Path, description = "Robot name")),
    responses(
        (status = 200, description = "The Jacobian of the tool point in the asked frame, its measures and the tool pose", body = JacobianOutput,
            example = json!({"robot": "planar_2dof", "length_unit": "m", "frame": "base",
                "jacobian": [[-0.48977774788672046, -0.2897777478867205], [0.4240558750445318, 0.07764571353075628],
                    [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [1.0, 1.0]],
                "manipulability": 0.08485281374238575, "condition_number": 5.835575728945763, "singular": false,
                "pose": {"matrix": [[0.2588190451025209, -0.9659258262890682, 0.0, 0.4240558750445318],
                        [0.9659258262890682, 0.2588190451025209, 0.0, 0.48977774788672046], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
                    "position": [0.4240558750445318, 0.48977774788672046, 0.0],
                    "quaternion": {"w": 0.7933533402912353, "x": 0.0, "y": 0.0, "z": 0.6087614290087205},
                    "rpy": [0.0, 0.0, 1.308996938995747]}})),
        (status = 400, description = "Malformed JSON or wrong types", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:malformed-request", "title": "Malformed request", "status": 400,
                "detail": "malformed input: frame: unknown variant `world`, expected `base` or `tool`",
                "errors": [{"field": "frame", "message": "unknown variant `world`, expected `base` or `tool`"}]})),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body over the size limit", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:too-large", "title": "Request too large", "status": 413, "detail": "too large: request body is over the limit of 1048576 bytes"})),
        (status = 415, description = "Not a JSON body", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Wrong joint count or a value outside the limits", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:invalid-input", "title": "Invalid input", "status": 422,
                "detail": "invalid input: joints: robot 'planar_2dof' has 2 movable joints, got 3 values",
                "errors": [{"field": "joints", "message": "robot 'planar_2dof' has 2 movable joints, got 3 values"}]})),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn jacobian(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    JsonBody(req): JsonBody<JacobianRequest>,
) -> ApiResult<Json<JacobianOutput>> {
    let entry = state.service.robot(&name)?;
    let robot = &entry.robot;
    let answer = state.service.jacobian(robot, &JacobianSpec::from(req))?;
    Ok(Json(JacobianOutput {
        robot: robot.name().to_string(),
        length_unit: robot.length_unit(),
        result: JacobianItem::from(&answer),
    }))
}

/// Jacobians of many configurations, in request order; one bad configuration
/// fails the batch, naming it (`configurations[17][2]`).
///
/// Also in binary: `application/x-protobuf` (gRPC's `JacobianBatch`
/// messages) and `application/octet-stream` (packed little-endian float64:
/// `n × dof` joint values in, `n × (6·dof + 15)` numbers out; options as
/// query parameters); `Content-Type` says what the body is, `Accept` what
/// the answer is (default JSON).
#[utoipa::path(post, path = "/v1/robots/{name}/jacobian/batch", tag = "velocity",
    request_body(description = binary::BATCH_BODY, content(
        (JacobianBatchRequest = "application/json"),
        (binary::Binary = "application/x-protobuf"),
        (binary::Binary = "application/octet-stream"))),
    params(("name" = String, Path, description = "Robot name"), binary::PackedJacobianQuery),
    responses(
        (status = 200, description = binary::BATCH_ANSWER, content(
            (JacobianBatchOutput = "application/json"),
            (binary::Binary = "application/x-protobuf"),
            (binary::Binary = "application/octet-stream")),
            example = json!({"robot": "planar_2dof", "length_unit": "m", "results": [{"frame": "tool",
                "jacobian": [[0.0, 0.0], [0.7, 0.29999999999999993], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [1.0, 1.0]],
                "manipulability": 0.0, "condition_number": null, "singular": true,
                "pose": {"matrix": [[1.0, 0.0, 0.0, 0.7], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
                    "position": [0.7, 0.0, 0.0], "quaternion": {"w": 1.0, "x": 0.0, "y": 0.0, "z": 0.0}, "rpy": [0.0, 0.0, 0.0]}}]})),
        (status = 400, description = "Malformed JSON or wrong types", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:malformed-request", "title": "Malformed request", "status": 400,
                "detail": "malformed input: configurations[0][1]: invalid type: string \"x\", expected f64",
                "errors": [{"field": "configurations[0][1]", "message": "invalid type: string \"x\", expected f64"}]})),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json"),
        (status = 406, description = "`Accept` names none of the answer formats", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "More configurations than the batch limit, or body over the size limit", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:too-large", "title": "Request too large", "status": 413,
                "detail": "too large: a batch holds at most 10000 configurations, got 10001",
                "errors": [{"field": "configurations", "message": "a batch holds at most 10000 configurations, got 10001"}]})),
        (status = 415, description = "Not a JSON body", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "A configuration with the wrong joint count or a value outside the limits", body = Problem, content_type = "application/problem+json",
            example = json!({"type": "urn:kinserve:problem:invalid-input", "title": "Invalid input", "status": 422,
                "detail": "invalid input: configurations[1][0]: 4 rad is outside the limits [-2.96706, 2.96706] rad of joint 'joint1'",
                "errors": [{"field": "configurations[1][0]", "message": "4 rad is outside the limits [-2.96706, 2.96706] rad of joint 'joint1'"}]})),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn jacobian_batch(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    Client(client): Client,
    body: BatchBody<JacobianBatch>,
) -> ApiResult<Response> {
    let entry = state.service.robot(&name)?;
    let answer = body.answer;
    let spec = body.spec(&state.service, &entry.robot)?;
    check_answer_size(
        spec.configurations.len(),
        entry.robot.dof(),
        state.settings.max_buffered_response_bytes,
    )?;
    let answers = state
        .service
        .jacobian_batch_on_pool(client, entry.clone(), spec)
        .await?;
    let robot = &entry.robot;
    if answer != Media::Json {
        return Ok(binary::jacobian_answer(answer, robot, &answers));
    }
    Ok(Json(JacobianBatchOutput {
        robot: robot.name().to_string(),
        length_unit: robot.length_unit(),
        results: answers.iter().map(JacobianItem::from).collect(),
    })
    .into_response())
}

/// Fewest bytes one Jacobian batch item takes in JSON: `6 × dof` Jacobian
/// entries and the 16 + 3 + 4 + 3 pose numbers, at 2 bytes (`0,`) or more
/// each, plus the field names (~150 bytes). A lower bound: what it refuses
/// could never fit.
fn min_item_bytes(dof: usize) -> usize {
    (6 * dof + 26) * 2 + 150
}

/// Refuses, before computing, a Jacobian batch whose answer could not fit in
/// the response budget (`--max-buffered-response-bytes`), which would
/// otherwise be computed in full and then replaced by a 503.
fn check_answer_size(configurations: usize, dof: usize, budget: usize) -> Result<(), Error> {
    let item = min_item_bytes(dof);
    let least = configurations.saturating_mul(item);
    if least <= budget {
        return Ok(());
    }
    Err(Error::TooLarge {
        detail: format!(
            "the answer would take at least {least} bytes, more than the {budget} bytes the server holds for answers (--max-buffered-response-bytes): send at most {} configurations of this robot per request",
            budget / item
        ),
        field: Some("configurations".into()),
    })
}
