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

/// Every kernel this CPU can run, the portable one first. Says once per
/// test binary which kernels run and which are left out (past the
/// harness's capture, see [`crate::report`]). Under CI (see
/// [`crate::under_ci`]) a kernel whose CPU flags `/proc/cpuinfo` lists but
/// that the product's detection ([`Kernel::is_supported`]) leaves out fails
/// the calling test: the CI machine has AVX-512, and its kernel must be tested.
pub fn supported_kernels() -> Vec<Kernel> {
    let all = [Kernel::Portable, Kernel::Avx2Fma, Kernel::Avx512];
    let (run, left_out): (Vec<Kernel>, Vec<Kernel>) =
        all.into_iter().partition(|k| k.is_supported());
    static REPORTED: std::sync::Once = std::sync::Once::new();
    REPORTED.call_once(|| {
        let names = |ks: &[Kernel]| ks.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ");
        crate::report(&format!(
            "kernels tested: {}; left out (this CPU lacks them): {}",
            names(&run),
            if left_out.is_empty() {
                "none".into()
            } else {
                names(&left_out)
            }
        ));
    });
    if crate::under_ci() {
        let flags = cpu_flags();
        for k in &left_out {
            let needs = kernel_flags(*k);
            assert!(
                !needs.iter().all(|f| flags.iter().any(|g| g == f)),
                "the CPU lists {needs:?} in /proc/cpuinfo but the {} kernel is not \
                 detected (Kernel::is_supported): its tests would not run",
                k.name()
            );
        }
    }
    run
}

/// The `/proc/cpuinfo` flags a kernel needs (as the kernel's detection checks them).
fn kernel_flags(k: Kernel) -> &'static [&'static str] {
    match k {
        Kernel::Portable => &[],
        Kernel::Avx2Fma => &["avx2", "fma"],
        Kernel::Avx512 => &["avx2", "fma", "avx512f", "avx512vl", "avx512dq"],
    }
}

/// The CPU flags of the first processor in `/proc/cpuinfo` (empty where
/// there is no such file, e.g. not Linux): read independently of `std`'s
/// feature detection.
fn cpu_flags() -> Vec<String> {
    std::fs::read_to_string("/proc/cpuinfo")
        .unwrap_or_default()
        .lines()
        .find(|l| l.starts_with("flags"))
        .and_then(|l| l.split_once(':'))
        .map(|(_, f)| f.split_whitespace().map(str::to_owned).collect())
        .unwrap_or_default()
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
