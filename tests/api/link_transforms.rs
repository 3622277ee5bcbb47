//! `link_transforms` on every front door: each DH row's `ⁱ⁻¹Aᵢ` and its
//! inverse. Checked against an independent evaluation of the textbook DH
//! matrices from the robot's own table (GET /v1/robots/{name}), against the
//! server's FK frames (`frames[i-1] · Aᵢ = frames[i]`), `A · A⁻¹ = I`, and the
//! same numbers bit for bit over REST, WebSocket, gRPC unary and stream and the CLI.
//! Tolerance: 1e-12 × (1 + the largest translation) on every entry.

use futures_util::SinkExt;
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;

use kinserve::api::grpc::pb;

use crate::helpers::*;

type M4 = [[f64; 4]; 4];

/// Robots covering both conventions, prismatic joints, fixed rows, degrees and millimetres.
const ROBOTS: &[(&str, &[f64])] = &[
    ("puma560", &[0.3, -0.6, 0.9, 0.2, -0.4, 1.1]),
    ("panda", &[0.1, -0.3, 0.2, -1.9, 0.4, 1.6, -0.5]),
    ("stanford", &[0.2, -0.5, 0.35, 0.3, -0.2, 0.7]),
    ("articulated_rrr_mdh", &[0.4, -0.2, 0.6]),
    ("scara_4dof", &[0.3, -0.4, 0.05, 0.8]),
    ("alpha_ii", &[0.2, 0.5, -0.4, 0.3, 0.1]),
];

fn m4(v: &Value) -> M4 {
    let mut out = [[0.0; 4]; 4];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = v[i][j].as_f64().expect("a number");
        }
    }
    out
}

