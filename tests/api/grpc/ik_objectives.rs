//! The IK objectives on every front door: a null-space `posture` for a
//! redundant arm (the posture error falls, the pose stays within the
//! tolerance), partial poses (`free_axes`, `axis_tolerances`: a tool free to
//! spin about its z axis reaches the rest of the pose), the same joints over
//! REST (`/ik`, `/ik/batch`), the WebSocket `ik` message and gRPC
//! `InverseKinematics` / `InverseKinematicsBatch`, and bad objectives refused
//! naming the same field everywhere.

use kinserve::api::grpc::pb;
use kinserve_testkit::RobotExt;
use serde_json::{Value, json};
use tonic::Code;

use super::velocity::{floats, ik_request, matrix_pb, rest_ok, spawn_ik_app, ws_one};
use crate::helpers::*;

/// Pose agreement asked of answers checked by the library's FK (length
/// unit, matrix entries): the default tolerance is 1e-9.
const POSE_TOL: f64 = 1e-8;

/// The Panda's preferred posture (deg): elbow bent, wrist square.
const POSTURE: [f64; 7] = [0.0, 0.0, 0.0, -90.0, 0.0, 90.0, 45.0];

fn model(name: &str) -> kinserve::model::Robot {
    let path = format!("{}/robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    kinserve::model::load_robot_file(std::path::Path::new(&path)).unwrap()
}

/// Tool pose (4×4) of `q` in degrees by the library's FK.
fn fk_deg(robot: &kinserve::model::Robot, q: &[f64]) -> [[f64; 4]; 4] {
    let rad: Vec<f64> = q.iter().map(|x| x.to_radians()).collect();
    robot.fk_unchecked(&rad).matrix()
}

/// Σ (q − posture)² in rad².
fn posture_error(q: &[f64]) -> f64 {
    q.iter()
        .zip(POSTURE)
        .map(|(a, b)| (a - b).to_radians().powi(2))
        .sum()
}

/// A gRPC IK request for the 4×4 `goal`.
fn goal_request(
    robot: &str,
    goal: &[[f64; 4]; 4],
    unit: pb::AngleUnit,
) -> pb::InverseKinematicsRequest {
    let target = pb::IkTarget {
        matrix: Some(matrix_pb(&json!({ "matrix": goal }))),
        ..Default::default()
    };
    ik_request(robot, target, unit)
}

fn grpc_posture() -> pb::IkPosture {
    pb::IkPosture {
        joints: POSTURE.to_vec(),
        weights: Vec::new(),
    }
}

#[tokio::test]
async fn a_posture_pulls_a_redundant_arm_and_is_the_same_on_every_door() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let panda = model("panda");
    let (mut plain_total, mut pulled_total) = (0.0, 0.0);
    for q in [
        [40.0, 30.0, -20.0, -120.0, 30.0, 100.0, 10.0],
        [-30.0, 50.0, 40.0, -60.0, -40.0, 150.0, -60.0],
        [70.0, -20.0, -60.0, -140.0, 60.0, 60.0, 100.0],
    ] {
        let goal = fk_deg(&panda, &q);
        let target = json!({"matrix": goal});
        let plain = json!({"target": target, "angle_unit": "deg"});
        let body = json!({"target": target, "angle_unit": "deg",
            "posture": {"joints": POSTURE}});
        let a = rest_ok(&app, "/v1/robots/panda/ik", &plain).await;
        let b = rest_ok(&app, "/v1/robots/panda/ik", &body).await;
        assert_eq!(b["solver"], "numeric", "{b}");
        for answer in [&a, &b] {
            assert_eq!(answer["converged"], true, "{answer}");
            let reached = fk_deg(&panda, &floats(&answer["joints"]));
            for (r, g) in reached.iter().flatten().zip(goal.iter().flatten()) {
                assert!((r - g).abs() < POSE_TOL, "{answer}");
            }
        }
        plain_total += posture_error(&floats(&a["joints"]));
        pulled_total += posture_error(&floats(&b["joints"]));
        let ws = ws_one(&app, "panda", json!({"id": 1, "ik": body})).await;
        assert_eq!(ws["joints"], b["joints"], "WebSocket");
        let batch = json!({"targets": [target], "angle_unit": "deg",
            "posture": {"joints": POSTURE}});
        let batch = rest_ok(&app, "/v1/robots/panda/ik/batch", &batch).await;
        assert_eq!(batch["results"][0]["joints"], b["joints"], "batch");
        let mut req = goal_request("panda", &goal, pb::AngleUnit::Deg);
        req.posture = Some(grpc_posture());
        let g = c
            .inverse_kinematics(req.clone())
            .await
            .unwrap()
            .into_inner();
        assert_eq!(g.result.unwrap().joints, floats(&b["joints"]), "gRPC");
        let gb = pb::InverseKinematicsBatchRequest {
            robot: "panda".into(),
            targets: vec![req.target.clone().unwrap()],
            angle_unit: pb::AngleUnit::Deg as i32,
            posture: Some(grpc_posture()),
            ..Default::default()
        };
        let gb = c.inverse_kinematics_batch(gb).await.unwrap().into_inner();
        assert_eq!(gb.results[0].joints, floats(&b["joints"]), "gRPC batch");
    }
    assert!(
        pulled_total < plain_total,
        "posture error with the posture {pulled_total} rad², without {plain_total} rad²"
    );
}

