//! The gRPC corpus: typed messages, raw frames and stream cases, with the
//! parallel FK client checking the server keeps answering. OK answers' poses
//! are checked against the plain reference product (1e-12); the case count
//! has a floor (today's 53).

use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use serde_json::{Value, json};
use tokio_stream::wrappers::ReceiverStream;
use tonic::Code;

use crate::helpers::*;

// ---------------------------------------------------------------- gRPC corpus

fn num(v: &Value) -> f64 {
    match v {
        Value::Number(n) => n.as_f64().unwrap(),
        Value::String(s) => match s.as_str() {
            "NaN" => f64::NAN,
            "Infinity" => f64::INFINITY,
            "-Infinity" => f64::NEG_INFINITY,
            "-0" => -0.0,
            other => panic!("unknown number {other}"),
        },
        other => panic!("not a number: {other}"),
    }
}

fn nums(v: &Value) -> Vec<f64> {
    v.as_array()
        .map(|a| a.iter().map(num).collect())
        .unwrap_or_default()
}

fn enum_of(v: &Value, names: &[(&str, i32)], default: i32) -> i32 {
    match v {
        Value::Number(n) => n.as_i64().unwrap() as i32,
        Value::String(s) => names.iter().find(|(n, _)| n == s).unwrap().1,
        _ => default,
    }
}

fn transform_pb(t: &Value) -> Option<pb::FixedTransform> {
    if t.is_null() {
        return None;
    }
    use pb::fixed_transform::Rotation;
    let rotation = if !t["matrix"].is_null() {
        Some(Rotation::Matrix(pb::Matrix4 {
            values: nums(&t["matrix"]),
        }))
    } else if !t["quaternion"].is_null() {
        let q = nums(&t["quaternion"]);
        Some(Rotation::Quaternion(pb::Quaternion {
            w: q[0],
            x: q[1],
            y: q[2],
            z: q[3],
        }))
    } else {
        None
    };
    Some(pb::FixedTransform {
        translation: None,
        rotation,
    })
}

fn model_pb(m: &Value) -> pb::Robot {
    let joints = [
        ("revolute", pb::JointType::Revolute as i32),
        ("prismatic", pb::JointType::Prismatic as i32),
        ("fixed", pb::JointType::Fixed as i32),
    ];
    pb::Robot {
        name: m["name"].as_str().unwrap_or("").to_owned(),
        description: m["description"].as_str().map(str::to_owned),
        source: None,
        convention: enum_of(
            &m["convention"],
            &[
                ("standard", pb::Convention::Standard as i32),
                ("modified", pb::Convention::Modified as i32),
            ],
            0,
        ),
        angle_unit: enum_of(
            &m["angle_unit"],
            &[
                ("rad", pb::AngleUnit::Rad as i32),
                ("deg", pb::AngleUnit::Deg as i32),
            ],
            0,
        ),
        length_unit: enum_of(
            &m["length_unit"],
            &[
                ("m", pb::LengthUnit::M as i32),
                ("mm", pb::LengthUnit::Mm as i32),
            ],
            0,
        ),
        base: transform_pb(&m["base"]),
        tool: transform_pb(&m["tool"]),
        links: m["links"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| pb::Link {
                name: None,
                joint: enum_of(&l["joint"], &joints, 0),
                a: l.get("a").map(num),
                alpha: l.get("alpha").map(num),
                d: l.get("d").map(num),
                theta: l.get("theta").map(num),
                limits: l["limits"].as_array().map(|x| pb::Limits {
                    lo: num(&x[0]),
                    hi: num(&x[1]),
                }),
            })
            .collect(),
    }
}

fn gen_n(case: &Value) -> usize {
    case["gen"]["n"].as_u64().unwrap_or(0) as usize
}

fn case_joints(case: &Value) -> Vec<f64> {
    match case["gen"]["kind"].as_str() {
        Some("joints") => vec![0.0; gen_n(case)],
        _ => nums(&case["joints"]),
    }
}

fn case_options(case: &Value) -> Option<pb::FkOptions> {
    case["angle_unit"].as_i64().map(|u| pb::FkOptions {
        angle_unit: u as i32,
        ..Default::default()
    })
}

/// Stream cases in today's corpus (the floor the replay asserts).
const STREAM_CASES: usize = 14;

fn code_named(name: &str) -> Code {
    match name {
        "Ok" => Code::Ok,
        "InvalidArgument" => Code::InvalidArgument,
        "NotFound" => Code::NotFound,
        "ResourceExhausted" => Code::ResourceExhausted,
        "Unimplemented" => Code::Unimplemented,
        other => panic!("code {other}"),
    }
}

