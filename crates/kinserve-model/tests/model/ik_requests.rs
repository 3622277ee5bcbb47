//! The validated layer of velocity and inverse kinematics (`kinserve-model`):
//! IK requests refused with their field paths, answers in the request's
//! angle unit that pass the FK check, batches seeded by the previous answer,
//! and `JointVector::jacobian` in both angle units.

use std::time::{Duration, Instant};

use kinserve_model::{
    AngleUnit, FkOptions, IkBatchSpec, IkSpec, IkTargetSpec, QuaternionSpec, ReferenceFrame, Robot,
    load_robot_file,
};
use serde_json::json;

fn load(name: &str) -> Robot {
    let path = format!("{}/../../robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    load_robot_file(std::path::Path::new(&path)).unwrap()
}

fn spec(v: serde_json::Value) -> IkSpec {
    serde_json::from_value(v).unwrap()
}

/// The field paths of the violations of an IK request that must be refused.
fn fields(robot: &Robot, v: serde_json::Value) -> Vec<String> {
    match robot.check_ik(&spec(v.clone())) {
        Ok(_) => panic!("should be refused: {v}"),
        Err(e) => e.violations().iter().map(|v| v.field.clone()).collect(),
    }
}

fn target_of(robot: &Robot, q: &[f64]) -> IkTargetSpec {
    let t = robot.fk(q, &FkOptions::default()).unwrap();
    let [w, x, y, z] = t.quaternion();
    IkTargetSpec {
        position: Some(t.translation),
        quaternion: Some(QuaternionSpec { w, x, y, z }),
        matrix: None,
    }
}

#[test]
fn bad_requests_name_their_fields() {
    let r = load("puma560");
    let id = [
        [1.0, 0.0, 0.0, 0.3],
        [0.0, 1.0, 0.0, 0.1],
        [0.0, 0.0, 1.0, 0.2],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let q = json!({"w": 1, "x": 0, "y": 0, "z": 0});
    let cases = [
        (json!({"target": {}}), vec!["target"]),
        (
            json!({"target": {"matrix": id, "position": [0, 0, 0]}}),
            vec!["target.matrix"],
        ),
        (
            json!({"target": {"matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]}}),
            vec!["target.matrix[3]"],
        ),
        (
            json!({"target": {"matrix": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}}),
            vec!["target.matrix"],
        ),
        (
            json!({"target": {"matrix": [[1, 0, 0, 2e9], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}}),
            vec!["target.matrix[0][3]"],
        ),
        (
            json!({"target": {"position": [0, 0, 0]}}),
            vec!["target.quaternion"],
        ),
        (
            json!({"target": {"position": [0, 0, 0], "quaternion": {"w": 0, "x": 0, "y": 0, "z": 0}}}),
            vec!["target.quaternion"],
        ),
        (
            json!({"target": {"position": [0, 2e9, 0], "quaternion": q}}),
            vec!["target.position[1]"],
        ),
        (
            json!({"target": {"matrix": id}, "tolerance": 0}),
            vec!["tolerance"],
        ),
        (
            json!({"target": {"matrix": id}, "tolerance": 1e4}),
            vec!["tolerance"],
        ),
        (
            json!({"target": {"matrix": id}, "max_iterations": 0}),
            vec!["max_iterations"],
        ),
        (
            json!({"target": {"matrix": id}, "restarts": 1001}),
            vec!["restarts"],
        ),
        (
            json!({"target": {"matrix": id}, "seed": [0, 0]}),
            vec!["seed"],
        ),
        (
            json!({"target": {"matrix": id}, "seed": [0, 0, 0, 0, 9, 0]}),
            vec!["seed[4]"],
        ),
        (
            json!({"target": {"position": [0, 0, 0]}, "tolerance": -1, "restarts": 5000}),
            vec!["target.quaternion", "tolerance", "restarts"],
        ),
    ];
    for (body, expected) in cases {
        assert_eq!(fields(&r, body.clone()), expected, "{body}");
    }
    // A seed in degrees is checked in degrees.
    let ok = json!({"target": {"matrix": id}, "seed": [0, 0, 0, 0, 90, 0], "angle_unit": "deg"});
    assert!(r.check_ik(&spec(ok)).is_ok());
    // Position only: no quaternion needed.
    let ok = json!({"target": {"position": [0.3, 0.1, 0.2]}, "position_only": true});
    assert!(r.check_ik(&spec(ok)).is_ok());
}

#[test]
fn unknown_fields_and_arrays_for_objects_are_refused_by_the_schema() {
    for body in [
        json!({"target": {"matrix": null}, "bogus": 1}),
        json!({"target": {"position": [0, 0, 0], "rpy": [0, 0, 0]}}),
        json!({"target": [null, null, null]}),
    ] {
        assert!(
            serde_json::from_value::<IkSpec>(body.clone()).is_err(),
            "{body}"
        );
    }
}

#[test]
fn batch_targets_are_named_by_index() {
    let r = load("ur5e");
    let batch: IkBatchSpec = serde_json::from_value(json!({
        "targets": [{"position": [0.3, 0.1, 0.2], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}}, {"position": [0, 0, 0]}],
        "max_iterations": 0
    }))
    .unwrap();
    let e = r.check_ik_batch(&batch).unwrap_err();
    let f: Vec<&str> = e.violations().iter().map(|v| v.field.as_str()).collect();
    assert_eq!(f, ["targets[1].quaternion", "max_iterations"]);
}

#[test]
fn answers_in_degrees_pass_the_fk_check_and_reach_the_target() {
    let r = load("puma560");
    let q = [0.3, -0.5, 0.2, 0.4, 0.6, -0.2];
    let target = target_of(&r, &q);
    for unit in [AngleUnit::Rad, AngleUnit::Deg] {
        let req = r
            .check_ik(&IkSpec {
                target: target.clone(),
                angle_unit: unit,
                ..IkSpec::default()
            })
            .unwrap();
        let a = req.solve(None);
        assert!(a.converged, "{a:?}");
        assert!(a.position_error <= 1e-9 && a.orientation_error.unwrap() <= 1e-9);
        // The answer in its unit passes the limit check and gives the reported pose.
        let pose = r
            .fk(&a.joints, &FkOptions::new(Some(unit), Some(true)))
            .unwrap();
        assert!(pose.max_abs_diff(&a.pose) <= 1e-12, "{unit:?}");
    }
}

#[test]
fn an_answer_at_a_limit_in_degrees_still_passes_the_limit_check() {
    // Targets at the upper limit of every joint: answers clamp to the limit,
    // whose value in degrees must not round to just outside it.
    for name in ["puma560", "kuka_kr5", "abb_irb140", "panda"] {
        let r = load(name);
        let q: Vec<f64> = r.joints().iter().map(|j| j.limits.unwrap().1).collect();
        let spec = IkSpec {
            target: target_of(&r, &q),
            seed: Some(q.iter().map(|x| x.to_degrees()).collect()),
            angle_unit: AngleUnit::Deg,
            ..IkSpec::default()
        };
        // The seed is the upper limit in degrees, rounded: it may be refused;
        // what matters is the answer, so seed from the middle if it is.
        let req = r.check_ik(&spec).or_else(|_| {
            r.check_ik(&IkSpec {
                seed: None,
                ..spec.clone()
            })
        });
        let a = req.unwrap().solve(None);
        r.check_joints(&a.joints, &FkOptions::new(Some(AngleUnit::Deg), Some(true)))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn position_only_without_orientation_reports_no_orientation_error() {
    let r = load("scara_4dof");
    let t = r.fk(&[0.3, -0.4, 0.1, 0.5], &FkOptions::default()).unwrap();
    let spec = IkSpec {
        target: IkTargetSpec {
            position: Some(t.translation),
            ..IkTargetSpec::default()
        },
        position_only: true,
        ..IkSpec::default()
    };
    let a = r.check_ik(&spec).unwrap().solve(None);
    assert!(a.converged && a.position_error <= 1e-9, "{a:?}");
    assert_eq!(a.orientation_error, None);
}

#[test]
fn a_batch_tracks_its_path_and_stops_at_the_deadline() {
    let r = load("ur5e");
    let path: Vec<IkTargetSpec> = (0..20)
        .map(|k| target_of(&r, &[0.3 + 0.01 * k as f64, -1.2, 1.1, -0.5, 1.3, 0.2]))
        .collect();
    let batch = IkBatchSpec {
        targets: path.clone(),
        seed: Some(vec![0.3, -1.2, 1.1, -0.5, 1.3, 0.2]),
        ..IkBatchSpec::default()
    };
    let checked = r.check_ik_batch(&batch).unwrap();
    let far = Instant::now() + Duration::from_secs(60);
    let answers = checked.solve(Duration::from_secs(10), far);
    assert_eq!(answers.len(), 20);
    for (k, a) in answers.iter().enumerate() {
        assert!(a.converged, "{k}: {a:?}");
        // Seeded by the previous answer: the same branch all along (joint 1 follows the path).
        assert!(
            (a.joints[0] - (0.3 + 0.01 * k as f64)).abs() < 1e-6,
            "{k}: {:?}",
            a.joints
        );
        assert!(a.iterations <= 10, "{k}: {} iterations", a.iterations);
    }
    // A deadline already passed: every target answered, none solved.
    let late = checked.solve(Duration::from_secs(10), Instant::now());
    assert_eq!(late.len(), 20);
    assert!(
        late.iter()
            .skip(1)
            .all(|a| !a.converged && a.iterations == 0)
    );
}

#[test]
fn the_jacobian_of_a_joint_vector_is_per_radian_in_either_unit() {
    let r = load("stanford");
    let q_rad: [f64; 6] = [0.2, -0.4, 0.5, 0.5, -0.6, 0.7];
    let mut q_deg = q_rad;
    for (x, j) in q_deg.iter_mut().zip(r.joints()) {
        if j.kind == kinserve_kinematics::JointKind::Revolute {
            *x = x.to_degrees();
        }
    }
    let a = r.check_joints(&q_rad, &FkOptions::default()).unwrap();
    let b = r
        .check_joints(&q_deg, &FkOptions::new(Some(AngleUnit::Deg), Some(true)))
        .unwrap();
    for frame in [ReferenceFrame::Base, ReferenceFrame::Tool] {
        let (ja, jb) = (a.jacobian(frame), b.jacobian(frame));
        assert_eq!(ja.frame, frame);
        assert!(ja.pose.max_abs_diff(&a.fk()) <= 1e-12);
        for (ca, cb) in ja.jacobian.columns().iter().zip(jb.jacobian.columns()) {
            for (x, y) in ca.iter().zip(cb) {
                assert!((x - y).abs() <= 1e-12);
            }
        }
        assert!((ja.measures.manipulability - jb.measures.manipulability).abs() <= 1e-12);
    }
}