#[tokio::test]
async fn a_tool_free_to_spin_reaches_the_rest_of_the_pose_on_every_door() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let puma = model("puma560");
    let q = [20.0, -30.0, 45.0, 10.0, 50.0, -20.0];
    let mut goal = fk_deg(&puma, &q);
    // Turn the target 40° about its own z axis: the same approach direction
    // and position, a spin the answer may keep or drop.
    let (s, c40) = 40f64.to_radians().sin_cos();
    for row in goal.iter_mut().take(3) {
        let (x, y) = (row[0], row[1]);
        row[0] = c40 * x + s * y;
        row[1] = -s * x + c40 * y;
    }
    let body = json!({"target": {"matrix": goal}, "angle_unit": "deg", "free_axes": ["rz"],
        "axis_tolerances": {"x": 1e-9, "y": 1e-9}});
    let rest = rest_ok(&app, "/v1/robots/puma560/ik", &body).await;
    // The spin was left where the solver found the rest of the pose, not
    // turned the 40° a full pose asks for.
    assert!(rest["orientation_error"].as_f64().unwrap() > 1e-3, "{rest}");
    assert_eq!(
        (&rest["converged"], &rest["solver"]),
        (&json!(true), &json!("numeric")),
        "{rest}"
    );
    let reached = fk_deg(&puma, &floats(&rest["joints"]));
    for i in 0..3 {
        assert!(
            (reached[i][2] - goal[i][2]).abs() < POSE_TOL,
            "z axis: {rest}"
        );
        assert!(
            (reached[i][3] - goal[i][3]).abs() < POSE_TOL,
            "position: {rest}"
        );
    }
    let ws = ws_one(&app, "puma560", json!({"id": 2, "ik": body})).await;
    assert_eq!(ws["joints"], rest["joints"], "WebSocket");
    let mut req = goal_request("puma560", &goal, pb::AngleUnit::Deg);
    req.free_axes = vec![pb::PoseAxis::Rz as i32];
    req.axis_tolerances = Some(pb::AxisTolerances {
        x: Some(1e-9),
        y: Some(1e-9),
        ..Default::default()
    });
    let g = c.inverse_kinematics(req).await.unwrap().into_inner();
    assert_eq!(g.result.unwrap().joints, floats(&rest["joints"]), "gRPC");
}

