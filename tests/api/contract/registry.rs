//! Cross-protocol registry and limits: bad models, registry errors, auth and
//! size limits give the same class and fields over REST and gRPC.

use kinserve::api::grpc::pb;
use serde_json::{Value, json};

use crate::helpers::*;

// ---------------------------------------------------------------- registry and limits

/// A JSON robot model (REST schema) as the protobuf message, field by field.
/// Enum strings the proto does not know become an out-of-range enum value.
fn model_to_pb(m: &Value) -> pb::Robot {
    let s = |v: &Value| v.as_str().map(str::to_string);
    let f = |v: &Value| v.as_f64().unwrap_or(0.0);
    let transform = |t: &Value| -> Option<pb::FixedTransform> {
        if t.is_null() {
            return None;
        }
        let v3 = |v: &Value| pb::Vector3 {
            x: f(&v[0]),
            y: f(&v[1]),
            z: f(&v[2]),
        };
        let rotation = if !t["rpy"].is_null() {
            Some(pb::fixed_transform::Rotation::Rpy(pb::Rpy {
                roll: f(&t["rpy"][0]),
                pitch: f(&t["rpy"][1]),
                yaw: f(&t["rpy"][2]),
            }))
        } else if !t["quaternion"].is_null() {
            let q = &t["quaternion"];
            Some(pb::fixed_transform::Rotation::Quaternion(pb::Quaternion {
                w: f(&q["w"]),
                x: f(&q["x"]),
                y: f(&q["y"]),
                z: f(&q["z"]),
            }))
        } else if !t["matrix"].is_null() {
            Some(pb::fixed_transform::Rotation::Matrix(pb::Matrix4 {
                values: t["matrix"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .flat_map(|r| r.as_array().unwrap().iter().map(f).collect::<Vec<_>>())
                    .collect(),
            }))
        } else {
            None
        };
        Some(pb::FixedTransform {
            translation: (!t["translation"].is_null()).then(|| v3(&t["translation"])),
            rotation,
        })
    };
    pb::Robot {
        name: s(&m["name"]).unwrap_or_default(),
        description: s(&m["description"]),
        source: s(&m["source"]),
        convention: match m["convention"].as_str() {
            Some("standard") => pb::Convention::Standard as i32,
            Some("modified") => pb::Convention::Modified as i32,
            _ => 99,
        },
        angle_unit: match m["angle_unit"].as_str() {
            Some("rad") | None => pb::AngleUnit::Rad as i32,
            Some("deg") => pb::AngleUnit::Deg as i32,
            _ => 99,
        },
        length_unit: match m["length_unit"].as_str() {
            Some("m") | None => pb::LengthUnit::M as i32,
            Some("mm") => pb::LengthUnit::Mm as i32,
            _ => 99,
        },
        base: transform(&m["base"]),
        tool: transform(&m["tool"]),
        links: m["links"]
            .as_array()
            .map(|links| {
                links
                    .iter()
                    .map(|l| pb::Link {
                        name: s(&l["name"]),
                        joint: match l["joint"].as_str() {
                            Some("revolute") => pb::JointType::Revolute as i32,
                            Some("prismatic") => pb::JointType::Prismatic as i32,
                            Some("fixed") => pb::JointType::Fixed as i32,
                            _ => 99,
                        },
                        a: l.get("a").map(f),
                        alpha: l.get("alpha").map(f),
                        d: l.get("d").map(f),
                        theta: l.get("theta").map(f),
                        limits: l["limits"].as_array().map(|x| pb::Limits {
                            lo: f(&x[0]),
                            hi: f(&x[1]),
                        }),
                    })
                    .collect()
            })
            .unwrap_or_default(),
    }
}

fn modified(name: &str, edit: impl FnOnce(&mut Value)) -> Value {
    let mut m = planar_model(name);
    edit(&mut m);
    m
}

async fn register_over_rest(app: &TestApp, model: &Value, token: Option<&str>) -> Outcome {
    let mut req = app
        .client
        .post(format!("{}/v1/robots", app.http))
        .json(model);
    if let Some(t) = token {
        req = req.header("authorization", t);
    }
    rest_outcome(req.send().await.unwrap(), &[200, 201]).await
}

async fn rest_outcome(r: reqwest::Response, ok: &[u16]) -> Outcome {
    let status = r.status().as_u16();
    if ok.contains(&status) {
        return Ok(Success {
            pose: PoseOut {
                matrix: vec![],
                position: [0.0; 3],
                quaternion: [0.0; 4],
                rpy: [0.0; 3],
            },
            frames: None,
            length_unit: String::new(),
        });
    }
    let v: Value = r.json().await.expect("problem body");
    Err(problem_error(status, &v))
}

fn grpc_outcome<T>(r: Result<tonic::Response<T>, tonic::Status>) -> Outcome {
    match r {
        Ok(_) => Ok(Success {
            pose: PoseOut {
                matrix: vec![],
                position: [0.0; 3],
                quaternion: [0.0; 4],
                rpy: [0.0; 3],
            },
            frames: None,
            length_unit: String::new(),
        }),
        Err(s) => Err(Failure {
            class: class_of_code(s.code()),
            kind: status_kind(&s),
            fields: status_fields(&s),
            raw: format!("{s:?}"),
        }),
    }
}

fn assert_error(o: &Outcome, class: Class, fields: &[&str], what: &str) -> String {
    match o {
        Err(f) => {
            assert_eq!(f.class, class, "{what}: class ({})", f.raw);
            assert_eq!(f.fields, fields, "{what}: fields ({})", f.raw);
            assert!(
                !f.kind.is_empty(),
                "{what}: names its problem kind ({})",
                f.raw
            );
            f.kind.clone()
        }
        Ok(_) => panic!("{what}: expected {class:?}, it succeeded"),
    }
}

/// The same error over REST and gRPC: class, field paths and problem kind
/// (REST's problem type, gRPC's `ErrorInfo` reason).
fn assert_errors(rest: &Outcome, grpc: &Outcome, class: Class, fields: &[&str], what: &str) {
    let r = assert_error(rest, class, fields, &format!("{what} over REST"));
    let g = assert_error(grpc, class, fields, &format!("{what} over gRPC"));
    assert_eq!(
        g, r,
        "{what}: the gRPC ErrorInfo reason names REST's problem type"
    );
}

#[tokio::test]
async fn bad_models_are_rejected_alike_over_rest_and_grpc() {
    let app = spawn_app_with(|c| c.max_joints = 3).await;
    let mut c = app.grpc_client().await;
    let cases: Vec<(&str, Value, &[&str])> = vec![
        ("bad name", planar_model("Not OK"), &["name"]),
        ("empty name", planar_model(""), &["name"]),
        (
            "no links",
            modified("m1", |m| m["links"] = json!([])),
            &["links"],
        ),
        (
            "unknown convention",
            modified("m2", |m| m["convention"] = json!("sideways")),
            &["convention"],
        ),
        (
            "unknown joint type",
            modified("m3", |m| m["links"][1]["joint"] = json!("ball")),
            &["links[1].joint"],
        ),
        (
            "limits upside down",
            modified("m4", |m| m["links"][0]["limits"] = json!([10, -10])),
            &["links[0].limits"],
        ),
        (
            "zero tool quaternion",
            modified("m5", |m| {
                m["tool"] = json!({"quaternion": {"w": 0, "x": 0, "y": 0, "z": 0}})
            }),
            &["tool.quaternion"],
        ),
        (
            "non-rigid base matrix",
            modified("m6", |m| {
                m["base"] = json!({"matrix": [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})
            }),
            &["base.matrix"],
        ),
        (
            "too many joints",
            modified("m7", |m| {
                let l = m["links"][1].clone();
                m["links"] = json!([l, l, l, l]);
            }),
            &["links"],
        ),
    ];
    for (label, model, fields) in cases {
        let rest = register_over_rest(&app, &model, None).await;
        let grpc = grpc_outcome(
            c.register_robot(pb::RegisterRobotRequest {
                robot: Some(model_to_pb(&model)),
                replace: false,
                ..Default::default()
            })
            .await,
        );
        let (Err(r), Err(g)) = (&rest, &grpc) else {
            panic!("{label}: REST {rest:?}, gRPC {grpc:?}");
        };
        assert_eq!(r.class, Class::Invalid, "{label} over REST: {}", r.raw);
        assert_eq!(g.class, Class::Invalid, "{label} over gRPC: {}", g.raw);
        // The same problem kind, except for enum values the proto has no
        // name for: JSON refuses the unknown string while reading (400
        // malformed) where gRPC reads the number and the rule refuses it
        // (422 invalid), as with the non-finite stand-ins (see `contract`).
        if label.starts_with("unknown ") {
            let kinds = (r.kind.as_str(), g.kind.as_str());
            assert_eq!(kinds, ("malformed-request", "invalid-input"), "{label}");
        } else {
            assert_eq!(g.kind, r.kind, "{label}: ErrorInfo reason vs problem type");
        }
        // Same field paths on both doors; the first one is the expected field.
        let rs: Vec<&str> = r.fields.iter().map(String::as_str).collect();
        let gs: Vec<&str> = g.fields.iter().map(String::as_str).collect();
        assert_eq!(rs, gs, "{label}: REST {} vs gRPC {}", r.raw, g.raw);
        assert!(
            rs.first().is_some_and(|f| f.starts_with(fields[0])),
            "{label}: {rs:?} should name {fields:?}"
        );
    }
    // The good model converts and registers on both doors.
    register_over_rest(&app, &planar_model("fine_rest"), None)
        .await
        .unwrap();
    c.register_robot(pb::RegisterRobotRequest {
        robot: Some(model_to_pb(&planar_model("fine_grpc"))),
        replace: false,
        ..Default::default()
    })
    .await
    .unwrap();
}

#[tokio::test]
async fn registry_errors_have_the_same_class_over_rest_and_grpc() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let http =
        |m: reqwest::Method, path: &str| app.client.request(m, format!("{}{path}", app.http));
    use reqwest::Method;

    register_over_rest(&app, &planar_model("taken"), None)
        .await
        .unwrap();

    // Name taken: ALREADY_EXISTS / 409 already-exists.
    let rest = register_over_rest(&app, &planar_model("taken"), None).await;
    let grpc = grpc_outcome(
        c.register_robot(pb::RegisterRobotRequest {
            robot: Some(model_to_pb(&planar_model("taken"))),
            replace: false,
            ..Default::default()
        })
        .await,
    );
    assert_errors(&rest, &grpc, Class::AlreadyExists, &[], "taken");

    // Built-ins: read-only, whether created, replaced or deleted.
    let rest = register_over_rest(&app, &planar_model("puma560"), None).await;
    let grpc = grpc_outcome(
        c.register_robot(pb::RegisterRobotRequest {
            robot: Some(model_to_pb(&planar_model("puma560"))),
            replace: false,
            ..Default::default()
        })
        .await,
    );
    assert_errors(&rest, &grpc, Class::ReadOnly, &[], "create built-in");
    let rest = rest_outcome(
        http(Method::PUT, "/v1/robots/puma560")
            .json(&planar_model("puma560"))
            .send()
            .await
            .unwrap(),
        &[200, 201],
    )
    .await;
    let grpc = grpc_outcome(
        c.register_robot(pb::RegisterRobotRequest {
            robot: Some(model_to_pb(&planar_model("puma560"))),
            replace: true,
            ..Default::default()
        })
        .await,
    );
    assert_errors(&rest, &grpc, Class::ReadOnly, &[], "replace built-in");
    let rest = rest_outcome(
        http(Method::DELETE, "/v1/robots/panda")
            .send()
            .await
            .unwrap(),
        &[204],
    )
    .await;
    let grpc = grpc_outcome(
        c.delete_robot(pb::DeleteRobotRequest {
            name: "panda".into(),
            ..Default::default()
        })
        .await,
    );
    assert_errors(&rest, &grpc, Class::ReadOnly, &[], "delete built-in");

    // Unknown robots.
    let rest = rest_outcome(
        http(Method::DELETE, "/v1/robots/ghost")
            .send()
            .await
            .unwrap(),
        &[204],
    )
    .await;
    let grpc = grpc_outcome(
        c.delete_robot(pb::DeleteRobotRequest {
            name: "ghost".into(),
            ..Default::default()
        })
        .await,
    );
    assert_errors(&rest, &grpc, Class::NotFound, &[], "delete unknown");
    let rest = rest_outcome(
        http(Method::GET, "/v1/robots/ghost").send().await.unwrap(),
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.get_robot(pb::GetRobotRequest {
            name: "ghost".into(),
        })
        .await,
    );
    assert_errors(&rest, &grpc, Class::NotFound, &[], "get unknown");
    let rest = rest_outcome(
        http(Method::POST, "/v1/robots/ghost/fk/batch")
            .json(&json!({"configurations": [[0, 0]]}))
            .send()
            .await
            .unwrap(),
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "ghost".into(),
            configurations: vec![pb::JointConfiguration {
                joints: vec![0.0, 0.0],
            }],
            options: None,
            ..Default::default()
        })
        .await,
    );
    assert_errors(&rest, &grpc, Class::NotFound, &[], "batch unknown");

    // A bad configuration in a batch is named the same way.
    let rest = rest_outcome(
        http(Method::POST, "/v1/robots/taken/fk/batch")
            .json(&json!({"configurations": [[0, 0], [0, 0], [400, 0]], "angle_unit": "deg"}))
            .send()
            .await
            .unwrap(),
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "taken".into(),
            configurations: vec![
                pb::JointConfiguration {
                    joints: vec![0.0, 0.0],
                },
                pb::JointConfiguration {
                    joints: vec![0.0, 0.0],
                },
                pb::JointConfiguration {
                    joints: vec![400.0, 0.0],
                },
            ],
            options: Some(pb::FkOptions {
                angle_unit: pb::AngleUnit::Deg as i32,
                ..Default::default()
            }),
            ..Default::default()
        })
        .await,
    );
    assert_errors(
        &rest,
        &grpc,
        Class::Invalid,
        &["configurations[2][0]"],
        "batch limit",
    );
}

