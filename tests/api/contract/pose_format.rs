//! Compact pose formats (`pose_format`: `full`, `matrix`, `position`) on every
//! front door: the compact numbers are the full answer's, bit for bit (tool
//! pose and frames, several robots including a modified-DH one), batches keep
//! request order, and an unknown format is a parse error naming the field
//! (`pose_format` in JSON, `options.pose_format` over gRPC) everywhere.
//! Helpers are in `crate::helpers::pose_format`.

use futures_util::SinkExt;
use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use kinserve_testkit::RobotExt;
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;
use tonic::Code;

use crate::helpers::*;

/// Robots and joints (rad; within the limits): standard and modified DH, a
/// prismatic joint, millimetres.
const CASES: [(&str, &[f64]); 5] = [
    ("planar_2dof", &[0.5, 0.1]),
    ("puma560", &[0.3, -0.4, 0.6, 0.2, -0.5, 0.7]),
    ("panda", &[0.1, -0.3, 0.2, -1.5, 0.1, 1.2, 0.4]),
    ("stanford", &[0.3, -0.4, 0.5, 0.2, -0.5, 0.7]),
    ("alpha_ii", &[0.1, 0.5, -0.5, 0.2, 0.3]),
];

#[tokio::test]
async fn compact_answers_are_the_full_answers_numbers_bit_for_bit_on_every_door() {
    let app = spawn_app().await;
    for (robot, q) in CASES {
        let lib = library_robot(robot).fk_unchecked(q);
        let lib16: Vec<f64> = lib.matrix().iter().flatten().copied().collect();
        for door in Door::ALL {
            for frames in [false, true] {
                let what = format!("{robot} {door:?} frames={frames}");
                let full = fk_numbers(&app, door, robot, q, frames, "full").await;
                for (a, b) in full.pose.iter().zip(&lib16) {
                    assert_close(*a, *b, 1e-12, &format!("{what}: full vs library"));
                }
                for format in ["matrix", "position"] {
                    let got = fk_numbers(&app, door, robot, q, frames, format).await;
                    let what = format!("{what} {format}");
                    assert_bits_eq(&got.pose, &compact_of(&full.pose, format), &what);
                    let (Some(want), Some(got)) = (&full.frames, &got.frames) else {
                        assert!(!frames && got.frames.is_none(), "{what}: frames");
                        continue;
                    };
                    assert_eq!(got.len(), want.len(), "{what}: frame count");
                    for (i, (g, w)) in got.iter().zip(want).enumerate() {
                        assert_bits_eq(g, &compact_of(w, format), &format!("{what}: frame {i}"));
                    }
                }
            }
        }
    }
}

/// Five distinct configurations of a robot (so that a reordering shows).
fn batch_of(q: &[f64]) -> Vec<Vec<f64>> {
    (0..5)
        .map(|k| q.iter().map(|x| x * (1.0 - 0.15 * k as f64)).collect())
        .collect()
}

#[tokio::test]
async fn batches_keep_request_order_in_every_format_over_rest_and_grpc() {
    let app = spawn_app().await;
    let mut client = app.grpc_client().await;
    for (robot, q) in [CASES[1], CASES[2]] {
        let configs = batch_of(q);
        let mut full = Vec::new();
        for format in FORMATS {
            let what = format!("{robot} {format}");
            // REST: the format's own field (`poses`, `matrices` or
            // `positions`), an array of poses in the format.
            let body = json!({"configurations": configs, "pose_format": format});
            let r = app
                .post(&format!("/v1/robots/{robot}/fk/batch"), &body)
                .await;
            assert_eq!(r.status(), 200, "{what}");
            let v: Value = r.json().await.unwrap();
            assert_only_fields_of(&v, format);
            let rest = json_list(&v[format_fields(format).2], format);
            // gRPC: Pose messages (full) or one packed field.
            let req = pb::ForwardKinematicsBatchRequest {
                robot: robot.into(),
                configurations: configs
                    .iter()
                    .map(|c| pb::JointConfiguration { joints: c.clone() })
                    .collect(),
                options: format_options(format, false),
                ..Default::default()
            };
            let r = client
                .forward_kinematics_batch(req)
                .await
                .unwrap()
                .into_inner();
            let grpc: Vec<Vec<f64>> = match &r.packed_poses {
                Some(p) => {
                    assert!(r.poses.is_empty(), "{what}: no Pose messages");
                    assert_eq!(p.values.len(), configs.len() * stride(format));
                    unpack(p, format)
                }
                None => {
                    assert_eq!(format, "full", "{what}: packed poses");
                    r.poses.iter().map(|p| p.matrix.clone()).collect()
                }
            };
            assert_eq!(rest.len(), configs.len(), "{what}: REST pose count");
            assert_eq!(grpc.len(), configs.len(), "{what}: gRPC pose count");
            if format == "full" {
                full = rest.clone();
            }
            for (i, c) in configs.iter().enumerate() {
                let want = compact_of(&full[i], format);
                assert_bits_eq(&rest[i], &want, &format!("{what}: REST pose {i}"));
                assert_bits_eq(&grpc[i], &want, &format!("{what}: gRPC pose {i}"));
                let lib = library_robot(robot).fk_unchecked(c);
                let lib16: Vec<f64> = lib.matrix().iter().flatten().copied().collect();
                for (a, b) in rest[i].iter().zip(compact_of(&lib16, format)) {
                    assert_close(*a, b, 1e-12, &format!("{what}: pose {i} vs library"));
                }
            }
        }
    }
}

