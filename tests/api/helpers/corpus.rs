//! The bad-input corpus in `tests/corpus/` and small text builders for it.

use serde_json::Value;

pub(crate) fn corpus(name: &str) -> Vec<Value> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/corpus")
        .join(name);
    let doc: Value = serde_json::from_slice(&std::fs::read(&path).expect("corpus file"))
        .expect("corpus is JSON");
    doc["cases"].as_array().expect("cases").clone()
}

pub(crate) fn corpus_bytes(name: &str) -> Vec<u8> {
    std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/corpus")
            .join(name),
    )
    .expect("corpus data file")
}

pub(crate) fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

pub(crate) fn join(n: usize, item: &str) -> String {
    vec![item; n].join(",")
}

/// The tool pose of built-in `robot` at `joints` by the plain reference
/// product (`kinserve_testkit::forward_reference`, not the server's fast
/// path), in rad unless `deg`.
pub(crate) fn reference_pose(
    robot: &str,
    joints: &[f64],
    deg: bool,
) -> kinserve::kinematics::Transform {
    let robot = crate::helpers::library_robot(robot);
    let scale = if deg {
        std::f64::consts::PI / 180.0
    } else {
        1.0
    };
    kinserve_testkit::forward_reference(robot.chain(), joints, scale)
}

/// Whether 16 row-major values equal `want`'s matrix to 1e-12 (absolute);
/// the difference when not.
pub(crate) fn matrix_matches(
    got: &[f64],
    want: &kinserve::kinematics::Transform,
) -> Result<(), String> {
    let want: Vec<f64> = want.matrix().iter().flatten().copied().collect();
    if got.len() != 16 {
        return Err(format!("{} matrix values instead of 16", got.len()));
    }
    match got
        .iter()
        .zip(&want)
        .position(|(a, b)| (a - b).abs() > 1e-12)
    {
        None => Ok(()),
        Some(k) => Err(format!(
            "matrix[{k}] = {} instead of {} (reference)",
            got[k], want[k]
        )),
    }
}
