//! The docs' model examples (README.md and every `docs/*.md`) are valid
//! models and give the documented poses (so the front door stays true).

use std::path::Path;

use kinserve::model::{ModelLimits, Robot};
use kinserve_testkit::RobotExt;

/// Every ```json block of README.md and `docs/*.md` that holds a
/// `"convention"`, validated (a block that does not validate fails here,
/// naming its page).
fn doc_models() -> Vec<Robot> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut pages: Vec<_> = std::fs::read_dir(root.join("docs"))
        .expect("docs/ exists")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    pages.sort();
    pages.insert(0, root.join("README.md"));
    let mut models = Vec::new();
    for page in pages {
        let text = std::fs::read_to_string(&page).unwrap();
        for block in text.split("```json").skip(1) {
            let block = block.split("```").next().unwrap();
            if block.contains("\"convention\"") && block.contains("\"links\"") {
                let robot = Robot::from_json(block.as_bytes(), &ModelLimits::default())
                    .unwrap_or_else(|e| panic!("{}: model example invalid: {e:?}", page.display()));
                models.push(robot);
            }
        }
    }
    models
}

#[test]
fn readme_model_examples_validate_and_give_the_documented_poses() {
    let models = doc_models();
    let named = |name: &str| {
        models
            .iter()
            .find(|m| m.name() == name)
            .unwrap_or_else(|| panic!("the docs show the model '{name}'"))
    };
    // Standard planar arm with a 5 cm tool: x = a1 + a2 + 0.05 at home.
    let planar = named("planar-demo");
    let p = planar.fk_unchecked(&[0.0, 0.0]).position();
    assert!((p[0] - 0.75).abs() < 1e-12 && p[1].abs() < 1e-12, "{p:?}");
    // Modified-DH articulated arm at home = [[1,0,0,a2+a3],[0,0,1,0],[0,-1,0,d1]] (lecture 004).
    let rrr = named("rrr-mdh-demo");
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
    let imported = named("urdf-demo");
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
