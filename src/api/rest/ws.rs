//! `GET /v1/robots/{name}/fk/stream`: FK, Jacobians and IK over a WebSocket,
//! one reply per message, in order.

use std::time::Duration;

use axum::Extension;
use axum::extract::State;
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::ws::{CloseFrame, Message, WebSocket, WebSocketUpgrade};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use futures_util::{FutureExt, SinkExt};
use tokio::time::Instant;

use super::AppState;
use super::dto::{WsIdOnly, WsIk, WsIkPath, WsJacobian, WsReply, WsRequest};
use super::extract::{Client, RobotName, parse_object_joints};
use super::problem::{ApiError, Problem};
use crate::api::budget::{ConnectionStreams, StreamPermit};
use crate::api::pose_format::{self, PoseFormat};
use crate::compute::ClientId;
use crate::error::Error;
use crate::model::{LengthUnit, StreamOp};
use crate::service::{RobotCache, StreamAnswer};
use crate::telemetry::{Protocol, StreamGuard};

/// Close code 1001 "going away" (server shutting down or idle stream).
const GOING_AWAY: u16 = 1001;

/// Close code 1009 "message too big" (a message over `--max-body-bytes`).
const TOO_BIG: u16 = 1009;

/// Longest a close frame may wait to go out (the client may not be reading).
const CLOSE_TIMEOUT: Duration = Duration::from_secs(1);

/// Read buffer of a socket, allocated when it opens (tungstenite's default,
/// 128 KiB, made 2,000 idle sockets cost 250 MB). Bigger frames still arrive
/// whole: the buffer grows for them and they are read in pieces this size.
const READ_BUFFER: usize = 8 << 10;

/// Replies are written out once this much is queued (or at the end of a
/// batch of replies, whichever comes first).
const WRITE_BUFFER: usize = 8 << 10;

