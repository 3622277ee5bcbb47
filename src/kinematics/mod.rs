//! Pure forward-kinematics math: rigid transforms, DH link matrices, compiled
//! chains and vectorised sine/cosine. No serde, no I/O, no async.

mod chain;
pub mod sincos;
mod transform;

pub use chain::{Chain, Convention, DEFAULT_MAX_JOINTS, DhRow, JointKind, link_transform};
pub use transform::Transform;
