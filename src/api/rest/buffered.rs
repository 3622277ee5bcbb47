//! Request bodies read before admission, and response bodies held against the
//! response byte budget.
//!
//! **Requests.** A request's body is read whole, before the request takes a
//! permit (so a client that announces a body and never sends it holds no
//! permit), under three bounds: the route's size limit (413), the request
//! byte budget shared by all requests being read (503 `overloaded`), and time:
//! no piece of the body for `--body-timeout`, or the whole body not there
//! within `--request-timeout`, is 408 and the connection is closed.
//!
//! **Responses.** An answer of [`UNCOUNTED_BYTES`] or more holds its size from
//! the response byte budget until the connection has taken its last frame (or
//! dropped it); an answer that does not fit is dropped and 503 `overloaded` is
//! sent instead. Counted answers are handed to the connection in frames of at
//! most [`FRAME_BYTES`], each marking progress on the connection (see
//! [`super::conn`]), so a client that takes nothing is found out even on
//! HTTP/2, where flow control stops a stream without any write blocking.
//! A large FK batch answer is produced a frame at a time (see
//! [`super::streamed`]) and counts what its [`Holds`] extension says (its
//! poses and what may be in flight), not its JSON size. This module does not
//! depend on [`super::streamed`] (which depends on it).

use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use tracing::Instrument;

use axum::body::{Body, Bytes, HttpBody};
use axum::extract::Request;
use axum::http::{Method, header};
use axum::response::{IntoResponse, Response};
use futures_util::FutureExt;
use http_body::{Frame, SizeHint};
use http_body_util::BodyExt;
use tokio::time::Instant;

use super::body_budget::Reservation;
use super::conn::{BodyTicket, ConnActivity};
use super::problem::ApiError;
use super::{Admission, AppState, refuse_unread};
use crate::api::budget::{request_bytes_refusal, response_bytes_refusal};
use crate::error::Error;

/// Answers smaller than this are not counted against the response budget
/// (they fit a socket buffer; counting them would let large answers starve
/// small ones).
pub const UNCOUNTED_BYTES: usize = 64 << 10;

/// Largest frame a counted answer is handed to the connection in.
pub const FRAME_BYTES: usize = 64 << 10;

/// The memory a streamed answer keeps until its last frame is taken, in
/// bytes: a response extension (set by [`super::streamed`]) that
/// [`hold_response`] counts instead of the body's size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Holds(pub usize);

/// Whether the body of `req` is read ahead: it has one (not an upgrade or
/// CONNECT, whose "body" is the stream that follows).
fn read_ahead(req: &Request) -> bool {
    req.method() != Method::CONNECT
        && !req.headers().contains_key(header::UPGRADE)
        && !req.body().is_end_stream()
}

/// The refusal for `e` before the body was read whole: the connection closes after it.
fn refuse(e: Error) -> Response {
    if matches!(e, Error::Overloaded { .. }) {
        metrics::counter!("kinserve_http_rejected_total", "reason" => "request_bytes").increment(1);
    }
    refuse_unread(true, ApiError(e).into_response())
}

pub(super) fn too_large(limit: usize) -> Error {
    Error::TooLarge {
        detail: format!("request body is over the limit of {limit} bytes"),
        field: None,
    }
}

/// Reads the body of `req` (when it has one) within the limit of the route's
/// admission, the request byte budget and the body timeouts; returns the
/// request with the body in memory and the budget it holds, or the refusal to send.
pub async fn read_body(
    req: Request,
    state: &AppState,
    admission: Admission,
) -> Result<(Request, Option<Reservation>), Response> {
    if !read_ahead(&req) {
        return Ok((req, None));
    }
    let limit = body_limit(admission, &state.settings);
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<usize>().ok());
    if declared.is_some_and(|n| n > limit) {
        return Err(refuse(too_large(limit)));
    }
    let expected = declared.unwrap_or(0);
    let Some(mut held) = state.budgets().request.try_reserve(expected) else {
        return Err(refuse(request_bytes_refusal()));
    };
    let (parts, body) = req.into_parts();
    let bytes = collect(body, expected, limit, &mut held, state)
        .instrument(crate::trace_span!("read body"))
        .await
        .map_err(refuse)?;
    Ok((Request::from_parts(parts, Body::from(bytes)), Some(held)))
}

/// The body's bytes, each piece within the idle timeout and all within the
/// request timeout, counted in `held`.
async fn collect(
    mut body: Body,
    expected: usize,
    limit: usize,
    held: &mut Reservation,
    state: &AppState,
) -> Result<Bytes, Error> {
    let idle = state.settings.body_timeout;
    let deadline = Instant::now() + state.settings.request_timeout;
    let mut buf: Vec<u8> = Vec::with_capacity(expected.min(limit));
    loop {
        // A piece already received is taken without arming a timer (a small
        // body usually arrives with its head); only a wait is timed.
        let next = match body.frame().now_or_never() {
            Some(next) => next,
            None => {
                let until = (Instant::now() + idle).min(deadline);
                match tokio::time::timeout_at(until, body.frame()).await {
                    Err(_) => return Err(stalled(idle, state)),
                    Ok(next) => next,
                }
            }
        };
        let frame = match next {
            None => break,
            Some(Err(e)) => return Err(unreadable(&e, limit)),
            Some(Ok(frame)) => frame,
        };
        let Ok(data) = frame.into_data() else {
            continue;
        };
        if buf.len().saturating_add(data.len()) > limit {
            return Err(too_large(limit));
        }
        if buf.is_empty() && body.is_end_stream() {
            // The whole body in one piece: kept as it is, not copied.
            if !held.grow_to(data.len()) {
                return Err(request_bytes_refusal());
            }
            return Ok(data);
        }
        if !held.grow_to(buf.len() + data.len()) {
            return Err(request_bytes_refusal());
        }
        buf.extend_from_slice(&data);
        if !held.grow_to(buf.capacity()) {
            return Err(request_bytes_refusal());
        }
    }
    Ok(Bytes::from(buf))
}

