//! Request extractors that turn every client mistake into a kinserve [`Error`]
//! (so the response is problem+json, never axum's plain-text rejection).

use axum::body::{Bytes, HttpBody};
use axum::extract::{FromRequest, FromRequestParts, Path, Request};
use axum::http::{header, request::Parts};
use axum::response::{IntoResponse, Response};
use futures_util::FutureExt;
use http_body_util::BodyExt;
use serde::de::DeserializeOwned;

use super::AppState;
use super::problem::ApiError;
use crate::compute::ClientId;
use crate::error::Error;
use crate::model::{Configurations, parse_json, parse_json_rows, parse_json_values};

/// A JSON body parsed with field paths. Checks the content type (415), the
/// body size (413: the batch limit on the routes admitted as batches, the
/// body limit elsewhere; see [`super::Admission`])
/// and the JSON (400 / 422).
pub struct JsonBody<T>(pub T);

impl<T: DeserializeOwned> FromRequest<AppState> for JsonBody<T> {
    type Rejection = Response;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, Self::Rejection> {
        let unread = super::has_body(req.headers());
        Self::read(req, state).await.map_err(|e| refusal(unread, e))
    }
}

/// The answer to a body refused with `e`; refused before the whole body was
/// read (`unread` and a 415 or 413), the connection is closed after it.
pub(super) fn refusal(unread: bool, e: Error) -> Response {
    let early = matches!(
        e,
        Error::UnsupportedMediaType { .. } | Error::TooLarge { .. }
    );
    super::refuse_unread(unread && early, ApiError(e).into_response())
}

impl<T: DeserializeOwned> JsonBody<T> {
    async fn read(req: Request, state: &AppState) -> Result<Self, Error> {
        let content_type = content_type(&req);
        if !is_json(content_type) {
            return Err(Error::UnsupportedMediaType {
                detail: format!(
                    "expected Content-Type application/json, got '{}'",
                    content_type.chars().take(100).collect::<String>()
                ),
            });
        }
        let bytes = read_bytes(req, state).await?;
        Ok(JsonBody(parse_object(&bytes)?))
    }
}

/// The request's `Content-Type` (empty when absent or not visible ASCII).
pub(super) fn content_type(req: &Request) -> &str {
    req.headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
}

/// The whole body, uncompressed, within the route's limit (413 beyond: the
/// batch limit on the routes admitted as batches, the body limit elsewhere).
pub(super) async fn read_bytes(req: Request, state: &AppState) -> Result<Bytes, Error> {
    // No request compression is supported: a compressed body is refused
    // as such (RFC 9110 §15.5.16), never decoded (no gzip bombs) nor parsed.
    if let Some(coding) = req.headers().get(header::CONTENT_ENCODING) {
        let coding = coding.to_str().unwrap_or("?").trim();
        if !coding.eq_ignore_ascii_case("identity") {
            return Err(Error::UnsupportedMediaType {
                detail: format!(
                    "Content-Encoding '{}' is not supported; send the body uncompressed",
                    coding.chars().take(100).collect::<String>()
                ),
            });
        }
    }
    let admission = req
        .extensions()
        .get::<super::Admission>()
        .copied()
        .unwrap_or_default();
    let limit = super::buffered::body_limit(admission, &state.settings);
    let mut body = req.into_body();
    // A body the admission read ahead is one piece in memory: taken as it is
    // (no collector, no copy). Anything else is collected within the limit.
    let first = match body.frame().now_or_never() {
        None => Bytes::new(),
        Some(None) => return Ok(Bytes::new()),
        Some(Some(frame)) => frame
            .map_err(|e| super::buffered::unreadable(&e, limit))?
            .into_data()
            .unwrap_or_default(),
    };
    if first.len() > limit {
        return Err(super::buffered::too_large(limit));
    }
    if body.is_end_stream() {
        return Ok(first);
    }
    let rest = axum::body::to_bytes(body, limit - first.len())
        .await
        .map_err(|e| super::buffered::unreadable(&e, limit))?;
    if first.is_empty() {
        return Ok(rest);
    }
    Ok([&first[..], &rest[..]].concat().into())
}

