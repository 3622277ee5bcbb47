//! kinserve: forward kinematics of serial robots described by Denavit–Hartenberg
//! tables, served over REST + WebSocket and gRPC.
//!
//! This crate is the server: the robot registry and its store, the
//! protocol-neutral service, the REST/WebSocket and gRPC adapters, start-up,
//! configuration and the `kinserve` command line. The math lives in
//! `kinserve-kinematics` and the model schema and validation in
//! `kinserve-model` (re-exported here as [`kinematics`] and [`model`]).
//!
//! Dependencies point one way: `cli` → `startup` → `api` → `service` →
//! `registry` → `model` → `kinematics`; `config` builds the settings each
//! layer is given as values. Must not depend on: hdrhistogram, reqwest,
//! criterion, proptest (load generation and test support live in
//! `kinserve-load` and `kinserve-testkit`).

pub mod api;
pub mod bench;
pub mod cli;
pub mod cli_objectives;
pub mod compute;
pub mod config;
pub mod error;
pub mod registry;
pub mod service;
pub mod startup;
pub mod telemetry;
pub mod tls;

pub use error::{Error, FieldViolation, Result};
pub use kinserve_kinematics as kinematics;
pub use kinserve_model as model;
pub use startup::{App, ShutdownHandle};