#[tokio::test]
async fn a_tilt_a_scara_cannot_make_is_reached_once_left_free() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let scara = model("scara_4dof");
    // A reachable pose tilted 0.3 rad about its x axis: no SCARA tilts its tool.
    let (s, c3) = 0.3f64.sin_cos();
    let mut goal = scara.fk_unchecked(&[0.4, -0.7, 0.1, 0.2]).matrix();
    for row in goal.iter_mut().take(3) {
        let (y, z) = (row[1], row[2]);
        row[1] = c3 * y + s * z;
        row[2] = -s * y + c3 * z;
    }
    let full = json!({"target": {"matrix": goal}, "restarts": 5});
    let p = problem(app.post("/v1/robots/scara_4dof/ik", &full).await, 422).await;
    assert_eq!(p["type"], "urn:kinserve:problem:ik-not-converged", "{p}");
    let free = json!({"target": {"matrix": goal}, "free_axes": ["rx", "ry"]});
    let rest = rest_ok(&app, "/v1/robots/scara_4dof/ik", &free).await;
    let reached = scara.fk_unchecked(&floats(&rest["joints"])).matrix();
    for i in 0..3 {
        assert!((reached[i][3] - goal[i][3]).abs() < POSE_TOL, "{rest}");
    }
    // What is left of the rotation is the tilt.
    let left = rest["orientation_error"].as_f64().unwrap();
    assert!((left - 0.3).abs() < POSE_TOL, "{rest}");
    let mut req = goal_request("scara_4dof", &goal, pb::AngleUnit::Rad);
    req.free_axes = vec![pb::PoseAxis::Rx as i32, pb::PoseAxis::Ry as i32];
    let g = c.inverse_kinematics(req).await.unwrap().into_inner();
    assert_eq!(g.result.unwrap().joints, floats(&rest["joints"]), "gRPC");
}

/// A refused objective: the REST body's extra fields, the same on gRPC, the
/// field both must name.
type Case = (Value, fn(&mut pb::InverseKinematicsRequest), &'static str);

#[tokio::test]
async fn bad_objectives_name_the_same_field_everywhere() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let goal = fk_deg(&model("panda"), &[10.0, 20.0, 0.0, -90.0, 0.0, 100.0, 0.0]);
    let cases: [Case; 6] = [
        (
            json!({"posture": {"joints": [0, 0, 0]}}),
            |r| {
                r.posture = Some(pb::IkPosture {
                    joints: vec![0.0; 3],
                    weights: vec![],
                })
            },
            "posture.joints",
        ),
        (
            json!({"posture": {"joints": POSTURE, "weights": [1, 1, 2, 1, 1, 1, 1]}}),
            |r| {
                r.posture = Some(pb::IkPosture {
                    joints: POSTURE.to_vec(),
                    weights: vec![1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 1.0],
                })
            },
            "posture.weights[2]",
        ),
        (
            json!({"axis_tolerances": {"rz": 0}}),
            |r| {
                r.axis_tolerances = Some(pb::AxisTolerances {
                    rz: Some(0.0),
                    ..Default::default()
                })
            },
            "axis_tolerances.rz",
        ),
        (
            json!({"free_axes": ["x", "y", "z", "rx", "ry", "rz"]}),
            |r| r.free_axes = (1..=6).collect(),
            "free_axes",
        ),
        (
            json!({"free_axes": ["rz"], "solutions": "all"}),
            |r| {
                r.free_axes = vec![pb::PoseAxis::Rz as i32];
                r.solutions = pb::IkSolutions::All as i32;
            },
            "solutions",
        ),
        (
            json!({"posture": {"joints": POSTURE}, "solver": "analytic"}),
            |r| {
                r.posture = Some(grpc_posture());
                r.solver = pb::IkSolver::Analytic as i32;
            },
            "solver",
        ),
    ];
    for (extra, set, field) in cases {
        let mut body = json!({"target": {"matrix": goal}, "angle_unit": "deg"});
        body.as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        let p = problem(app.post("/v1/robots/panda/ik", &body).await, 422).await;
        assert_eq!(p["errors"][0]["field"], field, "REST {body}: {p}");
        let ws = ws_one(&app, "panda", json!({"id": 1, "ik": body})).await;
        assert_eq!(ws["error"]["errors"][0]["field"], field, "WebSocket {ws}");
        let mut req = goal_request("panda", &goal, pb::AngleUnit::Deg);
        set(&mut req);
        let s = c.inverse_kinematics(req).await.unwrap_err();
        assert_eq!(s.code(), Code::InvalidArgument, "gRPC {body}");
        assert_eq!(status_fields(&s), vec![field.to_string()], "gRPC {body}");
    }
    // An axis that does not exist: a malformed body / an unknown enum value.
    let body = json!({"target": {"matrix": goal}, "free_axes": ["w"]});
    let p = problem(app.post("/v1/robots/panda/ik", &body).await, 400).await;
    assert!(p["detail"].as_str().unwrap().contains("free_axes"), "{p}");
    let mut req = goal_request("panda", &goal, pb::AngleUnit::Rad);
    req.free_axes = vec![99];
    let s = c.inverse_kinematics(req).await.unwrap_err();
    assert_eq!(
        (s.code(), status_fields(&s)),
        (Code::InvalidArgument, vec!["free_axes[0]".to_string()])
    );
}

