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

pub mod grpc;
pub mod pose;
pub mod rest;