#[tokio::test]
async fn auth_and_size_limits_have_the_same_class_over_rest_and_grpc() {
    let app = spawn_app_with(|c| {
        c.api_token = Some("tok".into());
        c.max_batch = 3;
        c.max_batch_body_bytes = 32 << 10;
    })
    .await;
    let mut c = app.grpc_client().await;

    for token in [None, Some("Bearer nope")] {
        let rest = register_over_rest(&app, &planar_model("guarded"), token).await;
        let mut req = tonic::Request::new(pb::RegisterRobotRequest {
            robot: Some(model_to_pb(&planar_model("guarded"))),
            replace: false,
            ..Default::default()
        });
        if let Some(t) = token {
            req.metadata_mut()
                .insert("authorization", t.parse().unwrap());
        }
        let grpc = grpc_outcome(c.register_robot(req).await);
        assert_errors(&rest, &grpc, Class::Unauthenticated, &[], "register");
    }
    let rest = rest_outcome(
        app.client
            .delete(format!("{}/v1/robots/puma560", app.http))
            .send()
            .await
            .unwrap(),
        &[204],
    )
    .await;
    let grpc = grpc_outcome(
        c.delete_robot(pb::DeleteRobotRequest {
            name: "puma560".into(),
            ..Default::default()
        })
        .await,
    );
    assert_errors(&rest, &grpc, Class::Unauthenticated, &[], "delete");

    // Over the batch count: too large, naming `configurations`.
    let rest = rest_outcome(
        app.post(
            "/v1/robots/puma560/fk/batch",
            &json!({"configurations": vec![vec![0; 6]; 4]}),
        )
        .await,
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "puma560".into(),
            configurations: vec![
                pb::JointConfiguration {
                    joints: vec![0.0; 6]
                };
                4
            ],
            options: None,
            ..Default::default()
        })
        .await,
    );
    assert_errors(
        &rest,
        &grpc,
        Class::TooLarge,
        &["configurations"],
        "batch count",
    );

    // Over the byte limit of a batch body / message (the count limit is not reached).
    let joints = vec![0.123456789; 5000]; // 40 KB as doubles, ~60 KB as JSON
    let rest = rest_outcome(
        app.post(
            "/v1/robots/puma560/fk/batch",
            &json!({"configurations": [joints.clone()]}),
        )
        .await,
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "puma560".into(),
            configurations: vec![pb::JointConfiguration { joints }],
            options: None,
            ..Default::default()
        })
        .await,
    );
    assert_errors(&rest, &grpc, Class::TooLarge, &[], "batch bytes");

    // Health of the gRPC door, for completeness of the suite's server.
    let mut h = tonic_health::pb::health_client::HealthClient::new(channel(&app).await);
    let s = h
        .check(tonic_health::pb::HealthCheckRequest {
            service: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(
        s.status,
        tonic_health::pb::health_check_response::ServingStatus::Serving as i32
    );
    assert_eq!(app.get("/readyz").await.status(), 200);
}
