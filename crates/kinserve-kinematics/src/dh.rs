//! The Denavit–Hartenberg row types ([`Convention`], [`JointKind`], [`DhRow`])
//! and the textbook link matrix of one row ([`link_transform`], what the fast
//! paths are tested against): plain data and its definition, the layer below
//! both the compiler of a chain (`program.rs`) and the chain itself
//! (`chain.rs`), so neither has to reach into the other for them.
//!
//! Depends only on [`crate::transform`]; must not depend on any other module
//! of the crate.

use crate::transform::Transform;

/// Which Denavit–Hartenberg convention a table is written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Convention {
    /// Standard (distal): `A_i = Rz(θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)`.
    Standard,
    /// Modified (proximal, Craig): `A_i = Rx(α_{i-1})·Tx(a_{i-1})·Rz(θ_i)·Tz(d_i)`;
    /// row `i` holds `α_{i-1}, a_{i-1}, θ_i, d_i`.
    Modified,
}

/// The kind of joint a DH row describes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum JointKind {
    /// The joint value (rad) is added to θ.
    Revolute,
    /// The joint value (length unit) is added to d.
    Prismatic,
    /// No joint variable: a constant frame written as a table row.
    Fixed,
}

/// One DH row in internal units: angles in rad, lengths in the model's length unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DhRow {
    /// Joint kind.
    pub kind: JointKind,
    /// Link length `a` (standard: `a_i`; modified: `a_{i-1}`).
    pub a: f64,
    /// Link twist `α` in rad (standard: `α_i`; modified: `α_{i-1}`).
    pub alpha: f64,
    /// Link offset `d` (the zero position for a prismatic joint).
    pub d: f64,
    /// Joint angle `θ` in rad (the zero offset for a revolute joint).
    pub theta: f64,
}

/// The homogeneous matrix of one DH row for joint value `q` (rad for revolute,
/// length unit for prismatic, ignored for fixed), computed plainly with `std`
/// trigonometry and generic products: the textbook definition, which the fast
/// paths of [`Chain`](crate::Chain) are tested against.
pub fn link_transform(convention: Convention, row: &DhRow, q: f64) -> Transform {
    let (theta, d) = match row.kind {
        JointKind::Revolute => (row.theta + q, row.d),
        JointKind::Prismatic => (row.theta, row.d + q),
        JointKind::Fixed => (row.theta, row.d),
    };
    match convention {
        Convention::Standard => {
            Transform::rot_z(theta)
                * Transform::translation(0.0, 0.0, d)
                * Transform::translation(row.a, 0.0, 0.0)
                * Transform::rot_x(row.alpha)
        }
        Convention::Modified => {
            Transform::rot_x(row.alpha)
                * Transform::translation(row.a, 0.0, 0.0)
                * Transform::rot_z(theta)
                * Transform::translation(0.0, 0.0, d)
        }
    }
}
