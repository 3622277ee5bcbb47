//! kinserve-kinematics: the pure math of forward kinematics for serial robots
//! described by Denavit–Hartenberg tables, in both conventions (standard /
//! distal and modified / Craig, proximal).
//!
//! It owns rigid transforms ([`Transform`]), DH rows and their link matrices
//! ([`DhRow`], [`link_transform`]), compiled chains with everything that does
//! not depend on the joint values computed once ([`Chain`]), vectorised
//! sine/cosine ([`sincos`]), the geometric Jacobian ([`Jacobian`], with
//! manipulability and singularity measures under the `nalgebra` feature) and,
//! under the `ik` feature, numerical inverse kinematics ([`ik`]). The fast
//! paths pick the widest kernel the CPU has at run time ([`Kernel`]); every
//! kernel computes the same product.
//!
//! Units: angles in radians, lengths in whatever unit the caller's table uses.
//!
//! Must not depend on: serde, tokio, axum, tonic, prost, hyper, tower, utoipa —
//! or on any other kinserve crate. Validation lives one layer up
//! (`kinserve-model`); the evaluators here are unchecked by design and say so.

mod chain;
#[cfg(feature = "nalgebra")]
mod convert;
#[cfg(feature = "ik")]
pub mod ik;
mod jacobian;
mod kernel;
pub mod sincos;
mod transform;

pub use chain::{Chain, Convention, DhRow, JointKind, link_transform};
pub use jacobian::{Jacobian, JacobianFrame};
#[cfg(feature = "nalgebra")]
pub use jacobian::{SINGULAR_THRESHOLD, VelocityMeasures};
pub use kernel::Kernel;
pub use transform::Transform;
