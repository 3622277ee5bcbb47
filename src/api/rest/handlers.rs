//! REST handlers: validate → convert → call the service → convert back.

use axum::Json;
use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

use super::AppState;
use super::binary::{self, BatchBody, FkBatch, Media};
use super::dto::{FkBatchRequest, FkBatchResponse, FkReply, FkRequest, RobotList, RobotSummaryDto};
use super::dto::{ListParams, Readiness, StoreState};
use super::export::PLANAR_URDF_EXAMPLE;
use super::extract::{Client, JsonBody, RobotName};
use super::import::{self, CreateParams, ReplaceParams, RobotBody, UrdfImportBody};
use super::problem::{ApiError, Problem};
use crate::api::pose::FkOutput;
use crate::error::Error;
use crate::model::{FkSpec, RobotSpec};
use crate::registry::{Condition, Entry, Origin, PutMode};
use crate::service::{FkAnswer, FkBatchCompute};
use crate::telemetry::Protocol;
use axum::extract::Query;
use axum::extract::rejection::QueryRejection;

type ApiResult<T> = Result<T, ApiError>;

fn origin_str(o: Origin) -> &'static str {
    match o {
        Origin::Builtin => "builtin",
        Origin::Registered => "registered",
    }
}

/// Liveness: 200 while the process runs.
#[utoipa::path(get, path = "/healthz", tag = "health", responses((status = 200, description = "Alive")))]
pub async fn healthz() -> &'static str {
    "ok"
}

/// Readiness: 200 once robots are loaded, 503 while starting or shutting
/// down. The body says how the registry store is doing; a store that is down
/// leaves the server ready (FK, list and get are served from the snapshot).
#[utoipa::path(get, path = "/readyz", tag = "health", responses(
    (status = 200, description = "Ready; the registry store's state", body = Readiness),
    (status = 503, description = "Starting or shutting down", body = Problem, content_type = "application/problem+json")))]
pub async fn readyz(State(state): State<AppState>) -> ApiResult<Json<Readiness>> {
    if state.service.is_ready() {
        let health = state.service.registry().store_health();
        Ok(Json(Readiness {
            status: "ready".into(),
            store: StoreState {
                kind: health.kind.into(),
                state: if health.up { "up" } else { "down" }.into(),
                snapshot_age_seconds: health.snapshot_age.as_secs_f64(),
            },
        }))
    } else {
        Err(Error::Unavailable {
            detail: "starting or shutting down".into(),
        }
        .into())
    }
}

