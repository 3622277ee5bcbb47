//! gRPC contract tests: a tonic client against the real server on port 0.
//!
//! Every RPC of `kinematics.v1.KinematicsService` with its success path and every
//! status code the issue names, health, reflection (v1 and v1alpha), the
//! bidirectional stream (invalid message in the middle, slow reader, cancel,
//! shutdown, many configurations in one message), the registry shared with REST, and velocity / inverse kinematics
//! (the same answers as REST and the WebSocket).
//!
//! Split by area; the shared helpers are in `crate::helpers`.

mod fk;
mod grpcurl;
mod health;
mod ik_objectives;
mod ik_solutions;
mod packed;
mod registry;
mod stream;
mod stream_batch;
mod velocity;