/// Whether a `Content-Type` value is JSON: `application/json` or
/// `application/<anything>+json`, any case, parameters ignored.
pub(super) fn is_json(content_type: &str) -> bool {
    if content_type == "application/json" {
        return true; // what nearly every client sends
    }
    let mime = content_type.split(';').next().unwrap_or("").trim();
    let Some((kind, sub)) = mime.split_once('/') else {
        return false;
    };
    kind.eq_ignore_ascii_case("application")
        && (sub.eq_ignore_ascii_case("json")
            || sub
                .len()
                .checked_sub(5)
                .and_then(|i| sub.get(i..))
                .is_some_and(|tail| tail.eq_ignore_ascii_case("+json")))
}

/// Parses a JSON object into `T` (see [`parse_json`]). A top-level array is
/// refused as a wrong type: serde would otherwise read a struct from an array
/// of its fields in declaration order (`[[0, 0]]` as `{"joints": [0, 0]}`).
pub fn parse_object<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, Error> {
    refuse_array(bytes)?;
    Ok(parse_json(bytes)?)
}

/// [`parse_object`] of a batch body, its `configurations` read by the fast
/// path of [`parse_json_rows`] (the same value and errors; reading a
/// 10,000-row body took about a third less time, BENCHMARKS.md) and put
/// where `rows` says.
pub fn parse_object_rows<T: DeserializeOwned>(
    bytes: &[u8],
    rows: impl FnOnce(&mut T) -> &mut Configurations,
) -> Result<T, Error> {
    refuse_array(bytes)?;
    Ok(parse_json_rows(bytes, "configurations", rows)?)
}

/// [`parse_object`] of a body with one joint vector under `joints`, read
/// by the fast path of [`parse_json_values`] (the same value and errors; the
/// numbers were most of a WebSocket message's parse, BENCHMARKS.md) and put
/// where `joints` says.
pub fn parse_object_joints<T: DeserializeOwned>(
    bytes: &[u8],
    joints: impl FnOnce(&mut T) -> &mut Vec<f64>,
) -> Result<T, Error> {
    refuse_array(bytes)?;
    Ok(parse_json_values(bytes, "joints", joints)?)
}

/// A top-level array as a wrong type (see [`parse_object`]).
fn refuse_array(bytes: &[u8]) -> Result<(), Error> {
    let first = bytes
        .iter()
        .find(|b| !matches!(b, b' ' | b'\t' | b'\n' | b'\r'));
    if first == Some(&b'[') {
        return Err(Error::Malformed {
            detail: "invalid type: array, expected a JSON object".into(),
            violations: Vec::new(),
        });
    }
    Ok(())
}

/// The `{name}` path segment of a robot route.
pub struct RobotName(pub String);

impl FromRequestParts<AppState> for RobotName {
    type Rejection = ApiError;

    async fn from_request_parts(
        parts: &mut Parts,
        state: &AppState,
    ) -> Result<Self, Self::Rejection> {
        let Path(name) = Path::<String>::from_request_parts(parts, state)
            .await
            .map_err(|e| Error::malformed_field("name", format!("bad robot name in path: {e}")))?;
        Ok(RobotName(name))
    }
}

/// The request's client, for the per-client shares: what the admission middleware
/// resolved from the peer address (and `X-Forwarded-For` behind a trusted
/// proxy); [`ClientId::UNKNOWN`] when the transport gave no address.
pub struct Client(pub ClientId);

impl<S: Send + Sync> FromRequestParts<S> for Client {
    type Rejection = std::convert::Infallible;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, Self::Rejection> {
        Ok(Client(
            parts
                .extensions
                .get::<ClientId>()
                .copied()
                .unwrap_or(ClientId::UNKNOWN),
        ))
    }
}

/// The peer address of a connection, put in every request's extensions by the transport.
#[derive(Clone, Copy, Debug)]
pub struct PeerAddr(pub std::net::SocketAddr);
