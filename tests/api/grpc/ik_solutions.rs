//! Closed-form IK on every front door: `solutions: "all"` / `solver` over
//! REST (`/ik`, `/ik/batch`), the WebSocket `ik` message, gRPC
//! `InverseKinematics` / `InverseKinematicsBatch` and the gRPC stream — the
//! same solutions, branches and solver everywhere, each solution checked here
//! by the kinematics library's FK (1e-10); the robot list's `ik_class`; and
//! requests the arm cannot honour refused naming the same field
//! (`solver`, `solutions`, `max_solutions`) on every door.

use kinserve::api::grpc::pb;
use kinserve_testkit::RobotExt;
use serde_json::{Value, json};
use tonic::Code;

use super::velocity::{floats, ik_request, matrix_pb, rest_ok, spawn_ik_app, ws_one};
use crate::helpers::*;

/// FK agreement asked of every solution (length unit, matrix entries).
const FK_TOL: f64 = 1e-10;

/// A library model of a built-in robot.
fn model(name: &str) -> kinserve::model::Robot {
    let path = format!("{}/robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    kinserve::model::load_robot_file(std::path::Path::new(&path)).unwrap()
}

/// Every solution of a JSON answer reaches `goal` by the library's FK (deg).
fn check_solutions(robot: &str, answer: &Value, goal: &[[f64; 4]; 4]) -> usize {
    let m = model(robot);
    let sols = answer["solutions"].as_array().expect("solutions");
    for s in sols {
        let q: Vec<f64> = floats(&s["joints"])
            .iter()
            .map(|x| x.to_radians())
            .collect();
        let pose = m.fk_unchecked(&q).matrix();
        for i in 0..4 {
            for j in 0..4 {
                assert!((pose[i][j] - goal[i][j]).abs() < FK_TOL, "{robot}: {s}");
            }
        }
        assert!(s["branch"].is_object(), "{s}");
    }
    sols.len()
}

#[tokio::test]
async fn every_solution_is_the_same_on_rest_websocket_and_grpc() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    for (robot, q) in [
        ("puma560", [20.0, -30.0, 45.0, 10.0, 50.0, -20.0]),
        ("ur5e", [30.0, -80.0, 70.0, -40.0, 80.0, 10.0]),
    ] {
        let qr: Vec<f64> = q.iter().map(|x: &f64| x.to_radians()).collect();
        let goal = model(robot).fk_unchecked(&qr).matrix();
        let pose =
            fk_ok(&app, robot, json!({"joints": q, "angle_unit": "deg"})).await["pose"].clone();
        let body = json!({"target": {"matrix": pose["matrix"]}, "angle_unit": "deg",
            "solutions": "all", "max_solutions": 32});
        let rest = rest_ok(&app, &format!("/v1/robots/{robot}/ik"), &body).await;
        assert_eq!(rest["solver"], "analytic", "{rest}");
        assert_eq!(rest["iterations"], 0);
        let n = check_solutions(robot, &rest, &goal);
        assert!(n >= 2, "{robot}: {n} solutions");
        assert_eq!(rest["joints"], rest["solutions"][0]["joints"]);
        // The source configuration is among them.
        assert!(rest["solutions"].as_array().unwrap().iter().any(|s| {
            floats(&s["joints"])
                .iter()
                .zip(q)
                .all(|(a, b)| (a - b).abs() < 1e-6)
        }));
        let ws = ws_one(&app, robot, json!({"id": 3, "ik": body})).await;
        assert_eq!(ws["solutions"], rest["solutions"], "{robot}: WebSocket");
        assert_eq!(ws["solver"], "analytic");
        let batch = rest_ok(
            &app,
            &format!("/v1/robots/{robot}/ik/batch"),
            &json!({"targets": [{"matrix": pose["matrix"]}], "angle_unit": "deg",
                "solutions": "all", "max_solutions": 32}),
        )
        .await;
        assert_eq!(
            batch["results"][0]["solutions"], rest["solutions"],
            "{robot}: batch"
        );
        let mut req = ik_request(
            robot,
            pb::IkTarget {
                matrix: Some(matrix_pb(&pose)),
                ..Default::default()
            },
            pb::AngleUnit::Deg,
        );
        req.solutions = pb::IkSolutions::All as i32;
        req.max_solutions = Some(32);
        let g = c
            .inverse_kinematics(req)
            .await
            .unwrap()
            .into_inner()
            .result
            .unwrap();
        assert_eq!(g.solver, pb::IkSolver::Analytic as i32);
        assert_eq!(g.solutions.len(), n, "{robot}: gRPC count");
        for (gs, rs) in g
            .solutions
            .iter()
            .zip(rest["solutions"].as_array().unwrap())
        {
            assert_eq!(gs.joints, floats(&rs["joints"]), "{robot}: gRPC joints");
            let b = gs.branch.as_ref().unwrap();
            assert_eq!(
                json!({"shoulder": b.shoulder, "elbow": b.elbow, "wrist": b.wrist}),
                rs["branch"]
            );
            assert_eq!(Some(gs.distance), rs["distance"].as_f64());
        }
        assert_eq!(g.truncated, rest["truncated"].as_bool());
    }
}

