//! Model validation: every robot file validates; bad models give the documented field errors.

use kinserve_model::ModelError as Error;
use kinserve_model::{
    AngleUnit, FkOptions, ModelLimits, Robot, RobotSpec, load_robot_file, parse_json,
};
use kinserve_testkit::RobotExt;
use serde_json::json;

fn robots_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots")
}

#[test]
fn every_robot_file_validates_and_is_named_after_its_file() {
    let mut count = 0;
    for entry in std::fs::read_dir(robots_dir()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "json") {
            let robot =
                load_robot_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert_eq!(
                Some(robot.name()),
                path.file_stem().and_then(|s| s.to_str())
            );
            assert!(
                robot
                    .spec()
                    .source
                    .as_deref()
                    .is_some_and(|s| !s.is_empty()),
                "{} has no source",
                robot.name()
            );
            count += 1;
        }
    }
    assert!(
        count >= 17,
        "expected the course robots and at least 8 real arms, found {count}"
    );
}

fn base_model() -> serde_json::Value {
    json!({
        "name": "arm",
        "convention": "standard",
        "links": [
            {"joint": "revolute", "a": 0.5, "alpha": 0, "d": 0, "theta": 0, "limits": [-1, 1]},
            {"joint": "prismatic", "a": 0, "alpha": 0, "d": 0, "theta": 0, "limits": [0, 0.5]}
        ]
    })
}

/// Validates a JSON model and returns `(is Invalid (422), [(field, message)])`.
fn errors(v: &serde_json::Value) -> (bool, Vec<(String, String)>) {
    let bytes = serde_json::to_vec(v).unwrap();
    match Robot::from_json(&bytes, &ModelLimits::default()) {
        Ok(_) => panic!("model should be rejected: {v}"),
        Err(e) => {
            let invalid = matches!(e, Error::Invalid { .. });
            (
                invalid,
                e.violations()
                    .iter()
                    .map(|x| (x.field.clone(), x.message.clone()))
                    .collect(),
            )
        }
    }
}

fn fields(v: &serde_json::Value) -> Vec<String> {
    errors(v).1.into_iter().map(|x| x.0).collect()
}