#[tokio::test]
async fn an_unknown_pose_format_is_a_parse_error_naming_the_field_on_every_door() {
    let app = spawn_app().await;
    for bad in [json!("quaternion"), json!("Matrix"), json!(2), json!(null)] {
        let single = json!({"joints": [0, 0], "pose_format": bad});
        let p = problem(app.post("/v1/robots/planar_2dof/fk", &single).await, 400).await;
        assert_eq!(fields(&p), ["pose_format"], "{p}");
        let batch = json!({"configurations": [[0, 0]], "pose_format": bad});
        let p = problem(
            app.post("/v1/robots/planar_2dof/fk/batch", &batch).await,
            400,
        )
        .await;
        assert_eq!(fields(&p), ["pose_format"], "{p}");
        let mut ws = open_ws(&app, "planar_2dof").await;
        let msg = json!({"id": 5, "joints": [0, 0], "pose_format": bad});
        ws.send(Message::Text(msg.to_string().into()))
            .await
            .unwrap();
        let reply = next_text(&mut ws).await.unwrap();
        assert_eq!(reply["id"], 5, "{reply}");
        assert_eq!(reply["error"]["status"], 400, "{reply}");
        assert_eq!(fields(&reply["error"]), ["pose_format"], "{reply}");
    }
    let bad = Some(pb::FkOptions {
        pose_format: 99,
        ..Default::default()
    });
    let mut c = app.grpc_client().await;
    let e = fk(&mut c, fk_request("planar_2dof", &[0.0, 0.0], bad))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&e), ["options.pose_format"]);
    let e = c
        .forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "planar_2dof".into(),
            configurations: vec![pb::JointConfiguration {
                joints: vec![0.0, 0.0],
            }],
            options: bad,
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&e), ["options.pose_format"]);
    let m = stream_once(&app, "planar_2dof", &[0.0, 0.0], bad).await;
    let Some(StreamResult::Error(s)) = &m.result else {
        panic!("an error answer: {m:?}");
    };
    assert_eq!(s.code, Code::InvalidArgument as i32);
    assert_eq!(rpc_status_fields(s), ["options.pose_format"]);
}

#[tokio::test]
async fn the_default_and_full_are_todays_answer_and_jacobian_replies_follow_the_format() {
    let app = spawn_app().await;
    let q = [0.5, 0.1];
    let plain = fk_ok(&app, "planar_2dof", json!({"joints": q})).await;
    let full = fk_ok(
        &app,
        "planar_2dof",
        json!({"joints": q, "pose_format": "full"}),
    )
    .await;
    assert_eq!(plain, full);
    let mut c = app.grpc_client().await;
    let unspecified = fk(&mut c, fk_request("planar_2dof", &q, None))
        .await
        .unwrap();
    let full = fk(
        &mut c,
        fk_request("planar_2dof", &q, format_options("full", false)),
    )
    .await
    .unwrap();
    assert_eq!(unspecified, full);
    // The WebSocket's Jacobian replies carry the pose in the asked format's
    // field; IK replies always carry the full `pose`.
    let mut ws = open_ws(&app, "planar_2dof").await;
    let msg = json!({"id": 1, "joints": q, "jacobian": true, "pose_format": "position"});
    ws.send(Message::Text(msg.to_string().into()))
        .await
        .unwrap();
    let reply = next_text(&mut ws).await.unwrap();
    assert!(reply["jacobian"].is_array(), "{reply}");
    assert_eq!(
        reply["position"],
        json!(position(&plain["pose"])),
        "{reply}"
    );
    assert_only_fields_of(&reply, "position");
    let target = json!({"position": position(&plain["pose"])});
    let msg =
        json!({"id": 2, "ik": {"target": target, "position_only": true}, "pose_format": "matrix"});
    ws.send(Message::Text(msg.to_string().into()))
        .await
        .unwrap();
    let reply = next_text(&mut ws).await.unwrap();
    assert_eq!(reply["converged"], true, "{reply}");
    assert!(reply["pose"]["quaternion"].is_object(), "{reply}");
    assert_only_fields_of(&reply, "full");
}

/// Whether two JSON documents are equal, numbers to 1e-12 (the batch may take
/// a SIMD path whose last bit differs from the single-pose one).
fn json_close(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            (x.as_f64().unwrap() - y.as_f64().unwrap()).abs() <= 1e-12
        }
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(a, b)| json_close(a, b))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| json_close(v, w)))
        }
        _ => a == b,
    }
}