#[tokio::test]
async fn the_robot_list_says_which_arms_have_a_closed_form() {
    let app = spawn_ik_app().await;
    let list: Value = app
        .get("/v1/robots?page_size=100")
        .await
        .json()
        .await
        .unwrap();
    let class = |name: &str| {
        list["robots"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["name"] == name)
            .unwrap()["ik_class"]
            .clone()
    };
    assert_eq!(class("puma560"), "spherical_wrist_parallel_23");
    assert_eq!(class("ur5e"), "three_parallel_234");
    assert_eq!(class("panda"), Value::Null, "7 joints: numeric only");
    let mut c = app.grpc_client().await;
    let g = c
        .list_robots(pb::ListRobotsRequest {
            page_size: 100,
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    for r in g.robots {
        assert_eq!(
            r.ik_class.map(Value::from).unwrap_or(Value::Null),
            class(&r.name),
            "{}",
            r.name
        );
    }
}

#[tokio::test]
async fn requests_the_closed_form_cannot_honour_name_the_same_field_everywhere() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let panda_pose = fk_ok(
        &app,
        "panda",
        json!({"joints": [0.1, 0.2, 0.3, -1.0, 0.4, 1.0, 0.5]}),
    )
    .await["pose"]
        .clone();
    let puma_pose = fk_ok(
        &app,
        "puma560",
        json!({"joints": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]}),
    )
    .await["pose"]
        .clone();
    let cases = [
        (
            "panda",
            &panda_pose,
            json!({"solver": "analytic"}),
            pb::IkSolver::Analytic,
            pb::IkSolutions::Unspecified,
            None,
            "solver",
        ),
        (
            "panda",
            &panda_pose,
            json!({"solutions": "all"}),
            pb::IkSolver::Unspecified,
            pb::IkSolutions::All,
            None,
            "solutions",
        ),
        (
            "puma560",
            &puma_pose,
            json!({"solver": "numeric", "solutions": "all"}),
            pb::IkSolver::Numeric,
            pb::IkSolutions::All,
            None,
            "solutions",
        ),
        (
            "puma560",
            &puma_pose,
            json!({"max_solutions": 5}),
            pb::IkSolver::Unspecified,
            pb::IkSolutions::Unspecified,
            Some(5),
            "max_solutions",
        ),
        (
            "puma560",
            &puma_pose,
            json!({"solutions": "all", "max_solutions": 5000}),
            pb::IkSolver::Unspecified,
            pb::IkSolutions::All,
            Some(5000),
            "max_solutions",
        ),
    ];
    for (robot, pose, extra, solver, solutions, max, field) in cases {
        let mut body = json!({"target": {"matrix": pose["matrix"]}});
        body.as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        let p = problem(
            app.post(&format!("/v1/robots/{robot}/ik"), &body).await,
            422,
        )
        .await;
        assert_eq!(p["errors"][0]["field"], field, "REST {body}: {p}");
        let ws = ws_one(&app, robot, json!({"id": 1, "ik": body})).await;
        assert_eq!(
            ws["error"]["errors"][0]["field"], field,
            "WebSocket {body}: {ws}"
        );
        let mut req = ik_request(
            robot,
            pb::IkTarget {
                matrix: Some(matrix_pb(pose)),
                ..Default::default()
            },
            pb::AngleUnit::Rad,
        );
        req.solver = solver as i32;
        req.solutions = solutions as i32;
        req.max_solutions = max;
        let s = c.inverse_kinematics(req).await.unwrap_err();
        assert_eq!(s.code(), Code::InvalidArgument, "gRPC {body}");
        assert_eq!(status_fields(&s), vec![field.to_string()], "gRPC {body}");
    }
    // A batch whose solutions could not fit: 413 / RESOURCE_EXHAUSTED on max_solutions.
    let targets = vec![json!({"matrix": puma_pose["matrix"]}); 2_000];
    let body = json!({"targets": targets, "solutions": "all"});
    let p = problem(app.post("/v1/robots/puma560/ik/batch", &body).await, 413).await;
    assert_eq!(p["errors"][0]["field"], "max_solutions", "{p}");
    let req = pb::InverseKinematicsBatchRequest {
        robot: "puma560".into(),
        targets: vec![
            pb::IkTarget {
                matrix: Some(matrix_pb(&puma_pose)),
                ..Default::default()
            };
            2_000
        ],
        solutions: pb::IkSolutions::All as i32,
        ..Default::default()
    };
    let s = c.inverse_kinematics_batch(req).await.unwrap_err();
    assert_eq!(s.code(), Code::ResourceExhausted);
    // An unknown enum value on the wire is refused too.
    let mut req = ik_request(
        "puma560",
        pb::IkTarget {
            matrix: Some(matrix_pb(&puma_pose)),
            ..Default::default()
        },
        pb::AngleUnit::Rad,
    );
    req.solver = 99;
    let s = c.inverse_kinematics(req).await.unwrap_err();
    assert_eq!(
        (s.code(), status_fields(&s)),
        (Code::InvalidArgument, vec!["solver".to_string()])
    );
}

