//! kinserve-kinematics: the pure math of forward kinematics for serial robots
//! described by Denavit–Hartenberg tables, in both conventions (standard /
//! distal and modified / Craig, proximal).
//!
//! It owns rigid transforms ([`Transform`]), DH rows and their link matrices
//! ([`DhRow`], [`link_transform`]), compiled chains ([`Chain`]: each table
//! specialised once, at construction, into constants folded between the joints
//! and steps classified by which entries are 0 or ±1), their evaluators (single
//! pose, every frame, batches of 8 poses in structure-of-arrays form) and
//! vectorised sine/cosine ([`sincos`]), the geometric Jacobian ([`Jacobian`], with
//! manipulability and singularity measures under the `nalgebra` feature) and,
//! under the `ik` feature, numerical inverse kinematics ([`ik`]) and analytic,
//! every-solution inverse kinematics of 6R arms ([`analytic_ik`]). The fast
//! paths pick the widest kernel the CPU has at run time ([`Kernel`]: AVX-512,
//! AVX2+FMA, portable); every
//! kernel computes the same product.
//!
//! Units: angles in radians, lengths in whatever unit the caller's table uses.
//!
//! # Example
//!
//! A planar arm of two revolute joints with links of 0.4 and 0.3 (standard
//! DH), evaluated with its joint values in degrees:
//!
//! ```
//! use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Transform};
//!
//! let link = |a| DhRow { kind: JointKind::Revolute, a, alpha: 0.0, d: 0.0, theta: 0.0 };
//! let chain = Chain::new(Convention::Standard, &[link(0.4), link(0.3)], Transform::IDENTITY, None);
//! assert_eq!(chain.dof(), 2);
//!
//! // Shoulder at 90°, elbow at 0°: the arm points along +y, 0.7 out.
//! let [x, y, z] = chain.forward(&[90.0, 0.0], std::f64::consts::PI / 180.0).position();
//! assert!(x.abs() < 1e-12 && (y - 0.7).abs() < 1e-12 && z.abs() < 1e-12);
//! ```
//!
//! Must not depend on: serde, tokio, axum, tonic, prost, hyper, tower, utoipa —
//! or on any other kinserve crate. Validation lives one layer up
//! (`kinserve-model`); the evaluators here are unchecked by design and say so.

#[cfg(feature = "ik")]
pub mod analytic_ik;
mod batch_out;
mod chain;
#[cfg(feature = "nalgebra")]
mod convert;
mod dh;
mod eval;
#[cfg(feature = "ik")]
pub mod ik;
mod jacobian;
mod kernel;
mod lane;
mod program;
pub mod sincos;
mod step;
mod transform;

pub use batch_out::PackedLayout;
pub use chain::Chain;
pub use dh::{Convention, DhRow, JointKind, link_transform};
pub use jacobian::{Jacobian, JacobianFrame};
#[cfg(feature = "nalgebra")]
pub use jacobian::{SINGULAR_THRESHOLD, VelocityMeasures};
pub use kernel::Kernel;
pub use transform::Transform;