/// Opens the FK stream for a robot. Each text message
/// `{"id", "joints", "angle_unit"?, "frames"?, "check_limits"?, "pose_format"?, "jacobian"?, "frame"?}`
/// gets exactly one reply `{"id", "pose", "frames"?}` (plus `jacobian`,
/// `manipulability`, `condition_number`, `singular`, `frame` with
/// `"jacobian": true`) or `{"id", "error": problem}`, in order. A message
/// `{"id", "ik": {IK request}}` gets `{"id", "pose", "joints", "converged",
/// "position_error", "orientation_error", "iterations"}` or an `error` (an
/// unreached target is `ik-not-converged` with the best attempt).
///
/// A socket counts against the open-streams budget (`--max-streams`, and
/// `--max-streams-per-connection` on HTTP/2); past it the upgrade is refused
/// with 503. A message over `--max-body-bytes` (whole or being assembled
/// from fragments) closes the socket with 1009; a socket with no data
/// message from the client and no reply taken for `--stream-idle-timeout`
/// closes with 1001 (pings do not count).
#[utoipa::path(get, path = "/v1/robots/{name}/fk/stream", tag = "fk",
    params(("name" = String, Path, description = "Robot name")),
    responses((status = 101, description = "WebSocket upgrade; messages are WsRequest (FK, with the Jacobian on request, or IK), replies WsReply"),
        (status = 400, description = "Bad path or not a WebSocket handshake", body = Problem, content_type = "application/problem+json"),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 403, description = "The page's origin is not among --cors-origin (only when that is set)", body = Problem, content_type = "application/problem+json"),
        (status = 426, description = "The connection cannot be upgraded", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded (requests in flight or open streams), or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn stream(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    Client(client): Client,
    headers: axum::http::HeaderMap,
    connection: Option<Extension<ConnectionStreams>>,
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
    // The stream's budget slot, taken before upgrading: past the budget the
    // client gets 503 + Retry-After, not a socket that closes at once.
    let permit = state
        .streams
        .try_open(connection.as_ref().map(|Extension(c)| c), client)
        .inspect_err(|_| {
            metrics::counter!("kinserve_http_rejected_total", "reason" => "streams").increment(1);
        })?;
    let max = state.settings.max_body_bytes;
    // A child of the upgrade request's span, carried into the stream's task.
    let stream = crate::telemetry::spans::stream_span("websocket");
    Ok(ws
        .read_buffer_size(READ_BUFFER)
        .write_buffer_size(WRITE_BUFFER)
        // A reply echoes the message's id (up to `max`) beside the pose and
        // frames: room for two of them; the buffer only grows when used.
        .max_write_buffer_size(WRITE_BUFFER + 2 * max + (1 << 20))
        .max_message_size(max)
        .max_frame_size(max)
        .on_upgrade(move |socket| {
            tracing::Instrument::instrument(
                run(
                    socket,
                    state,
                    Target {
                        name,
                        client,
                        robots: RobotCache::default(),
                    },
                    permit,
                ),
                stream,
            )
        }))
}

/// Sends a close frame, if the client takes it within [`CLOSE_TIMEOUT`].
async fn close(socket: &mut WebSocket, code: u16, reason: &'static str) {
    let frame = CloseFrame {
        code,
        reason: reason.into(),
    };
    let _ = tokio::time::timeout(CLOSE_TIMEOUT, socket.send(Message::Close(Some(frame)))).await;
}

/// Ends a socket whose read failed: an oversized message (whole or being
/// assembled) gets close 1009; other errors (invalid frames, I/O) just end it.
async fn read_failed(socket: &mut WebSocket, e: axum::Error) {
    let too_big = e
        .into_inner()
        .downcast::<tungstenite::Error>()
        .is_ok_and(|e| matches!(*e, tungstenite::Error::Capacity(_)));
    if too_big {
        close(socket, TOO_BIG, "message too big").await;
    }
}

/// What a received message asks of the loop.
enum Step {
    /// A reply to send (the message was data: progress).
    Reply(String),
    /// Nothing to send (a ping or pong: not progress).
    Nothing,
    /// The client closed.
    End,
}

/// What a socket streams for: the robot and the client (whose share of the
/// compute pool its IK messages take).
struct Target {
    name: String,
    client: ClientId,
    /// The robot's entry, looked up once per registry change.
    robots: RobotCache,
}

async fn step(state: &AppState, target: &mut Target, msg: Message) -> Step {
    match msg {
        Message::Text(t) => Step::Reply(answer(state, target, t.as_bytes()).await),
        Message::Binary(_) => Step::Reply(error_reply(
            &serde_json::Value::Null,
            &Error::UnsupportedMediaType {
                detail: "binary messages are not supported; send JSON text".into(),
            },
        )),
        Message::Ping(_) | Message::Pong(_) => Step::Nothing,
        Message::Close(_) => Step::End,
    }
}

async fn run(mut socket: WebSocket, state: AppState, mut target: Target, permit: StreamPermit) {
    let _permit = permit;
    let _stream = StreamGuard::open(Protocol::WebSocket);
    let shutdown = state.shutdown.clone();
    let idle = state.settings.stream_idle_timeout;
    // Progress in either direction (a data message from the client, replies
    // taken by it) moves the deadline; pings and pongs do not. A socket that
    // sends nothing at first is closed after the (shorter) first-message timeout.
    let mut deadline = Instant::now() + idle.min(state.settings.stream_first_message_timeout);
    loop {
        let first = tokio::select! {
            _ = shutdown.cancelled() => {
                close(&mut socket, GOING_AWAY, "server shutting down").await;
                return;
            }
            _ = tokio::time::sleep_until(deadline) => {
                close(&mut socket, GOING_AWAY, "idle timeout").await;
                return;
            }
            r = socket.recv() => match r {
                None => return,
                Some(Err(e)) => return read_failed(&mut socket, e).await,
                Some(Ok(m)) => m,
            }
        };
        // Writing the answers must finish within the idle timeout from the
        // message (a client that does not read makes no progress); after a
        // ping, within what is left of it.
        let send_by = match first {
            Message::Ping(_) | Message::Pong(_) => deadline,
            _ => Instant::now() + idle,
        };
        match answer_pending(&mut socket, &state, &mut target, first, send_by).await {
            Some(true) => deadline = Instant::now() + idle,
            Some(false) => {}
            None => return,
        }
    }
}

/// Answers `first` and every message already received, then flushes once
/// (a pipelining client gets its replies in one write instead of one each).
/// Writing must finish by `send_by`. `Some(true)` when replies went out,
/// `Some(false)` when there was nothing to answer (pings), `None` when the
/// socket is done.
async fn answer_pending(
    socket: &mut WebSocket,
    state: &AppState,
    target: &mut Target,
    first: Message,
    send_by: Instant,
) -> Option<bool> {
    let mut replied = false;
    let mut next = Some(first);
    while let Some(msg) = next.take() {
        match step(state, target, msg).await {
            Step::Reply(reply) => {
                replied = true;
                let fed =
                    tokio::time::timeout_at(send_by, socket.feed(Message::Text(reply.into())));
                if !matches!(fed.await, Ok(Ok(()))) {
                    return None;
                }
            }
            Step::Nothing => {}
            Step::End => {
                // tungstenite queued the reply to the client's close frame
                // (its code echoed); it goes out with the flush.
                let _ = tokio::time::timeout_at(send_by, socket.flush()).await;
                return None;
            }
        }
        // `recv` is cancel-safe: a message not ready now stays queued.
        next = match socket.recv().now_or_never() {
            Some(Some(Ok(m))) => Some(m),
            Some(None) => None,
            Some(Some(Err(e))) => {
                let _ = tokio::time::timeout_at(send_by, socket.flush()).await;
                read_failed(socket, e).await;
                return None;
            }
            None => None,
        };
    }
    match tokio::time::timeout_at(send_by, socket.flush()).await {
        Ok(Ok(())) => Some(replied),
        _ => None,
    }
}

fn error_reply(id: &serde_json::Value, e: &Error) -> String {
    crate::telemetry::ws_message(false);
    let reply = WsReply {
        error: Some(Problem::from_error(e)),
        ..WsReply::empty(id)
    };
    reply_text(&reply, REPLY_CAPACITY)
}

/// Bytes reserved for a reply to one configuration: an FK answer in the
/// `full` format is ~400 bytes, so the text is written without regrowing
/// (`serde_json::to_string` starts at 128 and doubles: two copies). A reply
/// to many configurations reserves what the REST batch answer does.
const REPLY_CAPACITY: usize = 512;

/// `reply` as JSON text, written into `capacity` bytes reserved up front.
fn reply_text(reply: &WsReply<'_>, capacity: usize) -> String {
    super::streamed::json_vec(reply, capacity)
        .ok()
        .and_then(|bytes| String::from_utf8(bytes).ok())
        .unwrap_or_default()
}

/// Where a message's `joints` go (present whenever the fast path read them).
fn ws_joints(r: &mut WsRequest) -> &mut Vec<f64> {
    r.joints.get_or_insert_with(Vec::new)
}

/// The reply to one text message: parsed into the protocol-neutral
/// [`StreamOp`], answered by [`Service::stream_step`](crate::service::Service::stream_step)
/// (the same step as the gRPC stream's), written as JSON.
async fn answer(state: &AppState, target: &mut Target, bytes: &[u8]) -> String {
    let mut req: WsRequest = match parse_object_joints(bytes, ws_joints) {
        Ok(r) => r,
        Err(e) => {
            let id = serde_json::from_slice::<WsIdOnly>(bytes)
                .map(|x| x.id)
                .unwrap_or_default();
            return error_reply(&id, &e);
        }
    };
    let id = std::mem::take(&mut req.id);
    if let Some(c) = &req.configurations
        && let Err(e) = state.service.check_batch_size(c.len())
    {
        return error_reply(&id, &e);
    }
    let op = match StreamOp::try_from(req) {
        Ok(op) => op,
        Err(e) => return error_reply(&id, &e.into()),
    };
    let entry = match state
        .service
        .robot_cached(&mut target.robots, &target.name, "name")
    {
        Ok(e) => e,
        Err(e) => return error_reply(&id, &e),
    };
    let length_unit = entry.robot.length_unit();
    match state
        .service
        .stream_step(entry, op, Protocol::WebSocket, target.client)
        .await
    {
        Ok(answer) => {
            crate::telemetry::ws_message(true);
            ok_reply(&id, length_unit, &answer)
        }
        Err(e) => error_reply(&id, &e),
    }
}

/// A successful reply: FK (pose and frames in the message's format, with the
/// Jacobian and the operations on one configuration when asked for) or IK (always the full pose).
fn ok_reply(id: &serde_json::Value, length_unit: LengthUnit, answer: &StreamAnswer) -> String {
    let capacity = match answer {
        // As the REST batch answer reserves it.
        StreamAnswer::FkBatch { poses, pose_format } => {
            super::streamed::answer_capacity(*pose_format, poses.len())
        }
        _ => REPLY_CAPACITY,
    };
    let reply = match answer {
        // Many configurations: in the field `POST …/fk/batch` uses.
        StreamAnswer::FkBatch { poses, pose_format } => {
            let p = pose_format::many(*pose_format, Some(poses));
            WsReply {
                length_unit: Some(length_unit),
                poses: p.full,
                matrices: p.matrix,
                positions: p.position,
                ..WsReply::empty(id)
            }
        }
        StreamAnswer::IkPath(a) => WsReply {
            length_unit: Some(length_unit),
            ik_path: Some(WsIkPath {
                points: a.points.clone(),
                fraction: a.fraction,
                waypoints_reached: a.waypoints_reached,
                stop: a.stop.clone(),
            }),
            ..WsReply::empty(id)
        },
        StreamAnswer::Ik(a) => WsReply {
            ik: Some(WsIk::from(a)),
            ..WsReply::posed(id, length_unit, PoseFormat::Full, a.pose, None)
        },
        StreamAnswer::Fk {
            fk,
            pose_format,
            jacobian,
            ops,
        } => WsReply {
            jacobian: jacobian.as_ref().map(WsJacobian::from),
            ops: ops.clone(),
            ..WsReply::posed(id, length_unit, *pose_format, fk.pose, fk.frames.as_deref())
        },
    };
    reply_text(&reply, capacity)
}