#[tokio::test]
async fn a_cartesian_path_is_the_same_on_rest_websocket_and_grpc() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let start = [5.0, -20.0, 35.0, 10.0, 30.0, -15.0];
    let pose = fk_ok(
        &app,
        "puma560",
        json!({"joints": start, "angle_unit": "deg"}),
    )
    .await["pose"]
        .clone();
    let mut end = pose["position"].clone();
    end[2] = json!(end[2].as_f64().unwrap() + 0.04);
    let far = json!([2.0, 0.0, 0.5]);
    let target = |p: &Value| json!({"position": p, "quaternion": pose["quaternion"]});
    let body = json!({"start": start, "angle_unit": "deg", "waypoints": [target(&end), target(&far)],
        "max_step_length": 0.01});
    let rest = rest_ok(&app, "/v1/robots/puma560/ik/path", &body).await;
    // The first leg is taken (4 steps of 1 cm), the second stops where the arm runs out of reach.
    assert_eq!(rest["waypoints_reached"], 1, "{rest}");
    let points = rest["points"].as_array().unwrap();
    assert!(points.len() > 5, "{rest}");
    let stop = &rest["stop"];
    assert!(
        ["unreachable", "joint_limits", "joint_jump"].contains(&stop["reason"].as_str().unwrap()),
        "{stop}"
    );
    assert_eq!(stop["step"].as_u64(), Some(points.len() as u64));
    let f = rest["fraction"].as_f64().unwrap();
    assert!(f > 0.0 && f < 1.0);
    // Every step: FK by the library within the limits; the first leg on its line.
    let m = model("puma560");
    for q in points {
        let qr: Vec<f64> = floats(q).iter().map(|x| x.to_radians()).collect();
        assert!(
            m.check_joints(&qr, &kinserve::model::FkOptions::default())
                .is_ok()
        );
    }
    let leg_end: Vec<f64> = floats(&points[4]).iter().map(|x| x.to_radians()).collect();
    let p = m.fk_unchecked(&leg_end).position();
    for (i, e) in floats(&end).iter().enumerate() {
        assert!((p[i] - e).abs() < 1e-9, "end of the first leg {p:?}");
    }
    let ws = ws_one(&app, "puma560", json!({"id": "p", "ik_path": body})).await;
    assert_eq!(
        (&ws["points"], &ws["stop"], &ws["fraction"]),
        (&rest["points"], &rest["stop"], &rest["fraction"]),
        "WebSocket"
    );
    let pb_target = |p: &Value| pb::IkTarget {
        position: Some(pb::Vector3 {
            x: p[0].as_f64().unwrap(),
            y: p[1].as_f64().unwrap(),
            z: p[2].as_f64().unwrap(),
        }),
        quaternion: Some(pb::Quaternion {
            w: pose["quaternion"]["w"].as_f64().unwrap(),
            x: pose["quaternion"]["x"].as_f64().unwrap(),
            y: pose["quaternion"]["y"].as_f64().unwrap(),
            z: pose["quaternion"]["z"].as_f64().unwrap(),
        }),
        ..Default::default()
    };
    let req = pb::InverseKinematicsPathRequest {
        robot: "puma560".into(),
        start: Some(pb::JointConfiguration {
            joints: start.to_vec(),
        }),
        waypoints: vec![pb_target(&end), pb_target(&far)],
        angle_unit: pb::AngleUnit::Deg as i32,
        max_step_length: Some(0.01),
        ..Default::default()
    };
    let g = c
        .inverse_kinematics_path(req.clone())
        .await
        .unwrap()
        .into_inner();
    assert_eq!(g.points.len(), points.len());
    for (a, b) in g.points.iter().zip(points) {
        assert_eq!(a.joints, floats(b), "gRPC points");
    }
    let s = g.stop.unwrap();
    assert_eq!(
        (s.step as u64, s.detail.as_str()),
        (
            stop["step"].as_u64().unwrap(),
            stop["detail"].as_str().unwrap()
        )
    );
    assert_eq!(g.fraction, f);
    // On the gRPC stream too.
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    let mut msg = stream_request(5, "puma560", &[], None);
    msg.ik_path = Some(Box::new(pb::InverseKinematicsPathRequest {
        robot: String::new(),
        ..req.clone()
    }));
    tx.send(msg).await.unwrap();
    let s = rx.message().await.unwrap().unwrap();
    assert_eq!(s.id, 5);
    assert_eq!(s.ik_path.expect("path answer").points, g.points, "stream");
    // Refused requests name the same field.
    let bad = json!({"start": [0, 0, 0], "waypoints": [target(&end)]});
    let p = problem(app.post("/v1/robots/puma560/ik/path", &bad).await, 422).await;
    assert_eq!(p["errors"][0]["field"], "start");
    let mut r = req.clone();
    r.start = Some(pb::JointConfiguration {
        joints: vec![0.0; 3],
    });
    let e = c.inverse_kinematics_path(r).await.unwrap_err();
    assert_eq!(
        (e.code(), status_fields(&e)),
        (Code::InvalidArgument, vec!["start".to_string()])
    );
    let e = c
        .inverse_kinematics_path(pb::InverseKinematicsPathRequest {
            max_step_length: Some(1e-7),
            ..req
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted);
    let p = problem(app.post("/v1/robots/puma560/ik/path", &json!({"start": start, "angle_unit": "deg", "waypoints": [target(&far)], "max_step_length": 1e-7})).await, 413).await;
    assert_eq!(p["errors"][0]["field"], "max_step_length", "{p}");
}

