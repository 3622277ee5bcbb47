//! What both fuzz checks use — the property check of models and FK requests
//! (`fuzzing.rs`) and that of IK requests (`fuzz_ik.rs`): the built-in
//! robots they evaluate requests against, the pose check and the client-error
//! check. A layer below both, so neither reaches into the other for them.
//!
//! Depends on the server crate's error and pose types and on the model; must
//! not depend on `fuzzing.rs` or `fuzz_ik.rs`.

use std::sync::OnceLock;

use kinserve::api::pose::Pose;
use kinserve::api::rest::Problem;
use kinserve::error::Error;
use kinserve_kinematics::Transform;
use kinserve_model::{ModelLimits, RIGID_TOLERANCE, Robot};

/// Built-in robots covering revolute limits (puma560), prismatic joints with
/// limits (stanford, cylindrical_3dof), unlimited revolute joints (scara_4dof),
/// and a model with unlimited, parallel prismatic joints.
pub(crate) fn robots() -> &'static [Robot] {
    static ROBOTS: OnceLock<Vec<Robot>> = OnceLock::new();
    ROBOTS.get_or_init(|| {
        let files: [&[u8]; 4] = [
            include_bytes!("../../../robots/puma560.json"),
            include_bytes!("../../../robots/stanford.json"),
            include_bytes!("../../../robots/scara_4dof.json"),
            include_bytes!("../../../robots/cylindrical_3dof.json"),
        ];
        let slides = br#"{"name": "slides", "convention": "standard", "links": [
            {"joint": "prismatic", "a": 0, "alpha": 0, "d": 0, "theta": 0},
            {"joint": "prismatic", "a": 0, "alpha": 0, "d": 0, "theta": 0},
            {"joint": "revolute", "a": 1, "alpha": 0, "d": 0, "theta": 0}]}"#;
        files
            .iter()
            .copied()
            .chain([&slides[..]])
            .map(|b| Robot::from_json(b, &ModelLimits::default()).expect("built-in robot"))
            .collect()
    })
}

/// A model or request error must be one the client caused (HTTP 4xx).
pub(crate) fn assert_client_error(e: &Error, what: &str) {
    let status = Problem::from_error(e).status;
    assert!(
        (400..500).contains(&status),
        "{what}: error maps to HTTP {status}, not a client error: {e}"
    );
}

/// Finite and rigid, and its pose form (quaternion, rpy) is finite and unit.
pub(crate) fn check_pose(t: &Transform, what: &str, q: &[f64]) {
    let finite = t.rotation.iter().flatten().all(|x| x.is_finite())
        && t.translation.iter().all(|x| x.is_finite());
    assert!(finite, "{what}: non-finite pose {t:?} for q = {q:?}");
    let err = t.rigidity_error();
    assert!(
        err < RIGID_TOLERANCE,
        "{what}: pose is not rigid (off by {err:e}) for q = {q:?}: {t:?}"
    );
    let p = Pose::from(t);
    let n = p.quaternion.w.powi(2)
        + p.quaternion.x.powi(2)
        + p.quaternion.y.powi(2)
        + p.quaternion.z.powi(2);
    assert!(
        (n - 1.0).abs() < 1e-9 && p.quaternion.w >= 0.0,
        "{what}: quaternion {:?} is not a unit quaternion with w >= 0 for q = {q:?}",
        p.quaternion
    );
    assert!(
        p.rpy
            .iter()
            .all(|a| a.abs() <= std::f64::consts::PI + 1e-12),
        "{what}: rpy {:?} out of range for q = {q:?}",
        p.rpy
    );
}