/// The robots, sorted by name, a page at a time (AIP-158: `page_size`,
/// `page_token`; follow `next_page_token` until it is absent).
#[utoipa::path(get, path = "/v1/robots", tag = "robots",
    params(ListParams),
    responses((status = 200, body = RobotList),
        (status = 400, body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn list_robots(
    State(state): State<AppState>,
    query: Result<Query<ListParams>, QueryRejection>,
) -> ApiResult<Json<RobotList>> {
    let Query(params) = query.map_err(|e| Error::malformed_field("query", e.body_text()))?;
    let page_size = match params.page_size.unwrap_or(0) {
        n if n < 0 => {
            return Err(Error::malformed_field(
                "page_size",
                "must be 0 (the default, 100) or more",
            )
            .into());
        }
        n => u32::try_from(n).unwrap_or(u32::MAX),
    };
    let (page, next_page_token) = state
        .service
        .list_page(page_size, params.page_token.as_deref().unwrap_or(""))?;
    let robots = page
        .into_iter()
        .map(|s| RobotSummaryDto {
            name: s.name,
            dof: s.dof,
            convention: s.convention,
            length_unit: s.length_unit,
            source: origin_str(s.origin).to_string(),
            ik_class: s.ik_class.map(str::to_string),
        })
        .collect();
    Ok(Json(RobotList {
        robots,
        next_page_token,
    }))
}

/// One robot's model, in the schema it was registered with, with its `ETag`
/// (and, for registered robots, `Last-Modified`).
#[utoipa::path(get, path = "/v1/robots/{name}", tag = "robots",
    params(("name" = String, Path, description = "Robot name")),
    responses((status = 200, body = RobotSpec, headers(
            ("ETag" = String, description = "Entity tag of this version (`\"17\"`; built-ins: `\"builtin-<hash>\"`): send it as `If-Match` to replace or delete only this version"),
            ("Last-Modified" = String, description = "When this version was written (registered robots only)"))),
        (status = 400, body = Problem, content_type = "application/problem+json"),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn get_robot(
    State(state): State<AppState>,
    RobotName(name): RobotName,
) -> ApiResult<Response> {
    let entry = state.service.robot(&name)?;
    let mut resp = Json(entry.robot.spec()).into_response();
    version_headers(&mut resp, &entry);
    Ok(resp)
}

/// Sets `ETag` and, for a stored version, `Last-Modified`.
fn version_headers(resp: &mut Response, entry: &Entry) {
    let h = resp.headers_mut();
    if let Ok(v) = HeaderValue::from_str(entry.etag()) {
        h.insert(header::ETAG, v);
    }
    if let Some(v) = entry
        .version
        .and_then(|v| HeaderValue::from_str(&httpdate::fmt_http_date(v.updated)).ok())
    {
        h.insert(header::LAST_MODIFIED, v);
    }
}

fn header_str<'h>(headers: &'h HeaderMap, name: &str) -> Result<Option<&'h str>, Error> {
    headers
        .get(name)
        .map(|v| {
            v.to_str()
                .map_err(|_| Error::malformed_field(name, "must be visible ASCII"))
        })
        .transpose()
}

/// The condition of a write from `If-Match` (`*` or entity tags) and, when
/// `none_match_allowed` (PUT), `If-None-Match: *` (create only).
fn write_condition(headers: &HeaderMap, none_match_allowed: bool) -> Result<Condition, Error> {
    let if_match = header_str(headers, "If-Match")?;
    let if_none_match = header_str(headers, "If-None-Match")?;
    match (if_match, if_none_match) {
        (Some(_), Some(_)) => Err(Error::malformed_field(
            "If-None-Match",
            "send either If-Match (replace this version) or If-None-Match: * (create only), not both",
        )),
        (Some(m), None) => Condition::if_match(m, "If-Match"),
        (None, Some(n)) if none_match_allowed && n.trim() == "*" => Ok(Condition::Absent),
        (None, Some(_)) => Err(Error::malformed_field(
            "If-None-Match",
            if none_match_allowed {
                "only * is supported on a write (create only if the robot does not exist)"
            } else {
                "not supported on DELETE; use If-Match"
            },
        )),
        (None, None) => Ok(Condition::Any),
    }
}

fn created(name: &str, created: bool, entry: &Entry) -> Response {
    let status = if created {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    let mut resp = (status, Json(entry.robot.spec())).into_response();
    if created && let Ok(v) = HeaderValue::from_str(&format!("/v1/robots/{name}")) {
        resp.headers_mut().insert(header::LOCATION, v);
    }
    version_headers(&mut resp, entry);
    resp
}

/// What `POST /v1/robots` and `PUT /v1/robots/{name}` take.
const REGISTRATION_BODY: &str = "A robot model (`application/json`); or a URDF document \
(`application/xml`, `text/xml`; UTF-8) with the robot's name (POST), `base_link`, `tip_link` and \
`convention` as query parameters; or the same as JSON (`application/vnd.kinserve.urdf-import+json`). \
A URDF's chain from `base_link` to `tip_link` becomes an exact DH table (its DH frames are the \
import's own, not the URDF's link frames), checked against the URDF's forward kinematics; it is \
registered as a model is. Refusals name `urdf`, `base_link`, `tip_link` or `convention`.";

/// Registers a robot (201 with `Location` and `ETag`; 409 if the name is
/// taken): a model, or one imported from a URDF document.
#[utoipa::path(post, path = "/v1/robots", tag = "robots", request_body(description = REGISTRATION_BODY, content(
        (RobotSpec = "application/json"),
        (UrdfImportBody = "application/vnd.kinserve.urdf-import+json"),
        (String = "application/xml", example = json!(PLANAR_URDF_EXAMPLE)),
        (String = "text/xml", example = json!(PLANAR_URDF_EXAMPLE)))),
    params(CreateParams),
    security((), ("bearer" = [])),
    responses((status = 201, body = RobotSpec, headers(("Location" = String, description = "The robot's URL"),
            ("ETag" = String, description = "Entity tag of the version written"),
            ("Last-Modified" = String, description = "When it was written"))),
        (status = 400, body = Problem, content_type = "application/problem+json"),
        (status = 401, body = Problem, content_type = "application/problem+json"),
        (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 413, body = Problem, content_type = "application/problem+json"),
        (status = 415, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded, timed out, or the registry database is unavailable (Retry-After); nothing was changed, except that a write that timed out may have been committed (read it again)", body = Problem, content_type = "application/problem+json"),
        (status = 507, body = Problem, content_type = "application/problem+json")))]
