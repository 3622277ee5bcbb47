//! The README's model examples are valid models (so the front door stays true).

use kinserve::model::{ModelLimits, Robot};
use kinserve_testkit::RobotExt;

#[test]
fn readme_model_examples_validate_and_give_the_documented_poses() {
    let readme = include_str!("../../README.md");
    let models: Vec<Robot> = readme
        .split("```json")
        .skip(1)
        .filter_map(|block| block.split("```").next())
        .filter(|b| b.contains("\"convention\""))
        .map(|b| {
            Robot::from_json(b.as_bytes(), &ModelLimits::default()).expect("README model validates")
        })
        .collect();
    assert_eq!(
        models.len(),
        3,
        "one example per convention, and the URDF import's answer"
    );
    // Standard planar arm with a 5 cm tool: x = a1 + a2 + 0.05 at home.
    let planar = &models[0];
    assert_eq!(planar.name(), "planar-demo");
    let p = planar.fk_unchecked(&[0.0, 0.0]).position();
    assert!((p[0] - 0.75).abs() < 1e-12 && p[1].abs() < 1e-12, "{p:?}");
    // Modified-DH articulated arm at home = [[1,0,0,a2+a3],[0,0,1,0],[0,-1,0,d1]] (lecture 004).
    let rrr = &models[1];
    let m = rrr.fk_unchecked(&[0.0, 0.0, 0.0]).matrix();
    let expect = [
        [1.0, 0.0, 0.0, 0.75],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0, 0.3],
        [0.0, 0.0, 0.0, 1.0],
    ];
    for i in 0..4 {
        for j in 0..4 {
            assert!((m[i][j] - expect[i][j]).abs() < 1e-12, "home pose {m:?}");
        }
    }
    // The URDF import's answer: 0.25 m up, 0.5 + 0.25 m out at home; at
    // (90°, 0) the arm points along y.
    let imported = &models[2];
    assert_eq!(imported.name(), "urdf-demo");
    let p = imported.fk_unchecked(&[0.0, 0.0]).position();
    assert!(
        (p[0] - 0.75).abs() < 1e-12 && (p[2] - 0.25).abs() < 1e-12,
        "{p:?}"
    );
    let p = imported
        .fk_unchecked(&[std::f64::consts::FRAC_PI_2, 0.0])
        .position();
    assert!(p[0].abs() < 1e-12 && (p[1] - 0.75).abs() < 1e-12, "{p:?}");
}
