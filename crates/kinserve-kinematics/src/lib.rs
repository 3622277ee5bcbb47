//! kinserve-kinematics: the pure math of forward kinematics for serial robots
//! described by Denavit–Hartenberg tables, in both conventions (standard /
//! distal and modified / Craig, proximal).
//!
//! It owns rigid transforms ([`Transform`]), DH rows and their link matrices
//! ([`DhRow`], [`link_transform`]), compiled chains with everything that does
//! not depend on the joint values computed once ([`Chain`]), and vectorised
//! sine/cosine ([`sincos`]). The fast paths pick the widest kernel the CPU has
//! at run time ([`Kernel`]); every kernel computes the same product.
//!
//! Units: angles in radians, lengths in whatever unit the caller's table uses.
//!
//! Must not depend on: serde, tokio, axum, tonic, prost, hyper, tower, utoipa —
//! or on any other kinserve crate. Validation lives one layer up
//! (`kinserve-model`); the evaluators here are unchecked by design and say so.

mod chain;
#[cfg(feature = "nalgebra")]
mod convert;
mod kernel;
pub mod sincos;
mod transform;

pub use chain::{Chain, Convention, DhRow, JointKind, link_transform};
pub use kernel::Kernel;
pub use transform::Transform;