#[tokio::test]
async fn a_path_keeps_its_posture_and_is_the_same_on_rest_and_grpc() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let panda = model("panda");
    let start = [10.0, 20.0, -10.0, -100.0, 10.0, 110.0, 30.0];
    let goal = fk_deg(&panda, &start);
    let quaternion = fk_ok(&app, "panda", json!({"joints": start, "angle_unit": "deg"})).await
        ["pose"]["quaternion"]
        .clone();
    let end = [goal[0][3], goal[1][3], goal[2][3] - 0.05];
    let base = json!({"start": start, "angle_unit": "deg", "max_step_length": 0.01,
        "waypoints": [{"position": end, "quaternion": quaternion}]});
    let mut pulled = base.clone();
    pulled["posture"] = json!({"joints": POSTURE});
    let plain = rest_ok(&app, "/v1/robots/panda/ik/path", &base).await;
    let rest = rest_ok(&app, "/v1/robots/panda/ik/path", &pulled).await;
    assert_eq!(
        (&rest["fraction"], &plain["fraction"]),
        (&json!(1.0), &json!(1.0)),
        "{rest}"
    );
    // Every step reaches its point of the line; the last the waypoint.
    let last = floats(rest["points"].as_array().unwrap().last().unwrap());
    let reached = fk_deg(&panda, &last);
    for (i, e) in end.iter().enumerate() {
        assert!((reached[i][3] - e).abs() < POSE_TOL, "{rest}");
    }
    let err = |v: &Value| posture_error(&floats(v["points"].as_array().unwrap().last().unwrap()));
    assert!(
        err(&rest) < err(&plain),
        "posture {} vs {}",
        err(&rest),
        err(&plain)
    );
    let q = &quaternion;
    let req = pb::InverseKinematicsPathRequest {
        robot: "panda".into(),
        start: Some(pb::JointConfiguration {
            joints: start.to_vec(),
        }),
        waypoints: vec![pb::IkTarget {
            position: Some(pb::Vector3 {
                x: end[0],
                y: end[1],
                z: end[2],
            }),
            quaternion: Some(pb::Quaternion {
                w: q["w"].as_f64().unwrap(),
                x: q["x"].as_f64().unwrap(),
                y: q["y"].as_f64().unwrap(),
                z: q["z"].as_f64().unwrap(),
            }),
            ..Default::default()
        }],
        angle_unit: pb::AngleUnit::Deg as i32,
        max_step_length: Some(0.01),
        posture: Some(grpc_posture()),
        ..Default::default()
    };
    let g = c.inverse_kinematics_path(req).await.unwrap().into_inner();
    let points: Vec<Vec<f64>> = g.points.into_iter().map(|p| p.joints).collect();
    let want: Vec<Vec<f64>> = rest["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(floats)
        .collect();
    assert_eq!(points, want, "gRPC");
}