fn check_status(case: &Value, r: Result<(), tonic::Status>) -> Result<(), String> {
    let want = code_named(case["code"].as_str().unwrap());
    let status = match r {
        Ok(()) if want == Code::Ok => return Ok(()),
        Ok(()) => return Err(format!("OK instead of {want:?}")),
        Err(s) => s,
    };
    if status.code() != want {
        return Err(format!(
            "{:?} instead of {want:?}: {status:?}",
            status.code()
        ));
    }
    if status.message().is_empty() {
        return Err("empty status message".into());
    }
    let got = status_fields(&status).into_iter().next();
    let want_field = case["field"].as_str().map(str::to_owned);
    if got != want_field {
        return Err(format!(
            "field {got:?} instead of {want_field:?}: {status:?}"
        ));
    }
    Ok(())
}

/// Whether a case's options ask for degrees.
fn case_deg(case: &Value) -> bool {
    case_options(case).is_some_and(|o| o.angle_unit == pb::AngleUnit::Deg as i32)
}

/// Checks an OK answer's pose against the reference product.
fn check_pb_pose(case: &Value, joints: &[f64], pose: Option<&pb::Pose>) -> Result<(), String> {
    let robot = case["robot"].as_str().unwrap();
    let pose = pose.ok_or("an OK answer without a pose")?;
    matrix_matches(&pose.matrix, &reference_pose(robot, joints, case_deg(case)))
}

async fn run_grpc_case(
    c: &mut KinematicsServiceClient<tonic::transport::Channel>,
    raw: &reqwest::Client,
    grpc: &str,
    case: &Value,
) -> Result<(), String> {
    let r = match case["rpc"].as_str().unwrap() {
        "fk" => {
            let joints = case_joints(case);
            let answer = c
                .forward_kinematics(pb::ForwardKinematicsRequest {
                    robot: case["robot"].as_str().unwrap().to_owned(),
                    joints: joints.clone(),
                    options: case_options(case),
                })
                .await;
            if let Ok(a) = &answer {
                check_pb_pose(case, &joints, a.get_ref().pose.as_ref())?;
            }
            answer.map(drop)
        }
        "batch" => {
            let configurations = match case["gen"]["kind"].as_str() {
                Some("configs") => vec![
                    pb::JointConfiguration {
                        joints: vec![0.0, 0.0]
                    };
                    gen_n(case)
                ],
                _ => case["configurations"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|q| pb::JointConfiguration { joints: nums(q) })
                    .collect(),
            };
            let answer = c
                .forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
                    robot: case["robot"].as_str().unwrap().to_owned(),
                    configurations: configurations.clone(),
                    options: None,
                    ..Default::default()
                })
                .await;
            if let Ok(a) = &answer {
                let poses = &a.get_ref().poses;
                if poses.len() != configurations.len() {
                    return Err(format!(
                        "{} poses for {} configurations",
                        poses.len(),
                        configurations.len()
                    ));
                }
                for (i, (q, pose)) in configurations.iter().zip(poses).enumerate() {
                    check_pb_pose(case, &q.joints, Some(pose))
                        .map_err(|e| format!("poses[{i}]: {e}"))?;
                }
            }
            answer.map(drop)
        }
        "register" => {
            let robot = match case["gen"]["kind"].as_str() {
                Some("links") => {
                    let joint = case["gen"]["joint"].as_str().unwrap_or("fixed");
                    let row = json!({"joint": joint, "a": 0, "alpha": 0, "d": 0, "theta": 0});
                    Some(model_pb(&json!({
                        "name": "hostile_links", "convention": "standard",
                        "links": vec![row; gen_n(case)],
                    })))
                }
                _ if case["model"].is_null() => None,
                _ => Some(model_pb(&case["model"])),
            };
            c.register_robot(pb::RegisterRobotRequest {
                robot,
                replace: false,
                ..Default::default()
            })
            .await
            .map(drop)
        }
        "get" => c
            .get_robot(pb::GetRobotRequest {
                name: case["name"].as_str().unwrap().to_owned(),
            })
            .await
            .map(drop),
        "delete" => c
            .delete_robot(pb::DeleteRobotRequest {
                name: case["name"].as_str().unwrap().to_owned(),
                ..Default::default()
            })
            .await
            .map(drop),
        "raw" => return run_raw_grpc_case(raw, grpc, case).await,
        other => panic!("rpc {other}"),
    };
    check_status(case, r)
}

