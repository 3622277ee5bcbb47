//! gRPC velocity and inverse kinematics: `Jacobian`, `JacobianBatch`,
//! `InverseKinematics`, `InverseKinematicsBatch` and the Jacobian / IK
//! messages of the stream — the same answers, error classes and field paths
//! as REST and the WebSocket (compared here, all three on one server), and
//! `IK_NOT_CONVERGED` with the best attempt in the status details.

use futures_util::SinkExt;
use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use prost::Message as _;
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;
use tonic::Code;
use tonic_types::StatusExt;

use crate::helpers::*;

pub(super) fn matrix_pb(pose: &Value) -> pb::Matrix4 {
    pb::Matrix4 {
        values: matrix16(pose),
    }
}

pub(super) fn ik_request(
    robot: &str,
    target: pb::IkTarget,
    unit: pb::AngleUnit,
) -> pb::InverseKinematicsRequest {
    pb::InverseKinematicsRequest {
        robot: robot.into(),
        target: Some(target),
        angle_unit: unit as i32,
        ..Default::default()
    }
}

/// REST JSON numbers of an array.
pub(super) fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The pose of a JSON answer as the 16 matrix values.
pub(super) fn same_pose(json: &Value, p: &pb::Pose, what: &str) {
    assert_eq!(matrix16(json), p.matrix, "{what}: matrix");
}

/// A server whose IK time cap is far out of reach, so that answers compared
/// across protocols cannot differ by where a loaded machine cut a solve short.
pub(super) async fn spawn_ik_app() -> TestApp {
    spawn_app_with(|c| c.ik_time_limit = std::time::Duration::from_secs(30)).await
}

pub(super) async fn rest_ok(app: &TestApp, path: &str, body: &Value) -> Value {
    let r = app.post(path, body).await;
    assert_eq!(r.status(), 200, "{path}");
    r.json().await.unwrap()
}

pub(super) async fn ws_one(app: &TestApp, robot: &str, msg: Value) -> Value {
    let mut sock = open_ws(app, robot).await;
    sock.send(Message::Text(msg.to_string().into()))
        .await
        .unwrap();
    next_text(&mut sock).await.expect("a reply")
}

#[tokio::test]
async fn the_jacobian_is_the_same_on_grpc_rest_and_websocket() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    for (robot, q, frame, name) in [
        (
            "puma560",
            vec![0.3, -0.5, 0.4, 0.2, 0.6, -0.1],
            pb::JacobianFrame::Base,
            "base",
        ),
        (
            "panda",
            vec![0.1, -0.4, 0.2, -2.0, 0.3, 1.8, 0.5],
            pb::JacobianFrame::Tool,
            "tool",
        ),
        (
            "stanford",
            vec![0.2, -0.4, 0.5, 0.5, -0.6, 0.7],
            pb::JacobianFrame::Tool,
            "tool",
        ),
        (
            "planar_2dof",
            vec![0.3, 0.0],
            pb::JacobianFrame::Base,
            "base",
        ),
    ] {
        let g = c
            .jacobian(pb::JacobianRequest {
                robot: robot.into(),
                joints: q.clone(),
                options: None,
                frame: frame as i32,
            })
            .await
            .unwrap()
            .into_inner();
        let rest = rest_ok(
            &app,
            &format!("/v1/robots/{robot}/jacobian"),
            &json!({"joints": q, "frame": name}),
        )
        .await;
        let ws = ws_one(
            &app,
            robot,
            json!({"id": 1, "joints": q, "jacobian": true, "frame": name}),
        )
        .await;
        let r = g.result.unwrap();
        assert_eq!(r.frame, frame as i32);
        assert_eq!(r.columns as usize, q.len());
        let rows: Vec<f64> = rest["jacobian"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(floats)
            .collect();
        assert_eq!(r.values, rows, "{robot}: gRPC and REST");
        assert_eq!(
            ws["jacobian"], rest["jacobian"],
            "{robot}: WebSocket and REST"
        );
        assert_eq!(Some(r.manipulability), rest["manipulability"].as_f64());
        assert_eq!(r.condition_number, rest["condition_number"].as_f64());
        assert_eq!(Some(r.singular), rest["singular"].as_bool());
        same_pose(&rest["pose"], r.pose.as_ref().unwrap(), robot);
    }
}

