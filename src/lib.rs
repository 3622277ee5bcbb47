//! kinserve: forward kinematics of serial robots described by Denavit–Hartenberg
//! tables, served over REST and gRPC.
//!
//! Dependencies point one way: `api` → `service` → `registry` → `model` → `kinematics`.

pub mod api;
pub mod cli;
pub mod config;
pub mod error;
pub mod fuzzing;
pub mod kinematics;
pub mod load;
pub mod model;
pub mod registry;
pub mod service;
pub mod startup;
pub mod telemetry;

pub use error::{Error, FieldViolation, Result};
pub use startup::{App, ShutdownHandle};