/// POSTs raw gRPC frames over h2c and reads the status from the (trailers-only) response.
async fn run_raw_grpc_case(raw: &reqwest::Client, grpc: &str, case: &Value) -> Result<(), String> {
    let method = case["method"].as_str().unwrap();
    let mut req = raw
        .post(format!("{grpc}/kinematics.v1.KinematicsService/{method}"))
        .header("content-type", "application/grpc")
        .header("te", "trailers")
        .body(hex(case["frame_hex"].as_str().unwrap()));
    if let Some(h) = case["headers"].as_object() {
        for (k, v) in h {
            req = req.header(k.as_str(), v.as_str().unwrap());
        }
    }
    let resp = req.send().await.map_err(|e| format!("send: {e}"))?;
    if resp.status() != 200 {
        return Err(format!("HTTP status {}", resp.status()));
    }
    let code = resp
        .headers()
        .get("grpc-status")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<i32>().ok())
        .ok_or_else(|| format!("no grpc-status in the headers: {:?}", resp.headers()))?;
    let message = resp
        .headers()
        .get("grpc-message")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_owned();
    let want = code_named(case["code"].as_str().unwrap());
    if Code::from_i32(code) != want {
        return Err(format!(
            "{:?} instead of {want:?}: {message}",
            Code::from_i32(code)
        ));
    }
    if message.is_empty() {
        return Err("empty grpc-message".into());
    }
    Ok(())
}

async fn run_stream_cases(
    c: &mut KinematicsServiceClient<tonic::transport::Channel>,
    cases: &[&Value],
) -> Vec<String> {
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let mut inbound = c
        .stream_forward_kinematics(ReceiverStream::new(rx))
        .await
        .expect("stream opens")
        .into_inner();
    let mut failures = Vec::new();
    for (i, case) in cases.iter().enumerate() {
        let name = case["name"].as_str().unwrap();
        let id = i as u64 + 1;
        tx.send(pb::StreamForwardKinematicsRequest {
            id,
            robot: case["robot"].as_str().unwrap().to_owned(),
            joints: case_joints(case),
            options: case_options(case),
            ..Default::default()
        })
        .await
        .unwrap();
        let resp = match inbound.message().await {
            Ok(Some(m)) => m,
            other => {
                failures.push(format!("stream {name}: {other:?}"));
                return failures;
            }
        };
        if resp.id != id {
            failures.push(format!("stream {name}: id {} instead of {id}", resp.id));
        }
        let want = code_named(case["code"].as_str().unwrap());
        match (&resp.result, want) {
            (Some(StreamResult::Pose(p)), Code::Ok) => {
                if let Err(e) = check_pb_pose(case, &case_joints(case), Some(p)) {
                    failures.push(format!("stream {name}: {e}"));
                }
            }
            (Some(StreamResult::Error(s)), w) if s.code == w as i32 => {
                let got = rpc_status_fields(s).into_iter().next();
                let want_field = case["field"].as_str().map(str::to_owned);
                if got != want_field || s.message.is_empty() {
                    failures.push(format!(
                        "stream {name}: field {got:?} instead of {want_field:?} ({s:?})"
                    ));
                }
            }
            (other, w) => failures.push(format!("stream {name}: {other:?} instead of {w:?}")),
        }
    }
    drop(tx);
    failures
}

/// The gRPC corpus: typed messages on every RPC, the FK ones again on the
/// bidirectional stream, and raw frames (garbage, truncated, oversized,
/// compressed) over h2c; a parallel client checks correct FK all along.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn the_grpc_corpus_gets_documented_statuses_and_the_server_keeps_answering() {
    let app = spawn_app().await;
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    let cases = corpus("grpc.json");
    let mut c = app.grpc_client().await;
    let raw = reqwest::Client::builder()
        .http2_prior_knowledge()
        .build()
        .unwrap();
    let mut failures = Vec::new();
    for case in &cases {
        let name = case["name"].as_str().unwrap();
        if let Err(e) = run_grpc_case(&mut c, &raw, &app.grpc, case).await {
            failures.push(format!("{name}: {e}"));
        }
    }
    let stream_cases: Vec<&Value> = cases.iter().filter(|c| c["stream"] == true).collect();
    failures.extend(run_stream_cases(&mut c, &stream_cases).await);
    // Nothing was registered; the server still answers on the same channel.
    let list = c
        .list_robots(pb::ListRobotsRequest::default())
        .await
        .unwrap();
    assert!(
        list.into_inner()
            .robots
            .iter()
            .all(|r| r.source == pb::RobotSource::Builtin as i32)
    );
    let report = checker.finish().await;
    // Today's corpus: 53 calls, of which the stream repeats the FK ones; a
    // corpus file that lost cases fails.
    assert!(
        cases.len() >= 53,
        "{} gRPC corpus cases (at least 53)",
        cases.len()
    );
    assert!(
        stream_cases.len() >= STREAM_CASES,
        "{} stream cases",
        stream_cases.len()
    );
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    println!(
        "hostile gRPC corpus: {} calls, {} stream messages; parallel FK ok: {} REST, {} gRPC, {} WebSocket",
        cases.len(),
        stream_cases.len(),
        report.rest,
        report.grpc,
        report.ws
    );
}
