//! Statuses for requests tonic rejects before any handler runs, so that they
//! follow the kinserve mapping (`api::grpc::status`) like every other error:
//!
//! * a message over `max_decoding_message_size` is `RESOURCE_EXHAUSTED` (like
//!   REST's 413), not tonic's `OUT_OF_RANGE`;
//! * a message that cannot be decoded (garbage or truncated protobuf, a wrong
//!   wire type, a compressed flag without `grpc-encoding`, no message at all)
//!   is the client's fault: `INVALID_ARGUMENT` (like REST's 400), not tonic's
//!   `INTERNAL`, which kinserve keeps for its own bugs (caught panics) so that
//!   hostile input cannot pass for a server fault in alerts;
//! * an unknown method of the service is `UNIMPLEMENTED` with a message
//!   naming it (tonic sends none).
//!
//! The kinematics service itself never answers `OUT_OF_RANGE` and its own
//! `INTERNAL` messages start with `internal error:` (see
//! [`super::status::code_of`]), so the rewrite cannot catch a handler's
//! answer. [`WireErrorStatuses`] rewrites unary answers; the stream handler
//! maps errors of its inbound messages with [`remap_status`].

use std::task::{Context, Poll};

use futures_util::future::{MapOk, TryFutureExt};
use tonic::body::Body;
use tonic::codegen::http;
use tonic::server::NamedService;
use tonic::{Code, Status};

use super::status::to_status;
use crate::error::Error;

/// Messages tonic (and tonic-prost) give a request message it could not decode.
const DECODE_FAILURES: &[&str] = &[
    "failed to decode Protobuf message",
    "Unexpected EOF decoding stream",
    "protocol error: received message with",
    "Error decompressing",
    "Missing request message",
];

/// The status to send for a decoding error of an inbound message: an
/// oversized message becomes `RESOURCE_EXHAUSTED`, an undecodable one
/// `INVALID_ARGUMENT`; anything else is kept.
pub fn remap_status(status: Status) -> Status {
    match status.code() {
        Code::OutOfRange => to_status(&Error::TooLarge {
            detail: status.message().to_string(),
            field: None,
        }),
        Code::Internal
            if DECODE_FAILURES
                .iter()
                .any(|m| status.message().starts_with(m)) =>
        {
            to_status(&Error::Malformed {
                detail: format!(
                    "the request message cannot be decoded: {}",
                    status.message()
                ),
                violations: Vec::new(),
            })
        }
        _ => status,
    }
}

fn remap_response<S: NamedService>(resp: http::Response<Body>) -> http::Response<Body> {
    let code = resp.headers().get("grpc-status").map(|v| v.as_bytes());
    match code {
        // OUT_OF_RANGE, INTERNAL: maybe a message tonic could not take.
        Some(b"11") | Some(b"13") => match Status::from_header_map(resp.headers()) {
            Some(status) => remap_status(status).into_http(),
            None => resp,
        },
        // UNIMPLEMENTED without a message: a method the service does not have.
        Some(b"12") if !resp.headers().contains_key("grpc-message") => to_status(&Error::NoRoute {
            path: format!("/{}/<unknown method>", S::NAME),
        })
        .into_http(),
        _ => resp,
    }
}

/// Wraps a tonic service so that the answers tonic gives before any handler
/// runs follow the kinserve status mapping (see the module documentation).
#[derive(Clone, Debug)]
pub struct WireErrorStatuses<S>(pub S);

impl<S: NamedService> NamedService for WireErrorStatuses<S> {
    const NAME: &'static str = S::NAME;
}

type Remap = fn(http::Response<Body>) -> http::Response<Body>;

impl<S, B> tower::Service<http::Request<B>> for WireErrorStatuses<S>
where
    S: tower::Service<http::Request<B>, Response = http::Response<Body>> + NamedService,
{
    type Response = http::Response<Body>;
    type Error = S::Error;
    type Future = MapOk<S::Future, Remap>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        self.0.poll_ready(cx)
    }

    fn call(&mut self, req: http::Request<B>) -> Self::Future {
        self.0.call(req).map_ok(remap_response::<S> as Remap)
    }
}
