//! Tolerances and assertions on JSON poses.

use serde_json::Value;

/// Tolerance for closed forms (absolute, scaled by max(1, |expected|)).
pub(crate) const CLOSED_FORM_TOL: f64 = 1e-9;
/// Tolerance for comparing two results of the same library.
pub(crate) const SAME_LIB_TOL: f64 = 1e-12;

/// Asserts two numbers agree within `tol` (absolute, scaled by max(1, |b|)).
pub fn assert_close(a: f64, b: f64, tol: f64, what: &str) {
    let scale = b.abs().max(1.0);
    assert!(
        (a - b).abs() <= tol * scale,
        "{what}: {a} vs {b} (tol {tol})"
    );
}

/// Position `[x,y,z]` from a JSON pose.
pub fn position(pose: &serde_json::Value) -> [f64; 3] {
    let p = pose["position"].as_array().expect("position array");
    [
        p[0].as_f64().unwrap(),
        p[1].as_f64().unwrap(),
        p[2].as_f64().unwrap(),
    ]
}

/// The 16 matrix entries (row-major) of a JSON pose.
pub fn matrix16(pose: &serde_json::Value) -> Vec<f64> {
    pose["matrix"]
        .as_array()
        .expect("matrix")
        .iter()
        .flat_map(|r| {
            r.as_array()
                .expect("row")
                .iter()
                .map(|x| x.as_f64().expect("number"))
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Asserts two JSON poses agree entry by entry (matrix, position, quaternion, rpy).
pub(crate) fn assert_pose_eq(a: &Value, b: &Value, tol: f64, what: &str) {
    let (ma, mb) = (matrix16(a), matrix16(b));
    for (i, (x, y)) in ma.iter().zip(&mb).enumerate() {
        assert_close(
            *x,
            *y,
            tol,
            &format!("{what}: matrix[{}][{}]", i / 4, i % 4),
        );
    }
    let (pa, pb) = (position(a), position(b));
    for i in 0..3 {
        assert_close(pa[i], pb[i], tol, &format!("{what}: position[{i}]"));
        let (ra, rb) = (a["rpy"][i].as_f64().unwrap(), b["rpy"][i].as_f64().unwrap());
        assert_close(ra, rb, tol, &format!("{what}: rpy[{i}]"));
    }
    for k in ["w", "x", "y", "z"] {
        let (qa, qb) = (
            a["quaternion"][k].as_f64().unwrap(),
            b["quaternion"][k].as_f64().unwrap(),
        );
        assert_close(qa, qb, tol, &format!("{what}: quaternion.{k}"));
    }
}
