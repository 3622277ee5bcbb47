//! The plain reference path: `base · A_1 ⋯ A_n · tool` as a product of
//! textbook link matrices ([`link_transform`]) with generic 4×4 products and
//! `std` trigonometry. Slow and obviously right; every fast path is tested
//! against it. Depends only on the kinematics crate.

use kinserve_kinematics::{Chain, JointKind, Kernel, Transform, link_transform};
use kinserve_model::Robot;

/// The reference product for joint values `q` (revolute values times
/// `angle_scale`; missing values count as 0, like the fast paths).
pub fn forward_reference(chain: &Chain, q: &[f64], angle_scale: f64) -> Transform {
    let mut t = *chain.base();
    let mut qi = q.iter();
    for row in chain.dh_rows() {
        let qj = match row.kind {
            JointKind::Fixed => 0.0,
            JointKind::Revolute => qi.next().copied().unwrap_or(0.0) * angle_scale,
            JointKind::Prismatic => qi.next().copied().unwrap_or(0.0),
        };
        t = t * link_transform(chain.convention(), &row, qj);
    }
    match chain.tool() {
        Some(tool) => t * *tool,
        None => t,
    }
}

/// Every kernel this CPU can run, the portable one first.
pub fn supported_kernels() -> Vec<Kernel> {
    [Kernel::Portable, Kernel::Avx2Fma, Kernel::Avx512]
        .into_iter()
        .filter(|k| k.is_supported())
        .collect()
}

/// FK without checks, for tests that compute expected poses: joint values in
/// rad (revolute) and the model's length unit (prismatic), limits ignored.
pub trait RobotExt {
    /// The tool pose at `q`, unchecked (see [`Chain::forward`]).
    fn fk_unchecked(&self, q: &[f64]) -> Transform;
}

impl RobotExt for Robot {
    fn fk_unchecked(&self, q: &[f64]) -> Transform {
        self.chain().forward(q, 1.0)
    }
}
