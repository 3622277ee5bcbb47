//! Robot models and joint configurations to send.

use std::path::Path;

use serde_json::Value;

/// A small valid model (2-DoF planar arm, metres, degrees).
pub fn planar_model(name: &str) -> serde_json::Value {
    serde_json::json!({
        "name": name,
        "convention": "standard",
        "angle_unit": "deg",
        "length_unit": "m",
        "links": [
            {"joint": "revolute", "a": 0.5, "alpha": 0, "d": 0, "theta": 0, "limits": [-170, 170]},
            {"joint": "revolute", "a": 0.3, "alpha": 0, "d": 0, "theta": 0}
        ]
    })
}

pub(crate) fn builtin_file(name: &str) -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("robots")
        .join(format!("{name}.json"));
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// Deterministic pseudo-random joint values in [-1.5, 1.5] rad (inside every puma560 limit).
pub(crate) fn configs(n: usize, dof: usize) -> Vec<Vec<f64>> {
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    (0..n)
        .map(|_| {
            (0..dof)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    (x % 30_001) as f64 / 10_000.0 - 1.5
                })
                .collect()
        })
        .collect()
}