#[tokio::test]
async fn ik_is_the_same_on_grpc_rest_and_websocket() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    for (robot, q) in [
        ("puma560", json!([20.0, -30.0, 45.0, 10.0, 50.0, -20.0])),
        ("ur5e", json!([30.0, -80.0, 70.0, -40.0, 80.0, 10.0])),
        (
            "kinova_gen3",
            json!([10.0, 20.0, -15.0, 60.0, 20.0, 40.0, 30.0]),
        ),
    ] {
        let pose =
            fk_ok(&app, robot, json!({"joints": q, "angle_unit": "deg"})).await["pose"].clone();
        let body = json!({"target": {"matrix": pose["matrix"]}, "angle_unit": "deg"});
        let rest = rest_ok(&app, &format!("/v1/robots/{robot}/ik"), &body).await;
        let ws = ws_one(&app, robot, json!({"id": 7, "ik": body})).await;
        let target = pb::IkTarget {
            matrix: Some(matrix_pb(&pose)),
            ..Default::default()
        };
        let g = c
            .inverse_kinematics(ik_request(robot, target.clone(), pb::AngleUnit::Deg))
            .await
            .unwrap()
            .into_inner();
        assert_eq!(g.angle_unit, pb::AngleUnit::Deg as i32);
        let r = g.result.unwrap();
        assert!(r.converged);
        // The solver is deterministic: the very same joints everywhere.
        assert_eq!(r.joints, floats(&rest["joints"]), "{robot}: gRPC and REST");
        assert_eq!(ws["joints"], rest["joints"], "{robot}: WebSocket and REST");
        assert_eq!(Some(r.position_error), rest["position_error"].as_f64());
        assert_eq!(r.orientation_error, rest["orientation_error"].as_f64());
        assert_eq!(Some(r.iterations as u64), rest["iterations"].as_u64());
        same_pose(&rest["pose"], r.pose.as_ref().unwrap(), robot);
        // On the gRPC stream too.
        let (tx, mut rx) = open_stream(&mut c, 4).await;
        let mut msg = stream_request(9, robot, &[], None);
        msg.ik = Some(Box::new(ik_request("", target, pb::AngleUnit::Deg)));
        tx.send(msg).await.unwrap();
        let s = rx.message().await.unwrap().unwrap();
        assert_eq!(s.id, 9);
        assert_eq!(s.ik.unwrap().joints, r.joints, "{robot}: stream");
        assert!(matches!(s.result, Some(StreamResult::Pose(_))));
    }
}

#[tokio::test]
async fn an_unreached_target_is_failed_precondition_with_the_best_attempt() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let target = pb::IkTarget {
        position: Some(pb::Vector3 {
            x: 5.0,
            y: 0.0,
            z: 0.5,
        }),
        quaternion: Some(pb::Quaternion {
            w: 1.0,
            x: 0.0,
            y: 0.0,
            z: 0.0,
        }),
        ..Default::default()
    };
    let mut req = ik_request("ur5e", target.clone(), pb::AngleUnit::Deg);
    req.restarts = Some(3);
    let status = c.inverse_kinematics(req.clone()).await.unwrap_err();
    assert_eq!(status.code(), Code::FailedPrecondition);
    let info = status.get_details_error_info().expect("ErrorInfo");
    assert_eq!(
        (info.reason.as_str(), info.domain.as_str()),
        ("IK_NOT_CONVERGED", "kinserve")
    );
    let details = tonic_types::Status::decode(status.details()).unwrap();
    let any = details
        .details
        .iter()
        .find(|a| {
            a.type_url
                .ends_with("kinematics.v1.InverseKinematicsResult")
        })
        .expect("best attempt in the details");
    let best = pb::InverseKinematicsResult::decode(any.value.as_slice()).unwrap();
    assert!(!best.converged && best.position_error > 4.0, "{best:?}");
    assert_eq!(
        info.metadata["position_error"],
        best.position_error.to_string()
    );
    // The same best attempt as REST's problem (deterministic solver).
    let body = json!({"target": {"position": [5.0, 0.0, 0.5], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}},
        "angle_unit": "deg", "restarts": 3});
    let p = problem(app.post("/v1/robots/ur5e/ik", &body).await, 422).await;
    assert_eq!(best.joints, floats(&p["best_attempt"]["joints"]));
    // Its joints (degrees) pass the limit check.
    fk(&mut c, fk_request("ur5e", &best.joints, deg()))
        .await
        .unwrap();
    // On the stream: an error response carrying the same details, and the stream goes on.
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    let mut msg = stream_request(1, "ur5e", &[], None);
    msg.ik = Some(Box::new(req));
    tx.send(msg).await.unwrap();
    tx.send(stream_request(2, "ur5e", &[0.0; 6], None))
        .await
        .unwrap();
    let first = rx.message().await.unwrap().unwrap();
    let Some(StreamResult::Error(e)) = first.result else {
        panic!("{first:?}")
    };
    assert_eq!(e.code, Code::FailedPrecondition as i32);
    assert!(
        e.details
            .iter()
            .any(|a| a.type_url.ends_with("InverseKinematicsResult"))
    );
    let second = rx.message().await.unwrap().unwrap();
    assert!(matches!(second.result, Some(StreamResult::Pose(_))));
}

