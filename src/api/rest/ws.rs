//! `GET /v1/robots/{name}/fk/stream`: FK, Jacobians and IK over a WebSocket,
//! one reply per message, in order.

use axum::extract::State;
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::ws::{CloseFrame, Message, WebSocket, WebSocketUpgrade};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use futures_util::{FutureExt, SinkExt};

use super::AppState;
use super::dto::{WsIdOnly, WsIk, WsJacobian, WsReply, WsRequest};
use super::extract::{RobotName, parse_object};
use super::problem::{ApiError, Problem};
use crate::api::pose_format::{FormattedPose, FormattedPoses, PoseFormat};
use crate::error::Error;
use crate::telemetry::{Protocol, StreamGuard};

/// Close code 1001 "going away" (server shutting down or idle stream).
const GOING_AWAY: u16 = 1001;

/// Opens the FK stream for a robot. Each text message
/// `{"id", "joints", "angle_unit"?, "frames"?, "check_limits"?, "pose_format"?, "jacobian"?, "frame"?}`
/// gets exactly one reply `{"id", "pose", "frames"?}` (plus `jacobian`,
/// `manipulability`, `condition_number`, `singular`, `frame` with
/// `"jacobian": true`) or `{"id", "error": problem}`, in order. A message
/// `{"id", "ik": {IK request}}` gets `{"id", "pose", "joints", "converged",
/// "position_error", "orientation_error", "iterations"}` or an `error` (an
/// unreached target is `ik-not-converged` with the best attempt).
#[utoipa::path(get, path = "/v1/robots/{name}/fk/stream", tag = "fk",
    params(("name" = String, Path, description = "Robot name")),
    responses((status = 101, description = "WebSocket upgrade; messages are WsRequest (FK, with the Jacobian on request, or IK), replies WsReply"),
        (status = 400, description = "Bad path or not a WebSocket handshake", body = Problem, content_type = "application/problem+json"),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 403, description = "The page's origin is not among --cors-origin (only when that is set)", body = Problem, content_type = "application/problem+json"),
        (status = 426, description = "The connection cannot be upgraded", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn stream(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    headers: axum::http::HeaderMap,
    ws: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Result<Response, ApiError> {
    super::check_origin(&headers, &state.settings.cors_origins, false)?;
    state.service.robot(&name)?;
    // A request that is not a valid WebSocket handshake gets a problem, not axum's plain text.
    let ws = match ws {
        Ok(ws) => ws,
        Err(rejection) if rejection.status() == StatusCode::BAD_REQUEST => {
            return Err(Error::Malformed {
                detail: format!("not a WebSocket handshake: {}", rejection.body_text()),
                violations: Vec::new(),
            }
            .into());
        }
        Err(rejection) => {
            return Ok(Problem::protocol(
                rejection.status(),
                "websocket-upgrade",
                "WebSocket upgrade failed",
                rejection.body_text(),
            )
            .into_response());
        }
    };
    let max = state.settings.max_body_bytes;
    Ok(ws
        .max_message_size(max)
        .max_frame_size(max)
        .on_upgrade(move |socket| run(socket, state, name)))
}

async fn close(socket: &mut WebSocket, reason: &'static str) {
    let frame = CloseFrame {
        code: GOING_AWAY,
        reason: reason.into(),
    };
    let _ = socket.send(Message::Close(Some(frame))).await;
}

async fn run(mut socket: WebSocket, state: AppState, name: String) {
    let _stream = StreamGuard::open(Protocol::WebSocket);
    let shutdown = state.shutdown.clone();
    let idle = state.settings.stream_idle_timeout;
    loop {
        let first = tokio::select! {
            _ = shutdown.cancelled() => {
                close(&mut socket, "server shutting down").await;
                return;
            }
            r = tokio::time::timeout(idle, socket.recv()) => match r {
                Err(_) => {
                    close(&mut socket, "idle timeout").await;
                    return;
                }
                Ok(None) | Ok(Some(Err(_))) => return,
                Ok(Some(Ok(m))) => m,
            }
        };
        // Answer this message and every one already received, then flush once:
        // a pipelining client gets its replies in one write instead of one each.
        let mut next = Some(first);
        while let Some(msg) = next.take() {
            let reply = match msg {
                Message::Text(t) => Some(answer(&state, &name, t.as_bytes()).await),
                Message::Binary(_) => Some(error_reply(
                    &serde_json::Value::Null,
                    &Error::UnsupportedMediaType {
                        detail: "binary messages are not supported; send JSON text".into(),
                    },
                )),
                Message::Ping(_) | Message::Pong(_) => None,
                Message::Close(_) => return,
            };
            if let Some(reply) = reply
                && socket.feed(Message::Text(reply.into())).await.is_err()
            {
                return;
            }
            // `recv` is cancel-safe: a message not ready now stays queued.
            next = match socket.recv().now_or_never() {
                Some(Some(Ok(m))) => Some(m),
                Some(None) | Some(Some(Err(_))) => {
                    let _ = socket.flush().await;
                    return;
                }
                None => None,
            };
        }
        if socket.flush().await.is_err() {
            return;
        }
    }
}

fn error_reply(id: &serde_json::Value, e: &Error) -> String {
    crate::telemetry::ws_message(false);
    let reply = WsReply {
        id,
        length_unit: None,
        pose: None,
        frames: None,
        jacobian: None,
        ik: None,
        error: Some(Problem::from_error(e)),
    };
    serde_json::to_string(&reply).unwrap_or_default()
}

/// The reply to one text message.
async fn answer(state: &AppState, name: &str, bytes: &[u8]) -> String {
    let req: WsRequest = match parse_object(bytes) {
        Ok(r) => r,
        Err(e) => {
            let id = serde_json::from_slice::<WsIdOnly>(bytes)
                .map(|x| x.id)
                .unwrap_or_default();
            return error_reply(&id, &e);
        }
    };
    let entry = match state.service.robot(name) {
        Ok(e) => e,
        Err(e) => return error_reply(&req.id, &e),
    };
    if let Some(ik) = req.ik.clone() {
        if req.joints.is_some() {
            let e = Error::invalid_field("joints", "give joints (FK) or ik, not both");
            return error_reply(&req.id, &e);
        }
        return ik_reply(state, entry, &req, ik).await;
    }
    let Some(joints) = req.joints.as_deref() else {
        // As serde reports a missing field (400), naming the alternative.
        let e = Error::malformed_field("joints", "missing field `joints` (or give `ik`)");
        return error_reply(&req.id, &e);
    };
    fk_reply(state, &entry, &req, joints)
}

/// The reply to an IK message.
async fn ik_reply(
    state: &AppState,
    entry: std::sync::Arc<crate::registry::Entry>,
    req: &WsRequest,
    ik: crate::model::IkSpec,
) -> String {
    let length_unit = entry.robot.length_unit();
    match state.service.ik_blocking(entry, ik).await {
        Ok(a) => {
            crate::telemetry::ws_message(true);
            let reply = WsReply {
                id: &req.id,
                length_unit: Some(length_unit),
                pose: Some(FormattedPose::new(PoseFormat::Full, a.pose)),
                frames: None,
                jacobian: None,
                ik: Some(WsIk {
                    joints: a.joints,
                    converged: a.converged,
                    position_error: a.position_error,
                    orientation_error: a.orientation_error,
                    iterations: a.iterations,
                }),
                error: None,
            };
            serde_json::to_string(&reply).unwrap_or_default()
        }
        Err(e) => error_reply(&req.id, &e),
    }
}

/// The reply to an FK message (with the Jacobian when asked for; its pose is
/// then the Jacobian's, as `POST …/jacobian` answers it).
fn fk_reply(
    state: &AppState,
    entry: &crate::registry::Entry,
    req: &WsRequest,
    joints: &[f64],
) -> String {
    let robot = &entry.robot;
    let opts = req.options();
    let (pose, frames) = match state
        .service
        .fk_with_frames(robot, joints, &opts, req.frames)
    {
        Ok(r) => r,
        Err(e) => return error_reply(&req.id, &e),
    };
    let (pose, jacobian) = if req.jacobian {
        match state.service.jacobian(robot, joints, &opts, req.frame) {
            Ok(a) => {
                let item = crate::api::velocity::JacobianItem::from(&a);
                let jacobian = WsJacobian {
                    frame: item.frame,
                    jacobian: item.jacobian,
                    manipulability: item.manipulability,
                    condition_number: item.condition_number,
                    singular: item.singular,
                };
                (a.pose, Some(jacobian))
            }
            Err(e) => return error_reply(&req.id, &e),
        }
    } else {
        (pose, None)
    };
    entry.count_poses(Protocol::WebSocket, 1);
    crate::telemetry::ws_message(true);
    let format = req.pose_format;
    let reply = WsReply {
        id: &req.id,
        length_unit: Some(robot.length_unit()),
        pose: Some(FormattedPose::new(format, pose)),
        frames: frames
            .as_deref()
            .map(|poses| FormattedPoses { format, poses }),
        jacobian,
        ik: None,
        error: None,
    };
    serde_json::to_string(&reply).unwrap_or_default()
}