/// Every `<!-- pose format example: POST PATH BODY -->` in the README and
/// the migration note is followed by a ```json block with the server's
/// answer (numbers to 1e-12).
#[tokio::test]
async fn the_readme_pose_format_examples_are_what_the_server_answers() {
    let app = spawn_app().await;
    let mut seen = 0;
    let marker = "<!-- pose format example: POST ";
    let readme = readme_examples(marker);
    let migration = migration_examples(marker);
    assert!(
        migration.len() >= 3,
        "the migration note shows single, frames, batch"
    );
    for (request, documented) in readme.into_iter().chain(migration) {
        let (path, body) = request.split_once(' ').unwrap();
        let body: Value = serde_json::from_str(body).expect("body is JSON");
        let r = app.post(path, &body).await;
        assert_eq!(r.status(), 200, "{path}");
        let answered: Value = r.json().await.unwrap();
        assert!(
            json_close(&answered, &documented),
            "README example for {path}: {answered}"
        );
        seen += 1;
    }
    assert!(seen >= 5, "the README shows pose format examples");
}

/// Every `oneOf`/`anyOf` under `v`, with where it is.
fn unions<'a>(v: &'a Value, at: &str, out: &mut Vec<(String, &'a Value)>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                if k == "oneOf" || k == "anyOf" {
                    out.push((at.to_string(), x));
                }
                unions(x, &format!("{at}/{k}"), out);
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                unions(x, &format!("{at}/{i}"), out);
            }
        }
        _ => {}
    }
}

#[tokio::test]
async fn the_openapi_document_gives_each_pose_field_one_type() {
    let app = spawn_app().await;
    let doc: Value = app.get("/openapi.json").await.json().await.unwrap();
    let schemas = &doc["components"]["schemas"];
    assert_eq!(
        schemas["PoseFormat"]["enum"],
        json!(["full", "matrix", "position"])
    );
    for request in ["FkRequest", "FkBatchRequest", "WsRequest"] {
        let p = &schemas[request]["properties"]["pose_format"];
        assert!(!p.is_null(), "{request}: pose_format documented");
    }
    assert!(schemas.get("PoseValue").is_none(), "no union of poses");
    assert_eq!(schemas["PoseMatrix"]["type"], "array");
    assert_eq!(schemas["PoseMatrix"]["minItems"], 12);
    assert_eq!(schemas["PoseMatrix"]["maxItems"], 12);
    assert_eq!(schemas["PosePosition"]["minItems"], 3);
    assert_eq!(schemas["PosePosition"]["maxItems"], 3);
    let r = |name: &str| json!(format!("#/components/schemas/{name}"));
    assert_eq!(schemas["PoseMatrices"]["items"]["$ref"], r("PoseMatrix"));
    assert_eq!(schemas["PosePositions"]["items"]["$ref"], r("PosePosition"));
    // Each answer field: its own type, optional, and saying when it is there.
    let single = [
        ("pose", "Pose"),
        ("matrix", "PoseMatrix"),
        ("position", "PosePosition"),
        ("frame_matrices", "PoseMatrices"),
        ("frame_positions", "PosePositions"),
    ];
    let batch = [("matrices", "PoseMatrices"), ("positions", "PosePositions")];
    let ws_props = schemas["WsReply"]["allOf"]
        .as_array()
        .and_then(|parts| parts.iter().find(|p| p["properties"].is_object()))
        .expect("WsReply has its own properties");
    let answers = [
        ("FkOutput", &schemas["FkOutput"], &single[..], "frames"),
        ("WsReply", ws_props, &single[..], "frames"),
        (
            "FkBatchResponse",
            &schemas["FkBatchResponse"],
            &batch[..],
            "poses",
        ),
    ];
    for (name, schema, typed, full_list) in answers {
        let props = &schema["properties"];
        let required = schema["required"].as_array().cloned().unwrap_or_default();
        for (field, ty) in typed {
            assert_eq!(
                props[field]["$ref"],
                r(ty),
                "{name}.{field}: {}",
                props[field]
            );
        }
        assert_eq!(props[full_list]["type"], "array", "{name}.{full_list}");
        assert_eq!(
            props[full_list]["items"]["$ref"],
            r("Pose"),
            "{name}.{full_list}"
        );
        for (field, _) in typed.iter().chain([&(full_list, "")]) {
            assert!(
                !required.contains(&json!(field)),
                "{name}.{field} is optional"
            );
            let text = props[field]["description"].as_str().unwrap_or_default();
            assert!(text.contains("pose_format"), "{name}.{field}: {text}");
        }
    }
    for (name, must) in [
        ("FkOutput", &["robot", "length_unit"][..]),
        ("FkBatchResponse", &["robot", "length_unit"][..]),
    ] {
        let required = &schemas[name]["required"];
        assert_eq!(required, &json!(must), "{name}: required fields");
    }
    let mut found = Vec::new();
    unions(&doc, "#", &mut found);
    for (at, union) in found {
        let text = union.to_string();
        assert!(!text.contains("/Pose"), "a union of poses at {at}: {text}");
    }
}