fn mul(a: &M4, b: &M4) -> M4 {
    let mut out = [[0.0; 4]; 4];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

fn assert_close(got: &M4, want: &M4, what: &str) {
    let scale = 1.0 + (0..3).map(|i| want[i][3].abs()).fold(0.0, f64::max);
    for i in 0..4 {
        for j in 0..4 {
            assert!(
                (got[i][j] - want[i][j]).abs() <= 1e-12 * scale,
                "{what}[{i}][{j}]: {} vs {}\n{got:?}\n{want:?}",
                got[i][j],
                want[i][j]
            );
        }
    }
}

/// The textbook link matrix of one row of a robot file (its own units).
fn textbook(spec: &Value, link: &Value, q: f64) -> M4 {
    let deg = spec["angle_unit"].as_str() == Some("deg");
    let to_rad = |x: f64| if deg { x.to_radians() } else { x };
    let get = |k: &str| link[k].as_f64().expect("DH parameter");
    let (a, alpha, mut d, mut theta) = (
        get("a"),
        to_rad(get("alpha")),
        get("d"),
        to_rad(get("theta")),
    );
    match link["joint"].as_str() {
        Some("revolute") => theta += q,
        Some("prismatic") => d += q,
        _ => {}
    }
    let (st, ct, sa, ca) = (theta.sin(), theta.cos(), alpha.sin(), alpha.cos());
    if spec["convention"].as_str() == Some("modified") {
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -sa * d],
            [st * sa, ct * sa, ca, ca * d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    } else {
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }
}

/// REST answer for `robot` at `q` (rad), checked against the textbook, the FK frames and its inverses.
async fn checked_rest(app: &TestApp, robot: &str, q: &[f64]) -> Value {
    let r = app
        .post(
            &format!("/v1/robots/{robot}/link-transforms"),
            &json!({"joints": q}),
        )
        .await;
    assert_eq!(r.status(), 200, "{robot}");
    let out: Value = r.json().await.unwrap();
    let spec: Value = app
        .get(&format!("/v1/robots/{robot}"))
        .await
        .json()
        .await
        .unwrap();
    let spec = if spec.get("links").is_some() {
        spec
    } else {
        spec["robot"].clone()
    };
    let fk: Value = app
        .post(
            &format!("/v1/robots/{robot}/fk"),
            &json!({"joints": q, "frames": true}),
        )
        .await
        .json()
        .await
        .unwrap();
    let links = out["link_transforms"].as_array().expect("link_transforms");
    let rows = spec["links"].as_array().expect("links");
    assert_eq!(links.len(), rows.len(), "{robot}: one per DH row");
    assert_eq!(out["length_unit"], fk["length_unit"]);
    let mut joint = q.iter();
    let identity = m4(&json!([
        [1, 0, 0, 0],
        [0, 1, 0, 0],
        [0, 0, 1, 0],
        [0, 0, 0, 1]
    ]));
    for (i, (l, row)) in links.iter().zip(rows).enumerate() {
        let value = match row["joint"].as_str() {
            Some("fixed") => 0.0,
            _ => *joint.next().expect("a joint value"),
        };
        let (a, inv) = (m4(&l["matrix"]), m4(&l["inverse"]));
        assert_close(
            &a,
            &textbook(&spec, row, value),
            &format!("{robot} A{}", i + 1),
        );
        assert_close(&mul(&a, &inv), &identity, &format!("{robot} A·A⁻¹ row {i}"));
        assert_close(&mul(&inv, &a), &identity, &format!("{robot} A⁻¹·A row {i}"));
        let before = m4(&fk["frames"][i]["matrix"]);
        let after = m4(&fk["frames"][i + 1]["matrix"]);
        assert_close(
            &mul(&before, &a),
            &after,
            &format!("{robot} frame {}", i + 1),
        );
    }
    out
}

#[tokio::test]
async fn rest_link_transforms_are_the_textbook_matrices_and_compose_to_the_frames() {
    let app = spawn_app().await;
    for (robot, q) in ROBOTS {
        checked_rest(&app, robot, q).await;
    }
}

#[tokio::test]
async fn every_front_door_gives_the_same_numbers() {
    let app = spawn_app().await;
    let (robot, q) = ROBOTS[1];
    let rest = checked_rest(&app, robot, q).await;
    let want: Vec<f64> = rest["link_transforms"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|l| [l["matrix"].clone(), l["inverse"].clone()])
        .flat_map(|m| m4(&m).into_iter().flatten().collect::<Vec<_>>())
        .collect();
    let flat_pb = |links: &[pb::LinkTransform]| -> Vec<f64> {
        links
            .iter()
            .flat_map(|l| {
                let m = l.matrix.as_ref().unwrap().values.clone();
                m.into_iter()
                    .chain(l.inverse.as_ref().unwrap().values.clone())
            })
            .collect()
    };
    // gRPC unary.
    let mut c = app.grpc_client().await;
    let unary = c
        .link_transforms(pb::LinkTransformsRequest {
            robot: robot.into(),
            joints: q.to_vec(),
            options: None,
        })
        .await
        .expect("LinkTransforms")
        .into_inner();
    assert_eq!(flat_pb(&unary.link_transforms), want, "gRPC unary = REST");
    // gRPC stream (FK with include_link_transforms).
    let mut msg = stream_request(7, robot, q, None);
    msg.include_link_transforms = true;
    let mut rx = c
        .stream_forward_kinematics(tokio_stream::iter(vec![msg]))
        .await
        .unwrap()
        .into_inner();
    let reply = rx.message().await.unwrap().expect("a reply");
    assert_eq!(flat_pb(&reply.link_transforms), want, "gRPC stream = REST");
    // WebSocket.
    let mut ws = open_ws(&app, robot).await;
    let text = json!({"id": 3, "joints": q, "link_transforms": true}).to_string();
    ws.send(Message::Text(text.into())).await.unwrap();
    let reply = next_text(&mut ws).await.expect("a reply");
    assert_eq!(reply["id"], 3);
    assert!(
        reply["pose"]["matrix"].is_array(),
        "the FK pose comes too: {reply}"
    );
    assert_eq!(
        reply["link_transforms"], rest["link_transforms"],
        "WebSocket = REST"
    );
    // CLI.
    let joints: Vec<String> = q.iter().map(|x| format!("{x:?}")).collect();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_kinserve"))
        .args([
            "link-transforms",
            "--robot",
            robot,
            "--joints",
            &joints.join(","),
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cli: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(cli, rest, "CLI = REST");
}

#[tokio::test]
async fn a_wrong_joint_count_names_joints_on_every_front_door() {
    let app = spawn_app().await;
    let r = app
        .post(
            "/v1/robots/puma560/link-transforms",
            &json!({"joints": [0.1, 0.2]}),
        )
        .await;
    assert_eq!(r.status(), 422);
    let p: Value = r.json().await.unwrap();
    assert_eq!(p["errors"][0]["field"], "joints", "{p}");
    let mut c = app.grpc_client().await;
    let e = c
        .link_transforms(pb::LinkTransformsRequest {
            robot: "puma560".into(),
            joints: vec![0.1, 0.2],
            options: None,
        })
        .await
        .expect_err("two values for six joints");
    assert_eq!(e.code(), tonic::Code::InvalidArgument);
    assert!(e.message().contains("joints"), "{}", e.message());
    let r = app
        .post(
            "/v1/robots/puma560/link-transforms",
            &json!({"joints": [0, 0, 0, 0, 0, 0], "frames": true}),
        )
        .await;
    assert_eq!(r.status(), 400, "unknown field refused");
}

/// The names of the table's operations (`kinserve_model::config_ops!`).
macro_rules! op_names {
    ($( $(#[$doc:meta])* $name:ident: $op:ident => [$($answer:tt)+]; )*) => {
        &[$( stringify!($name) ),*]
    };
}

/// `snake_case` → `CamelCase` (the gRPC method).
fn camel(name: &str) -> String {
    name.split('_')
        .map(|w| w[..1].to_uppercase() + &w[1..])
        .collect()
}

/// Every line of the operations table is an operation on every front door:
/// its REST route and OpenAPI operation, its WebSocket flag and reply field
/// (answered as REST answers), its gRPC method and stream flag in the proto
/// the server serves, and its CLI subcommand. Fails for an operation that a
/// front door's expansion of the table misses.
#[tokio::test]
async fn every_operation_of_the_table_is_on_every_front_door() {
    let names: &[&str] = kinserve::model::config_ops!(op_names);
    assert!(names.contains(&"link_transforms"), "{names:?}");
    let app = spawn_app().await;
    let doc: Value = app.get("/openapi.json").await.json().await.unwrap();
    let proto = include_str!("../../proto/kinematics/v1/kinematics.proto");
    let (robot, q) = ROBOTS[0];
    let mut ws = open_ws(&app, robot).await;
    for (i, name) in names.iter().enumerate() {
        let path = format!("/v1/robots/{{name}}/{}", name.replace('_', "-"));
        let op = &doc["paths"][&path]["post"];
        assert_eq!(op["operationId"], *name, "{path} in the OpenAPI document");
        let ws_flag = &doc["components"]["schemas"]["WsRequest"]["properties"][name];
        assert_eq!(ws_flag["type"], "boolean", "WsRequest.{name}");
        let rpc = format!("rpc {}(", camel(name));
        assert!(proto.contains(&rpc), "{rpc} in the proto");
        assert!(
            proto.contains(&format!("bool include_{name} = ")),
            "StreamForwardKinematicsRequest.include_{name}"
        );
        // REST and WebSocket answer the same.
        let route = format!("/v1/robots/{robot}/{}", name.replace('_', "-"));
        let rest: Value = app
            .post(&route, &json!({"joints": q}))
            .await
            .json()
            .await
            .unwrap();
        let text = json!({"id": i, "joints": q, *name: true}).to_string();
        ws.send(Message::Text(text.into())).await.unwrap();
        let reply = next_text(&mut ws).await.expect("a reply");
        assert!(
            !reply[name].is_null(),
            "WebSocket reply has {name}: {reply}"
        );
        assert_eq!(reply[name], rest[name], "WebSocket {name} = REST");
        // The CLI has the subcommand.
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_kinserve"))
            .args([&name.replace('_', "-"), "--help"])
            .output()
            .unwrap();
        assert!(out.status.success(), "kinserve {name} --help");
    }
}
