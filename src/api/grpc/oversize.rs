//! Messages over the size limit are RESOURCE_EXHAUSTED (like REST's 413), not
//! tonic's OUT_OF_RANGE.
//!
//! tonic rejects a request message over `max_decoding_message_size` with
//! `OUT_OF_RANGE` ("decoded message length too large") before any handler
//! runs. The kinematics service itself never answers `OUT_OF_RANGE` (see
//! [`super::status::code_of`]), so on its routes that code can only mean an
//! oversized message; [`OversizedIsResourceExhausted`] rewrites it. The stream
//! handler maps the same error from its inbound messages with [`remap_status`].

use std::task::{Context, Poll};

use futures_util::future::{MapOk, TryFutureExt};
use tonic::body::Body;
use tonic::codegen::http;
use tonic::server::NamedService;
use tonic::{Code, Status};

use super::status::to_status;
use crate::error::Error;

/// The status to send for a decoding error of an inbound message: an
/// oversized message becomes `RESOURCE_EXHAUSTED`; anything else is kept.
pub fn remap_status(status: Status) -> Status {
    if status.code() == Code::OutOfRange {
        to_status(&Error::TooLarge {
            detail: status.message().to_string(),
            field: None,
        })
    } else {
        status
    }
}

fn remap_response(resp: http::Response<Body>) -> http::Response<Body> {
    let out_of_range = resp
        .headers()
        .get("grpc-status")
        .is_some_and(|v| v.as_bytes() == b"11");
    if !out_of_range {
        return resp;
    }
    match Status::from_header_map(resp.headers()) {
        Some(status) => remap_status(status).into_http(),
        None => resp,
    }
}

/// Wraps a tonic service so that `OUT_OF_RANGE` answers (tonic's "message too
/// large") go out as `RESOURCE_EXHAUSTED`.
#[derive(Clone, Debug)]
pub struct OversizedIsResourceExhausted<S>(pub S);

impl<S: NamedService> NamedService for OversizedIsResourceExhausted<S> {
    const NAME: &'static str = S::NAME;
}

type Remap = fn(http::Response<Body>) -> http::Response<Body>;

impl<S, B> tower::Service<http::Request<B>> for OversizedIsResourceExhausted<S>
where
    S: tower::Service<http::Request<B>, Response = http::Response<Body>>,
{
    type Response = http::Response<Body>;
    type Error = S::Error;
    type Future = MapOk<S::Future, Remap>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        self.0.poll_ready(cx)
    }

    fn call(&mut self, req: http::Request<B>) -> Self::Future {
        self.0.call(req).map_ok(remap_response as Remap)
    }
}