pub async fn create_robot(
    State(state): State<AppState>,
    Client(client): Client,
    query: Result<Query<CreateParams>, QueryRejection>,
    body: RobotBody,
) -> ApiResult<Response> {
    let Query(params) = query.map_err(|e| Error::malformed_field("query", e.body_text()))?;
    let spec = import::robot_spec((&state.service, client), body, params, None).await?;
    let name = spec.name.clone();
    let (entry, _) = state
        .service
        .register(spec, PutMode::Create, Condition::Any)
        .await?;
    Ok(created(&name, true, &entry))
}

/// Creates (201) or replaces (200) a registered robot, from a model or a
/// URDF document; a `name` in the body must match the path. `If-Match` replaces only that version (412 if it
/// changed); `If-None-Match: *` only creates (412 if it exists).
#[utoipa::path(put, path = "/v1/robots/{name}", tag = "robots", request_body(description = REGISTRATION_BODY, content(
        (RobotSpec = "application/json"),
        (UrdfImportBody = "application/vnd.kinserve.urdf-import+json"),
        (String = "application/xml", example = json!(PLANAR_URDF_EXAMPLE)),
        (String = "text/xml", example = json!(PLANAR_URDF_EXAMPLE)))),
    params(("name" = String, Path, description = "Robot name"), ReplaceParams,
        ("If-Match" = Option<String>, Header, description = "Replace only if the robot is at this version: its `ETag` (`\"17\"`), a list of them, or `*` (it must exist)"),
        ("If-None-Match" = Option<String>, Header, description = "`*`: create only; 412 if the robot exists")),
    security((), ("bearer" = [])),
    responses((status = 200, body = RobotSpec, headers(("ETag" = String, description = "Entity tag of the version written"),
            ("Last-Modified" = String, description = "When it was written"))),
        (status = 201, body = RobotSpec, headers(("Location" = String, description = "The robot's URL"),
            ("ETag" = String, description = "Entity tag of the version written"),
            ("Last-Modified" = String, description = "When it was written"))),
        (status = 400, body = Problem, content_type = "application/problem+json"),
        (status = 401, body = Problem, content_type = "application/problem+json"),
        (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 412, body = Problem, content_type = "application/problem+json"),
        (status = 413, body = Problem, content_type = "application/problem+json"),
        (status = 415, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded, timed out, or the registry database is unavailable (Retry-After); nothing was changed, except that a write that timed out may have been committed (read it again)", body = Problem, content_type = "application/problem+json"),
        (status = 507, body = Problem, content_type = "application/problem+json")))]
pub async fn put_robot(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    Client(client): Client,
    headers: HeaderMap,
    query: Result<Query<ReplaceParams>, QueryRejection>,
    body: RobotBody,
) -> ApiResult<Response> {
    let Query(params) = query.map_err(|e| Error::malformed_field("query", e.body_text()))?;
    let cond = write_condition(&headers, true)?;
    let spec =
        import::robot_spec((&state.service, client), body, params.into(), Some(&name)).await?;
    let (entry, was_created) = state.service.register(spec, PutMode::Upsert, cond).await?;
    Ok(created(&name, was_created, &entry))
}

/// Deletes a registered robot (204); built-ins are read-only (409).
/// `If-Match` deletes only that version (412 if it changed).
#[utoipa::path(delete, path = "/v1/robots/{name}", tag = "robots",
    params(("name" = String, Path, description = "Robot name"),
        ("If-Match" = Option<String>, Header, description = "Delete only if the robot is at this version: its `ETag` (`\"17\"`), a list of them, or `*`")),
    security((), ("bearer" = [])),
    responses((status = 204, description = "Deleted"),
        (status = 400, body = Problem, content_type = "application/problem+json"),
        (status = 401, body = Problem, content_type = "application/problem+json"),
        (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 412, body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded, timed out, or the registry database is unavailable (Retry-After); nothing was changed, except that a write that timed out may have been committed (read it again)", body = Problem, content_type = "application/problem+json"),
        (status = 507, body = Problem, content_type = "application/problem+json")))]
pub async fn delete_robot(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    headers: HeaderMap,
) -> ApiResult<StatusCode> {
    let cond = write_condition(&headers, false)?;
    state.service.delete(&name, cond).await?;
    Ok(StatusCode::NO_CONTENT)
}