#[test]
fn bad_models_name_the_offending_field() {
    let mut m = base_model();
    m["links"][1]["joint"] = json!("spherical");
    assert_eq!(fields(&m), ["links[1].joint"]);

    let mut m = base_model();
    m["convention"] = json!("craig");
    assert_eq!(fields(&m), ["convention"]);

    let mut m = base_model();
    m["links"][0].as_object_mut().unwrap().remove("alpha");
    assert_eq!(fields(&m), ["links[0].alpha"]);
    // One status policy: whatever cannot be read into the schema is malformed (400).
    assert!(!errors(&m).0, "a missing field is malformed (400)");

    let mut m = base_model();
    m["links"][0]["alpah"] = json!(0);
    let (invalid, e) = errors(&m);
    assert!(!invalid, "an unknown field is malformed (400)");
    assert_eq!(e[0].0, "links[0].alpah");
    assert!(e[0].1.contains("unknown field"));

    let mut m = base_model();
    m["links"][0]["alpha"] = json!("x");
    let (invalid, e) = errors(&m);
    assert!(!invalid, "a wrong type is malformed (400)");
    assert_eq!(e[0].0, "links[0].alpha");

    let mut m = base_model();
    m["links"] = json!([]);
    assert_eq!(fields(&m), ["links"]);

    let mut m = base_model();
    m["links"] = json!([{"joint": "fixed", "a": 1, "alpha": 0, "d": 0, "theta": 0}]);
    assert_eq!(fields(&m), ["links"]);

    let mut m = base_model();
    m["links"][0]["limits"] = json!([1, -1]);
    assert_eq!(fields(&m), ["links[0].limits"]);

    let mut m = base_model();
    m["name"] = json!("../etc/passwd");
    assert_eq!(fields(&m), ["name"]);
    for bad in [
        "",
        "-lead",
        "UPPER",
        "a/b",
        "nul\u{0}",
        "ünïcode",
        &"x".repeat(65),
    ] {
        let mut m = base_model();
        m["name"] = json!(bad);
        assert_eq!(fields(&m), ["name"], "name {bad:?}");
    }

    let mut m = base_model();
    m["tool"] = json!({"matrix": [[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]});
    assert_eq!(fields(&m), ["tool.matrix"]);
    m["tool"] = json!({"matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]});
    assert_eq!(fields(&m), ["tool.matrix[3]"]);
    // A reflection (det -1) is not a rotation.
    m["tool"] = json!({"matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]]});
    assert_eq!(fields(&m), ["tool.matrix"]);

    let mut m = base_model();
    m["base"] = json!({"translation": [0, 0, 1], "quaternion": {"w": 0, "x": 0, "y": 0, "z": 0}});
    assert_eq!(fields(&m), ["base.quaternion"]);

    // Several errors at once, all reported.
    let mut m = base_model();
    m["name"] = json!("Bad Name");
    m["links"][1]["limits"] = json!([2, 1]);
    assert_eq!(fields(&m), ["name", "links[1].limits"]);
}

#[test]
fn too_many_joints_is_rejected_at_the_configured_maximum() {
    let link = json!({"joint": "revolute", "a": 0.1, "alpha": 0, "d": 0, "theta": 0});
    let mut m = base_model();
    m["links"] = json!(vec![link.clone(); 65]);
    assert_eq!(fields(&m), ["links"]);
    let mut m = base_model();
    m["links"] = json!(vec![link; 64]);
    let bytes = serde_json::to_vec(&m).unwrap();
    assert!(Robot::from_json(&bytes, &ModelLimits::default()).is_ok());
    assert!(
        Robot::from_json(
            &bytes,
            &ModelLimits {
                max_joints: 10,
                max_links: 256
            }
        )
        .is_err()
    );
}

#[test]
fn joint_checks_name_the_index_and_the_limits() {
    let spec: RobotSpec = parse_json(&serde_json::to_vec(&base_model()).unwrap()).unwrap();
    let robot = Robot::from_spec(spec, &ModelLimits::default()).unwrap();
    let opts = FkOptions::default();
    let e = robot.fk(&[0.0], &opts).unwrap_err();
    assert_eq!(e.violations()[0].field, "joints");
    let e = robot.fk(&[f64::NAN, 0.1], &opts).unwrap_err();
    assert_eq!(e.violations()[0].field, "joints[0]");
    let e = robot.fk(&[0.0, 0.7], &opts).unwrap_err();
    assert_eq!(e.violations()[0].field, "joints[1]");
    assert!(
        e.violations()[0].message.contains("[0, 0.5]"),
        "{}",
        e.violations()[0].message
    );
    // Limits off: computed anyway. Degrees: 57° is inside ±1 rad, 58° is not.
    assert!(
        robot
            .fk(
                &[0.0, 0.7],
                &FkOptions {
                    check_limits: false,
                    ..opts
                }
            )
            .is_ok()
    );
    let deg = FkOptions {
        angle_unit: AngleUnit::Deg,
        ..opts
    };
    assert!(robot.fk(&[57.0, 0.1], &deg).is_ok());
    let e = robot.fk(&[58.0, 0.1], &deg).unwrap_err();
    assert!(
        e.violations()[0].message.contains("deg"),
        "{}",
        e.violations()[0].message
    );
}

#[test]
fn degrees_and_millimetres_are_converted_where_they_belong() {
    // The same planar arm in (deg, mm) and (rad, m): positions differ by 1000, orientation equal.
    let mm = json!({"name": "mm", "convention": "standard", "angle_unit": "deg", "length_unit": "mm",
        "links": [{"joint": "revolute", "a": 400, "alpha": 90, "d": 100, "theta": 30},
                  {"joint": "prismatic", "a": 0, "alpha": 0, "d": 50, "theta": -90}],
        "tool": {"translation": [0, 0, 20], "rpy": [0, 90, 0]}});
    let m = json!({"name": "m", "convention": "standard", "angle_unit": "rad", "length_unit": "m",
        "links": [{"joint": "revolute", "a": 0.4, "alpha": std::f64::consts::FRAC_PI_2, "d": 0.1, "theta": std::f64::consts::PI / 6.0},
                  {"joint": "prismatic", "a": 0, "alpha": 0, "d": 0.05, "theta": -std::f64::consts::FRAC_PI_2}],
        "tool": {"translation": [0, 0, 0.02], "rpy": [0, std::f64::consts::FRAC_PI_2, 0]}});
    let a = Robot::from_json(&serde_json::to_vec(&mm).unwrap(), &ModelLimits::default()).unwrap();
    let b = Robot::from_json(&serde_json::to_vec(&m).unwrap(), &ModelLimits::default()).unwrap();
    let ta = a.fk_unchecked(&[0.3, 25.0]);
    let tb = b.fk_unchecked(&[0.3, 0.025]);
    for i in 0..3 {
        assert!((ta.translation[i] / 1000.0 - tb.translation[i]).abs() < 1e-12);
        for j in 0..3 {
            assert!((ta.rotation[i][j] - tb.rotation[i][j]).abs() < 1e-12);
        }
    }
}

/// Revolute joint values are bounded (±1e5 rad) like every other magnitude, so
/// every accepted input gives the same pose with and without frames (the
/// issue's repro: a 33.3° θ offset at 1e17 deg gave two different poses).
#[test]
fn revolute_values_are_bounded_and_frames_agree_up_to_the_bound() {
    let model = json!({
        "name": "offset", "convention": "standard", "angle_unit": "deg",
        "links": [
            {"joint": "revolute", "a": 0.5, "alpha": 0, "d": 0, "theta": 33.3},
            {"joint": "revolute", "a": 0.3, "alpha": 0, "d": 0, "theta": 0}
        ]
    });
    let robot = Robot::from_json(
        &serde_json::to_vec(&model).unwrap(),
        &ModelLimits::default(),
    )
    .unwrap();
    let deg = FkOptions {
        angle_unit: AngleUnit::Deg,
        check_limits: false,
    };
    let e = robot.fk(&[1e17, 0.0], &deg).unwrap_err();
    assert_eq!(e.violations()[0].field, "joints[0]");
    assert!(
        e.violations()[0]
            .message
            .contains("largest revolute joint value"),
        "{e}"
    );
    // Just inside the bound (the bound itself may round either way in degrees).
    let edge = kinserve_model::MAX_REVOLUTE_RAD.to_degrees() * (1.0 - 1e-12);
    for q in [[edge, 0.0], [-edge, 1234.5], [0.5 * edge, -0.25 * edge]] {
        let single = robot.fk(&q, &deg).unwrap();
        let (tool, _) = robot.fk_frames(&q, &deg).unwrap();
        // The angle itself is only known to an ulp of 1e5 rad (1.5e-11); reach 0.8 m.
        assert!(
            single.max_abs_diff(&tool) <= 1e-9,
            "{q:?}: {:e}",
            single.max_abs_diff(&tool)
        );
    }
    // Limits in a model are bounded the same way.
    let mut wide = model.clone();
    wide["links"][0]["limits"] = json!([-1e9, 1e9]);
    let e =
        Robot::from_json(&serde_json::to_vec(&wide).unwrap(), &ModelLimits::default()).unwrap_err();
    assert_eq!(e.violations()[0].field, "links[0].limits");
}