#[tokio::test]
async fn a_long_path_streams_and_keeps_every_point() {
    let app = spawn_ik_app().await;
    let start = [5.0, -20.0, 35.0, 10.0, 30.0, -15.0];
    let pose = fk_ok(
        &app,
        "puma560",
        json!({"joints": start, "angle_unit": "deg"}),
    )
    .await["pose"]
        .clone();
    let mut end = pose["position"].clone();
    end[2] = json!(end[2].as_f64().unwrap() + 0.08);
    // 8 cm in 0.02 mm steps: 4,000 steps, about 0.4 MB of JSON.
    let body = json!({"start": start, "angle_unit": "deg", "max_step_length": 2e-5,
        "waypoints": [{"position": end, "quaternion": pose["quaternion"]}]});
    let r = app.post("/v1/robots/puma560/ik/path", &body).await;
    assert_eq!(r.status(), 200);
    // Streamed: no Content-Length, the body written as the connection takes it.
    assert!(
        r.headers().get("content-length").is_none(),
        "{:?}",
        r.headers()
    );
    let rest: Value = r.json().await.unwrap();
    assert_eq!(
        (&rest["fraction"], &rest["stop"]),
        (&json!(1.0), &Value::Null),
        "{}",
        rest["stop"]
    );
    let points = rest["points"].as_array().unwrap();
    assert_eq!(points.len(), 4_001);
    // The same points as the WebSocket's (buffered) answer.
    let ws = ws_one(&app, "puma560", json!({"id": "long", "ik_path": body})).await;
    assert_eq!(ws["points"], rest["points"]);
}