/// Forward kinematics of one configuration.
#[utoipa::path(post, path = "/v1/robots/{name}/fk", tag = "fk", request_body = FkRequest,
    params(("name" = String, Path, description = "Robot name")),
    responses((status = 200, body = FkOutput),
        (status = 400, body = Problem, content_type = "application/problem+json"),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 413, body = Problem, content_type = "application/problem+json"),
        (status = 415, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn fk(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    JsonBody(req): JsonBody<FkRequest>,
) -> ApiResult<Response> {
    let entry = state.service.robot(&name)?;
    let robot = &entry.robot;
    let spec = FkSpec::from(req);
    let FkAnswer { pose, frames } = state.service.fk(robot, &spec)?;
    entry.count_poses(Protocol::Rest, 1);
    let reply = FkReply::new(
        robot.name(),
        robot.length_unit(),
        spec.pose_format,
        pose,
        frames.as_deref(),
    );
    let bytes = super::streamed::encoded(1024, |out| reply.write_json(out))?;
    Ok(super::streamed::json_answer(bytes))
}

/// Forward kinematics of many configurations; poses in request order.
///
/// Also in binary: `application/x-protobuf` (gRPC's `ForwardKinematicsBatch`
/// messages) and `application/octet-stream` (packed little-endian float64:
/// `n × dof` joint values in, `n × 12` (`matrix`; `full` is written as
/// `matrix`) or `n × 3` (`position`) numbers out, options as query
/// parameters); `Content-Type` says what the body is, `Accept` what the
/// answer is (default JSON).
#[utoipa::path(post, path = "/v1/robots/{name}/fk/batch", tag = "fk",
    request_body(description = binary::BATCH_BODY, content(
        (FkBatchRequest = "application/json"),
        (binary::Binary = "application/x-protobuf"),
        (binary::Binary = "application/octet-stream"))),
    params(("name" = String, Path, description = "Robot name"), binary::PackedFkQuery),
    responses((status = 200, description = binary::BATCH_ANSWER, content(
            (FkBatchResponse = "application/json"),
            (binary::Binary = "application/x-protobuf"),
            (binary::Binary = "application/octet-stream")),
            headers(("Kinserve-Pose-Format" = String, description = "`application/octet-stream` answers: `matrix` or `position`, the layout of each pose"),
                ("Kinserve-Length-Unit" = String, description = "`application/octet-stream` answers: the robot's length unit (`m` or `mm`)"))),
        (status = 400, body = Problem, content_type = "application/problem+json"),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 406, body = Problem, content_type = "application/problem+json"),
        (status = 413, body = Problem, content_type = "application/problem+json"),
        (status = 415, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn fk_batch(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    Client(client): Client,
    body: BatchBody<FkBatch>,
) -> ApiResult<Response> {
    let entry = state.service.robot(&name)?;
    let answer = body.answer;
    let mut spec = body.spec(&state.service, &entry.robot)?;
    let robot = &entry.robot;
    if answer != Media::Json {
        if answer == Media::Packed {
            // `full` has no packed form: its packed answer is `matrix`.
            spec.pose_format = kinserve_api::packed_format(spec.pose_format);
        }
        let service = &state.service;
        let compute = FkBatchCompute::IN_FORMAT;
        let (poses, _) = service
            .fk_batch_on_pool(client, entry.clone(), spec, compute)
            .await?;
        entry.count_poses(Protocol::Rest, poses.len() as u64);
        return Ok(binary::fk_answer(answer, robot, poses));
    }
    let compute = FkBatchCompute::TRANSFORMS;
    let (poses, spec) = state
        .service
        .fk_batch_on_pool(client, entry.clone(), spec, compute)
        .await?;
    entry.count_poses(Protocol::Rest, poses.len() as u64);
    // Large answers are written a frame at a time as the connection takes them.
    Ok(super::streamed::batch_answer(
        robot.name(),
        robot.length_unit(),
        spec.pose_format,
        poses,
    )?)
}

/// Unknown route: 404 problem.
pub async fn not_found(uri: axum::http::Uri) -> ApiError {
    ApiError(Error::NoRoute {
        path: uri.path().chars().take(200).collect(),
    })
}

/// Known route, unsupported method: 405 problem (axum keeps the `Allow` header).
pub async fn method_not_allowed(method: axum::http::Method, uri: axum::http::Uri) -> Problem {
    Problem::protocol(
        StatusCode::METHOD_NOT_ALLOWED,
        "method-not-allowed",
        "Method not allowed",
        format!(
            "method {method} is not allowed on '{}'",
            uri.path().chars().take(200).collect::<String>()
        ),
    )
}