#[tokio::test]
async fn bad_requests_name_the_same_fields_as_rest() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let bad_row = pb::Matrix4 {
        values: vec![
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 2.0,
        ],
    };
    let cases: Vec<(pb::InverseKinematicsRequest, &str)> = vec![
        (
            ik_request(
                "puma560",
                pb::IkTarget {
                    matrix: Some(bad_row),
                    ..Default::default()
                },
                pb::AngleUnit::Rad,
            ),
            "target.matrix[3]",
        ),
        (
            ik_request(
                "puma560",
                pb::IkTarget {
                    matrix: Some(pb::Matrix4 {
                        values: vec![1.0; 3],
                    }),
                    ..Default::default()
                },
                pb::AngleUnit::Rad,
            ),
            "target.matrix",
        ),
        (
            ik_request(
                "puma560",
                pb::IkTarget {
                    position: Some(pb::Vector3 {
                        x: 0.3,
                        y: 0.0,
                        z: 0.2,
                    }),
                    ..Default::default()
                },
                pb::AngleUnit::Rad,
            ),
            "target.quaternion",
        ),
        (
            pb::InverseKinematicsRequest {
                robot: "puma560".into(),
                ..Default::default()
            },
            "target",
        ),
        (
            pb::InverseKinematicsRequest {
                robot: "puma560".into(),
                target: Some(pb::IkTarget {
                    position: Some(pb::Vector3::default()),
                    ..Default::default()
                }),
                position_only: true,
                tolerance: Some(0.0),
                ..Default::default()
            },
            "tolerance",
        ),
        (
            pb::InverseKinematicsRequest {
                robot: "puma560".into(),
                target: Some(pb::IkTarget {
                    position: Some(pb::Vector3::default()),
                    ..Default::default()
                }),
                position_only: true,
                seed: Some(pb::JointConfiguration {
                    joints: vec![0.0, 0.0, 0.0, 0.0, 9.0, 0.0],
                }),
                ..Default::default()
            },
            "seed[4]",
        ),
    ];
    for (req, field) in cases {
        let s = c.inverse_kinematics(req.clone()).await.unwrap_err();
        assert_eq!(s.code(), Code::InvalidArgument, "{field}");
        assert_eq!(status_fields(&s), [field], "{req:?}");
    }
    let s = c
        .jacobian(pb::JacobianRequest {
            robot: "puma560".into(),
            joints: vec![0.0; 6],
            options: None,
            frame: 9,
        })
        .await
        .unwrap_err();
    assert_eq!(
        (s.code(), status_fields(&s)),
        (Code::InvalidArgument, vec!["frame".to_string()])
    );
    let s = c
        .jacobian_batch(pb::JacobianBatchRequest {
            robot: "puma560".into(),
            configurations: vec![
                pb::JointConfiguration {
                    joints: vec![0.0; 6],
                },
                pb::JointConfiguration {
                    joints: vec![0.0, 0.0, 0.0, 0.0, 9.0, 0.0],
                },
            ],
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(status_fields(&s), ["configurations[1][4]"]);
    let s = c
        .inverse_kinematics(ik_request(
            "nope",
            pb::IkTarget::default(),
            pb::AngleUnit::Rad,
        ))
        .await
        .unwrap_err();
    assert_eq!(s.code(), Code::NotFound);
}

#[tokio::test]
async fn batches_answer_in_request_order_like_rest() {
    let app = spawn_ik_app().await;
    let mut c = app.grpc_client().await;
    let cfgs = configs(4, 6);
    let g = c
        .jacobian_batch(pb::JacobianBatchRequest {
            robot: "puma560".into(),
            configurations: cfgs
                .iter()
                .map(|q| pb::JointConfiguration { joints: q.clone() })
                .collect(),
            options: None,
            frame: pb::JacobianFrame::Tool as i32,
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    let rest = rest_ok(
        &app,
        "/v1/robots/puma560/jacobian/batch",
        &json!({"configurations": cfgs, "frame": "tool"}),
    )
    .await;
    assert_eq!(g.results.len(), 4);
    for (r, j) in g.results.iter().zip(rest["results"].as_array().unwrap()) {
        let rows: Vec<f64> = j["jacobian"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(floats)
            .collect();
        assert_eq!(r.values, rows);
    }
    // IK batch: the targets of those configurations, in order, and one out of reach.
    let mut targets = Vec::new();
    let mut json_targets = Vec::new();
    for q in &cfgs {
        let pose = fk_ok(&app, "puma560", json!({"joints": q})).await["pose"].clone();
        targets.push(pb::IkTarget {
            matrix: Some(matrix_pb(&pose)),
            ..Default::default()
        });
        json_targets.push(json!({"matrix": pose["matrix"]}));
    }
    targets.push(pb::IkTarget {
        position: Some(pb::Vector3 {
            x: 4.0,
            y: 0.0,
            z: 0.0,
        }),
        quaternion: Some(pb::Quaternion {
            w: 1.0,
            ..Default::default()
        }),
        ..Default::default()
    });
    json_targets
        .push(json!({"position": [4.0, 0.0, 0.0], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}}));
    let g = c
        .inverse_kinematics_batch(pb::InverseKinematicsBatchRequest {
            robot: "puma560".into(),
            targets,
            restarts: Some(2),
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    let rest = rest_ok(
        &app,
        "/v1/robots/puma560/ik/batch",
        &json!({"targets": json_targets, "restarts": 2}),
    )
    .await;
    let converged: Vec<bool> = g.results.iter().map(|r| r.converged).collect();
    assert_eq!(converged, [true, true, true, true, false]);
    for (r, j) in g.results.iter().zip(rest["results"].as_array().unwrap()) {
        assert_eq!(r.joints, floats(&j["joints"]));
    }
}
