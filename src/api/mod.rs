//! Front doors: thin adapters from REST and gRPC to [`crate::service::Service`].

pub mod grpc;
pub mod rest;
