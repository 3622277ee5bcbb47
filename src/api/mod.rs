//! Front doors: thin adapters from REST and gRPC to [`crate::service::Service`].
//!
//! Everything here handles untrusted input, so a panic on request data is
//! ruled out by lint: no `unwrap`, `expect` or unchecked indexing/slicing
//! (tests are exempt).

#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::indexing_slicing,
        clippy::panic,
        clippy::unreachable,
        clippy::todo,
        clippy::unimplemented
    )
)]

use crate::error::Error;

pub mod budget;
pub mod grpc;
pub mod ik;
pub mod jacobian;
pub mod pose;
pub mod pose_format;
pub mod pose_json;
pub mod rest;
pub mod urdf_import;

/// The error a caught panic is answered with, on every front door: logs the
/// panic's message (`what` says where) and returns [`Error::Internal`], whose
/// text says it is a bug and carries nothing of the panic itself.
pub(crate) fn panic_to_error(payload: &(dyn std::any::Any + Send), what: &str) -> Error {
    let detail = payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("panic");
    tracing::error!(panic = detail, "{what} panicked");
    Error::Internal {
        detail: "the handler failed unexpectedly; this is a bug".into(),
    }
}
