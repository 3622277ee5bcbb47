//! Cartesian paths through the validated layer: every step's FK lies on the
//! straight line between the poses (positions 1e-9, orientations by slerp),
//! no joint moves more than `max_joint_step` between steps, the end reaches
//! the last waypoint; stops are reported with their step and reason
//! (`unreachable` / `joint_limits`, `joint_jump`, `singularity`); bad paths
//! name their field.

use kinserve_kinematics::Transform;
use kinserve_model::{
    FkOptions, IkPathSpec, IkTargetSpec, ModelError, PathStopReason, QuaternionSpec, Robot,
    load_robot_file,
};
use serde_json::json;

fn load(name: &str) -> Robot {
    let path = format!("{}/../../robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    load_robot_file(std::path::Path::new(&path)).unwrap()
}

fn target(t: &Transform) -> IkTargetSpec {
    let [w, x, y, z] = t.quaternion();
    IkTargetSpec {
        position: Some(t.translation),
        quaternion: Some(QuaternionSpec { w, x, y, z }),
        matrix: None,
    }
}

fn fk(r: &Robot, q: &[f64]) -> Transform {
    r.fk(q, &FkOptions::default()).unwrap()
}

/// Distance of `p` from the segment `a`–`b`.
fn off_line(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab: Vec<f64> = (0..3).map(|i| b[i] - a[i]).collect();
    let ap: Vec<f64> = (0..3).map(|i| p[i] - a[i]).collect();
    let len2: f64 = ab.iter().map(|x| x * x).sum();
    let s = if len2 == 0.0 {
        0.0
    } else {
        (0..3).map(|i| ab[i] * ap[i]).sum::<f64>() / len2
    };
    let s = s.clamp(0.0, 1.0);
    (0..3)
        .map(|i| (ap[i] - s * ab[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

#[test]
fn a_straight_path_stays_on_its_line_without_joint_jumps() {
    for (name, start, lift) in [
        (
            "puma560",
            vec![0.1, -0.4, 0.6, 0.2, 0.5, -0.3],
            [0.05, 0.1, -0.15],
        ),
        (
            "ur5e",
            vec![0.4, -1.2, 1.3, -0.7, 1.2, 0.3],
            [-0.1, 0.05, 0.1],
        ),
        (
            "panda",
            vec![0.1, -0.3, 0.2, -2.0, 0.1, 1.8, 0.6],
            [0.05, -0.05, 0.08],
        ),
    ] {
        let r = load(name);
        let a = fk(&r, &start);
        let mut b = a;
        for (x, d) in b.translation.iter_mut().zip(lift) {
            *x += d;
        }
        let spec = IkPathSpec {
            start: start.clone(),
            waypoints: vec![target(&b)],
            max_step_length: Some(0.005),
            ..IkPathSpec::default()
        };
        let req = r.check_ik_path(&spec, 10_000).unwrap();
        let answer = req.solve(None);
        assert_eq!(answer.stop, None, "{name}");
        assert_eq!((answer.fraction, answer.waypoints_reached), (1.0, 1));
        assert_eq!(answer.points.len(), req.len() + 1);
        assert_eq!(answer.points[0], start);
        let max_jump = kinserve_model::PATH_DEFAULT_JOINT_STEP;
        for (k, w) in answer.points.windows(2).enumerate() {
            let p = fk(&r, &w[1]);
            assert!(
                off_line(p.translation, a.translation, b.translation) < 1e-9,
                "{name} step {k}"
            );
            // Orientation constant along this path.
            assert!(
                p.rotation
                    .iter()
                    .flatten()
                    .zip(a.rotation.iter().flatten())
                    .all(|(x, y)| (x - y).abs() < 1e-8),
                "{name} step {k}"
            );
            assert!(
                w[0].iter()
                    .zip(&w[1])
                    .all(|(x, y)| (x - y).abs() <= max_jump),
                "{name} step {k}"
            );
            assert!(r.check_joints(&w[1], &FkOptions::default()).is_ok());
        }
        let end = fk(&r, answer.points.last().unwrap());
        assert!(
            end.max_abs_diff(&b) < 1e-8,
            "{name}: end reaches the waypoint"
        );
    }
}

#[test]
fn orientations_are_slerped_and_waypoints_counted() {
    let r = load("puma560");
    let start = vec![0.1, -0.4, 0.6, 0.2, 0.5, -0.3];
    let mid = fk(&r, &[0.2, -0.35, 0.55, 0.3, 0.6, -0.1]);
    let end = fk(&r, &[0.3, -0.3, 0.5, 0.4, 0.7, 0.1]);
    let spec = IkPathSpec {
        start,
        waypoints: vec![target(&mid), target(&end)],
        max_step_angle: Some(0.01),
        ..IkPathSpec::default()
    };
    let answer = r.check_ik_path(&spec, 10_000).unwrap().solve(None);
    assert_eq!(
        (
            answer.fraction,
            answer.waypoints_reached,
            answer.stop.clone()
        ),
        (1.0, 2, None)
    );
    // Some step lands on the middle waypoint exactly.
    assert!(
        answer
            .points
            .iter()
            .any(|q| fk(&r, q).max_abs_diff(&mid) < 1e-8)
    );
    // Consecutive orientations differ by at most max_step_angle (plus rounding).
    for w in answer.points.windows(2) {
        let (p, q) = (fk(&r, &w[0]).quaternion(), fk(&r, &w[1]).quaternion());
        let dot: f64 = (0..4).map(|i| p[i] * q[i]).sum::<f64>().abs().min(1.0);
        assert!(2.0 * dot.acos() <= 0.01 + 1e-9);
    }
}

#[test]
fn a_path_out_of_reach_stops_at_the_first_unreached_step() {
    let r = load("puma560");
    let start = vec![0.0, -0.3, 0.3, 0.0, 0.5, 0.0];
    let mut far = fk(&r, &start);
    far.translation[0] += 2.0;
    let spec = IkPathSpec {
        start,
        waypoints: vec![target(&far)],
        max_step_length: Some(0.02),
        ..IkPathSpec::default()
    };
    let answer = r.check_ik_path(&spec, 10_000).unwrap().solve(None);
    let stop = answer.stop.expect("stopped");
    assert!(
        matches!(
            stop.reason,
            PathStopReason::Unreachable | PathStopReason::JointLimits
        ),
        "{stop:?}"
    );
    assert_eq!(
        stop.step,
        answer.points.len(),
        "the step after the last point"
    );
    assert!(answer.fraction > 0.0 && answer.fraction < 1.0);
    assert_eq!(answer.waypoints_reached, 0);
}

#[test]
fn a_joint_jump_over_the_limit_stops_the_path() {
    let r = load("ur5e");
    let start = vec![0.4, -1.2, 1.3, -0.7, 1.2, 0.3];
    let mut b = fk(&r, &start);
    b.translation[2] += 0.05;
    let spec = IkPathSpec {
        start,
        waypoints: vec![target(&b)],
        max_joint_step: Some(1e-4),
        ..IkPathSpec::default()
    };
    let answer = r.check_ik_path(&spec, 10_000).unwrap().solve(None);
    let stop = answer.stop.expect("stopped");
    assert_eq!((stop.step, stop.reason), (1, PathStopReason::JointJump));
    assert!(stop.detail.contains("max_joint_step"), "{}", stop.detail);
    assert_eq!(answer.points.len(), 1);
    assert_eq!(answer.fraction, 0.0);
}

#[test]
fn a_step_onto_a_wrist_singularity_stops_the_path() {
    let r = load("puma560");
    let start = vec![0.2, -0.5, 0.8, 0.3, 0.4, 0.1];
    // Joint 5 at 0: axes 4 and 6 aligned.
    let singular = fk(&r, &[0.2, -0.5, 0.8, 0.3, 0.0, 0.1]);
    let spec = IkPathSpec {
        start,
        waypoints: vec![target(&singular)],
        max_step_length: Some(1.0),
        max_step_angle: Some(3.0),
        max_joint_step: Some(3.0),
        ..IkPathSpec::default()
    };
    let answer = r.check_ik_path(&spec, 10_000).unwrap().solve(None);
    let stop = answer.stop.expect("stopped");
    assert_eq!(
        (stop.step, stop.reason),
        (1, PathStopReason::Singularity),
        "{stop:?}"
    );
}

#[test]
fn bad_paths_name_their_fields() {
    let r = load("puma560");
    let t = serde_json::to_value(target(&fk(&r, &[0.1; 6]))).unwrap();
    let cases = [
        (json!({"start": [0, 0, 0], "waypoints": [t]}), "start"),
        (
            json!({"start": [0, 0, 0, 0, 9, 0], "waypoints": [t]}),
            "start[4]",
        ),
        (
            json!({"start": [0, 0, 0, 0, 0, 0], "waypoints": []}),
            "waypoints",
        ),
        (
            json!({"start": [0, 0, 0, 0, 0, 0], "waypoints": [{"position": [0, 0, 0]}]}),
            "waypoints[0].quaternion",
        ),
        (
            json!({"start": [0, 0, 0, 0, 0, 0], "waypoints": [t], "max_step_length": 0}),
            "max_step_length",
        ),
        (
            json!({"start": [0, 0, 0, 0, 0, 0], "waypoints": [t], "max_step_angle": -1}),
            "max_step_angle",
        ),
        (
            json!({"start": [0, 0, 0, 0, 0, 0], "waypoints": [t], "max_joint_step": 0}),
            "max_joint_step",
        ),
        (
            json!({"start": [0, 0, 0, 0, 0, 0], "waypoints": [t], "tolerance": 0}),
            "tolerance",
        ),
    ];
    for (body, field) in cases {
        let spec: IkPathSpec = serde_json::from_value(body.clone()).unwrap();
        let e = r.check_ik_path(&spec, 10_000).unwrap_err();
        assert_eq!(e.violations()[0].field, field, "{body}: {e}");
    }
    let panda = load("panda");
    let spec: IkPathSpec = serde_json::from_value(
        json!({"start": [0, 0, 0, -1, 0, 1, 0], "waypoints": [t], "solver": "analytic"}),
    )
    .unwrap();
    assert_eq!(
        panda.check_ik_path(&spec, 10_000).unwrap_err().violations()[0].field,
        "solver"
    );
    // A path needing more steps than allowed: refused before solving.
    let spec: IkPathSpec = serde_json::from_value(
        json!({"start": [0, 0, 0, 0, 0, 0], "waypoints": [t], "max_step_length": 1e-6}),
    )
    .unwrap();
    match r.check_ik_path(&spec, 10_000) {
        Err(ModelError::TooLarge { field, .. }) => {
            assert_eq!(field.as_deref(), Some("max_step_length"))
        }
        other => panic!("expected too large: {other:?}"),
    }
}

#[test]
fn a_position_only_path_keeps_the_tool_on_the_line() {
    let r = load("planar_2dof");
    let start = vec![0.3, 0.9];
    let a = fk(&r, &start);
    let mut b = a;
    b.translation[1] += 0.1;
    let spec = IkPathSpec {
        start,
        waypoints: vec![IkTargetSpec {
            position: Some(b.translation),
            ..IkTargetSpec::default()
        }],
        position_only: true,
        ..IkPathSpec::default()
    };
    let answer = r.check_ik_path(&spec, 10_000).unwrap().solve(None);
    assert_eq!(answer.stop, None);
    for q in &answer.points {
        assert!(off_line(fk(&r, q).translation, a.translation, b.translation) < 1e-9);
    }
}