fn stalled(idle: std::time::Duration, state: &AppState) -> Error {
    metrics::counter!("kinserve_http_rejected_total", "reason" => "body_timeout").increment(1);
    Error::RequestTimeout {
        detail: format!(
            "the request body did not arrive in time (at most {} s between two reads, {} s in all)",
            idle.as_secs_f64(),
            state.settings.request_timeout.as_secs_f64()
        ),
    }
}

/// The largest body a route takes: the batch limit on the routes admitted as
/// batches, the body limit elsewhere.
pub(super) fn body_limit(admission: Admission, settings: &super::RestSettings) -> usize {
    match admission {
        Admission::Batch => settings.max_batch_body_bytes,
        Admission::Single => settings.max_body_bytes,
    }
}

/// A body that could not be read: 413 when it was over `limit`, else 400.
pub(super) fn unreadable(e: &axum::Error, limit: usize) -> Error {
    let over = std::error::Error::source(e)
        .is_some_and(|s| s.is::<http_body_util::LengthLimitError>())
        || e.to_string().contains("length limit");
    if over {
        return too_large(limit);
    }
    Error::Malformed {
        detail: format!("could not read the request body: {e}"),
        violations: Vec::new(),
    }
}

/// Counts a large answer against the response budget (503 `overloaded`
/// instead when it does not fit) and hands it out in frames that mark
/// progress on the connection.
pub fn hold_response(
    resp: Response,
    state: &AppState,
    conn: Option<Arc<ConnActivity>>,
) -> Response {
    let size = match resp.extensions().get::<Holds>() {
        Some(holds) => holds.0,
        None => {
            let hint = resp.body().size_hint();
            let Ok(size) = usize::try_from(hint.exact().unwrap_or(hint.lower())) else {
                return resp;
            };
            size
        }
    };
    if size < UNCOUNTED_BYTES {
        return resp;
    }
    let Some(held) = state.budgets().response.try_reserve(size) else {
        metrics::counter!("kinserve_http_rejected_total", "reason" => "response_bytes")
            .increment(1);
        tracing::debug!(
            bytes = size,
            "answer dropped: the response byte budget is spent"
        );
        return ApiError(response_bytes_refusal()).into_response();
    };
    let ticket = conn.map(|c| c.body());
    resp.map(|body| {
        Body::new(HeldBody {
            inner: body,
            rest: None,
            held: Arc::new(held),
            ticket,
        })
    })
}

/// A response body that holds its budget until its last byte is gone and
/// hands out frames of at most [`FRAME_BYTES`].
///
/// The budget is released only when the body *and* every frame it handed out
/// are dropped: the connection keeps frames queued until the kernel took
/// them, and the frames share the answer's one allocation, so the bytes are
/// in memory until then.
struct HeldBody {
    inner: Body,
    rest: Option<Bytes>,
    held: Arc<Reservation>,
    ticket: Option<BodyTicket>,
}

/// The bytes of a frame and the budget they hold, for `Bytes::from_owner`.
struct Owned {
    data: Bytes,
    _held: Arc<Reservation>,
}

impl AsRef<[u8]> for Owned {
    fn as_ref(&self) -> &[u8] {
        &self.data
    }
}

impl HeldBody {
    /// `data` from the inner body, holding the budget for as long as any
    /// piece of it lives.
    fn own(&self, data: Bytes) -> Bytes {
        Bytes::from_owner(Owned {
            data,
            _held: self.held.clone(),
        })
    }

    /// The next piece of `data` (at most [`FRAME_BYTES`]), keeping the rest.
    fn piece(&mut self, mut data: Bytes) -> Frame<Bytes> {
        if data.len() > FRAME_BYTES {
            self.rest = Some(data.split_off(FRAME_BYTES));
        }
        if let Some(t) = &self.ticket {
            t.progress();
        }
        Frame::data(data)
    }
}

impl HttpBody for HeldBody {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        let this = self.get_mut();
        if let Some(rest) = this.rest.take() {
            return Poll::Ready(Some(Ok(this.piece(rest))));
        }
        match Pin::new(&mut this.inner).poll_frame(cx) {
            Poll::Ready(Some(Ok(frame))) => match frame.into_data() {
                Ok(data) => {
                    let data = this.own(data);
                    Poll::Ready(Some(Ok(this.piece(data))))
                }
                Err(other) => Poll::Ready(Some(Ok(other))),
            },
            other => other,
        }
    }

    fn is_end_stream(&self) -> bool {
        self.rest.is_none() && self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        let rest = self.rest.as_ref().map_or(0, |r| r.len() as u64);
        let inner = self.inner.size_hint();
        let mut hint = SizeHint::new();
        hint.set_lower(inner.lower().saturating_add(rest));
        if let Some(upper) = inner.upper() {
            hint.set_upper(upper.saturating_add(rest));
        }
        hint
    }
}
