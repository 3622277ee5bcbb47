//! kinserve: forward kinematics of serial robots described by Denavit–Hartenberg
//! tables, served over REST and gRPC.
//!
//! Dependencies point one way: `api` → `service` → `registry` → `model` → `kinematics`.

pub mod error;
pub mod kinematics;
pub mod model;

pub use error::{Error, FieldViolation, Result};
