//! Binary batch bodies on REST: `application/x-protobuf` (the gRPC messages)
//! and packed `application/octet-stream` (little-endian float64) on the FK,
//! Jacobian and IK batch routes. Every binary answer is compared with the
//! JSON answer to the same request bit for bit (JSON's numbers read back
//! exactly: serde_json prints the shortest text that parses to the same
//! double, and parses with `float_roundtrip`), the protobuf answers with
//! gRPC's byte for byte; `Accept` is negotiated independently of the
//! request's type; and the refusals (bad length, wrong joint count, another
//! robot's message, unsupported types, limits) are problem+json.

use kinserve::api::grpc::pb;
use prost::Message;
use serde_json::{Value, json};

use crate::helpers::*;

const PROTOBUF: &str = "application/x-protobuf";
const PACKED: &str = "application/octet-stream";

/// The body of a 200 answer of `content_type`.
async fn ok_bytes(r: reqwest::Response, content_type: &str) -> Vec<u8> {
    let status = r.status();
    let ct = r.headers()["content-type"].to_str().unwrap().to_owned();
    let body = r.bytes().await.unwrap().to_vec();
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    assert_eq!(ct, content_type);
    body
}

/// Joint values as a packed body: little-endian float64, row-major.
fn packed(configurations: &[Vec<f64>]) -> Vec<u8> {
    configurations
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect()
}

/// A packed answer's numbers.
fn unpack(bytes: &[u8]) -> Vec<f64> {
    assert_eq!(bytes.len() % 8, 0, "{} bytes", bytes.len());
    bytes
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// Every number of `v` (arrays and objects in order, `null` as +inf), for
/// bit comparisons.
fn numbers(v: &Value, out: &mut Vec<f64>) {
    match v {
        Value::Number(n) => out.push(n.as_f64().unwrap()),
        Value::Null => out.push(f64::INFINITY),
        Value::Bool(b) => out.push(if *b { 1.0 } else { 0.0 }),
        Value::Array(a) => a.iter().for_each(|x| numbers(x, out)),
        other => panic!("not a number: {other}"),
    }
}

/// Asserts the two lists hold the same doubles, bit for bit (`-0.0` is not `0.0`).
fn assert_bits_eq(got: &[f64], want: &[f64], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: count");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            g.to_bits() == w.to_bits(),
            "{what}: number {i}: {g:e} vs {w:e}"
        );
    }
}

/// Configurations for `dof` joints whose values need all 17 digits (so a
/// lossy JSON round trip would show), mixed with the plain test values, the
/// first all zeros.
fn awkward_configs(n: usize, dof: usize) -> Vec<Vec<f64>> {
    let mut qs = configs(n, dof);
    for (i, q) in qs.iter_mut().enumerate() {
        if i % 2 == 0 {
            for (j, x) in q.iter_mut().enumerate() {
                *x = (*x + (j as f64 + 1.0) / 3.0).clamp(-1.5, 1.5)
                    * std::f64::consts::FRAC_1_SQRT_2;
            }
        }
    }
    // All zeros: the PUMA's matrix holds negative zeros (`-0.0`), which must survive.
    if let Some(q) = qs.first_mut() {
        q.iter_mut().for_each(|x| *x = 0.0);
    }
    qs
}

fn pb_format(format: &str) -> i32 {
    match format {
        "matrix" => pb::PoseFormat::Matrix as i32,
        "position" => pb::PoseFormat::Position as i32,
        _ => pb::PoseFormat::Full as i32,
    }
}

fn fk_message(robot: &str, qs: &[Vec<f64>], format: &str) -> pb::ForwardKinematicsBatchRequest {
    pb::ForwardKinematicsBatchRequest {
        robot: robot.into(),
        configurations: qs
            .iter()
            .map(|q| pb::JointConfiguration { joints: q.clone() })
            .collect(),
        options: Some(pb::FkOptions {
            pose_format: pb_format(format),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// The numbers a packed FK answer holds for the JSON answer `json` in `format`.
fn packed_numbers_of_json(json: &Value, format: &str) -> Vec<f64> {
    let mut out = Vec::new();
    match format {
        "matrix" => numbers(&json["matrices"], &mut out),
        "position" => numbers(&json["positions"], &mut out),
        _ => {
            for pose in json["poses"].as_array().unwrap() {
                numbers(
                    &Value::from(pose["matrix"].as_array().unwrap()[..3].to_vec()),
                    &mut out,
                );
            }
        }
    }
    out
}

#[tokio::test]
async fn fk_batch_answers_in_every_format_are_the_json_answer_bit_for_bit() {
    let app = spawn_app().await;
    let mut grpc = app.grpc_client().await;
    let path = "/v1/robots/puma560/fk/batch";
    // 1,500 full poses: the JSON answer is streamed; 7: it is sent whole.
    for n in [7, 1_500] {
        let qs = awkward_configs(n, 6);
        for format in ["full", "matrix", "position"] {
            let what = format!("{n} × {format}");
            let body = json!({"configurations": qs, "pose_format": format});
            let json_text = ok_bytes(app.post(path, &body).await, "application/json").await;
            let json: Value = serde_json::from_slice(&json_text).unwrap();

            // Packed in, packed out.
            let query = format!("{path}?pose_format={format}");
            let r = app.post_bytes(&query, PACKED, PACKED, packed(&qs)).await;
            let want_format = if format == "position" {
                "position"
            } else {
                "matrix"
            };
            assert_eq!(r.headers()["kinserve-pose-format"], want_format, "{what}");
            assert_eq!(r.headers()["kinserve-length-unit"], "m", "{what}");
            let packed_answer = ok_bytes(r, PACKED).await;
            let stride = if format == "position" { 3 } else { 12 };
            assert_eq!(packed_answer.len(), n * stride * 8, "{what}");
            let from_json = packed_numbers_of_json(&json, format);
            assert_bits_eq(&unpack(&packed_answer), &from_json, &what);
            // JSON's text of each number reads back as the same double.
            for x in &from_json {
                let text = serde_json::to_string(x).unwrap();
                assert_eq!(
                    serde_json::from_str::<f64>(&text).unwrap().to_bits(),
                    x.to_bits()
                );
            }

            // Protobuf in; JSON, protobuf and packed out.
            let msg = fk_message("", &qs, format).encode_to_vec();
            let r = app
                .post_bytes(path, PROTOBUF, "application/json", msg.clone())
                .await;
            assert!(
                ok_bytes(r, "application/json").await == json_text,
                "{what}: the JSON answer to the protobuf request differs"
            );
            let r = app.post_bytes(path, PROTOBUF, PACKED, msg.clone()).await;
            assert!(ok_bytes(r, PACKED).await == packed_answer, "{what}");
            let rest_pb = ok_bytes(
                app.post_bytes(path, PROTOBUF, PROTOBUF, msg).await,
                PROTOBUF,
            )
            .await;

            // The protobuf answer is gRPC's answer, byte for byte.
            let grpc_answer = grpc
                .forward_kinematics_batch(fk_message("puma560", &qs, format))
                .await
                .unwrap()
                .into_inner();
            assert!(
                rest_pb == grpc_answer.encode_to_vec(),
                "{what}: REST protobuf ≠ gRPC"
            );
            let decoded = pb::ForwardKinematicsBatchResponse::decode(rest_pb.as_slice()).unwrap();
            assert_eq!(decoded.robot, "puma560");
            let mut from_pb = Vec::new();
            match decoded.packed_poses {
                Some(p) => from_pb = p.values,
                None => decoded
                    .poses
                    .iter()
                    .for_each(|p| from_pb.extend(&p.matrix[..12])),
            }
            assert_bits_eq(&from_pb, &from_json, &format!("{what} protobuf"));

            // JSON in, protobuf out: the same message.
            let r = app
                .client
                .post(format!("{}{path}", app.http))
                .header("accept", PROTOBUF)
                .json(&body)
                .send()
                .await
                .unwrap();
            assert!(
                ok_bytes(r, PROTOBUF).await == grpc_answer.encode_to_vec(),
                "{what}"
            );
        }
    }
}

#[tokio::test]
async fn packed_fk_options_come_as_query_parameters() {
    let app = spawn_app().await;
    let path = "/v1/robots/scara_4dof/fk/batch";
    // Degrees, and a quill beyond its 0.2 m limit that only check_limits=false lets through.
    let qs = vec![vec![30.0, -45.0, 0.1, 10.0], vec![0.0, 90.0, 0.5, -20.0]];
    let body = json!({"configurations": qs, "angle_unit": "deg", "check_limits": false, "pose_format": "position"});
    let json: Value = app.post(path, &body).await.json().await.unwrap();
    let query = format!("{path}?angle_unit=deg&check_limits=false&pose_format=position");
    let got = ok_bytes(
        app.post_bytes(&query, PACKED, PACKED, packed(&qs)).await,
        PACKED,
    )
    .await;
    let mut want = Vec::new();
    numbers(&json["positions"], &mut want);
    assert_bits_eq(&unpack(&got), &want, "deg, no limit check");
    // Without check_limits=false the same body is refused, naming the value.
    let query = format!("{path}?angle_unit=deg");
    let p = problem(
        app.post_bytes(&query, PACKED, PACKED, packed(&qs)).await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["configurations[1][2]"]);
    // A packed body answered as JSON, and with a JSON answer the default is `full`.
    let r = app
        .post_bytes(
            &format!("{path}?angle_unit=deg&check_limits=false"),
            PACKED,
            "",
            packed(&qs),
        )
        .await;
    let as_json: Value = serde_json::from_slice(&ok_bytes(r, "application/json").await).unwrap();
    assert_eq!(as_json["poses"].as_array().unwrap().len(), 2);
    assert!(json_eq(
        &as_json["poses"][1]["position"],
        &json["positions"][1]
    ));
    // joint_count: the robot's passes; another is refused even when the
    // length is a whole number of the robot's configurations (8 values: two
    // of 4 joints, or four of 2), on both batch routes.
    let query =
        format!("{path}?angle_unit=deg&check_limits=false&pose_format=position&joint_count=4");
    let got = ok_bytes(
        app.post_bytes(&query, PACKED, PACKED, packed(&qs)).await,
        PACKED,
    )
    .await;
    assert_bits_eq(&unpack(&got), &want, "with joint_count");
    for route in [path, "/v1/robots/scara_4dof/jacobian/batch"] {
        let query = format!("{route}?angle_unit=deg&check_limits=false&joint_count=2");
        let p = problem(
            app.post_bytes(&query, PACKED, PACKED, packed(&qs)).await,
            422,
        )
        .await;
        assert_eq!(fields(&p), ["joint_count"], "{route}");
        assert!(p["detail"].as_str().unwrap().contains("4 joints"), "{p}");
    }
    // Unknown or ill-typed parameters: 400 naming the query.
    for bad in [
        "pose_fromat=matrix",
        "angle_unit=grad",
        "check_limits=maybe",
        "joint_count=-1",
    ] {
        let r = app
            .post_bytes(&format!("{path}?{bad}"), PACKED, PACKED, packed(&qs))
            .await;
        let p = problem(r, 400).await;
        assert_eq!(fields(&p), ["query"], "{bad}");
    }
}

#[tokio::test]
async fn accept_chooses_the_answer_whatever_the_request() {
    let app = spawn_app().await;
    let path = "/v1/robots/planar_2dof/fk/batch";
    let qs = vec![vec![0.5, 0.1], vec![-1.0, 2.0]];
    for (accept, want) in [
        ("", "application/json"),
        ("*/*", "application/json"),
        ("application/*", "application/json"),
        (
            "application/json, application/x-protobuf",
            "application/json",
        ),
        (
            "application/x-protobuf, application/json",
            "application/json",
        ),
        ("application/x-protobuf, */*", PROTOBUF),
        ("text/html, application/x-protobuf;q=0.5", PROTOBUF),
        ("application/octet-stream, */*;q=0.1", PACKED),
        (
            "application/json;q=0.2, application/octet-stream;q=0.9",
            PACKED,
        ),
        ("APPLICATION/OCTET-STREAM", PACKED),
    ] {
        for (ct, body) in [
            (
                "application/json",
                serde_json::to_vec(&json!({"configurations": qs})).unwrap(),
            ),
            (PACKED, packed(&qs)),
        ] {
            let r = app.post_bytes(path, ct, accept, body).await;
            assert_eq!(r.status(), 200, "Accept {accept:?}, {ct}");
            assert_eq!(r.headers()["content-type"], want, "Accept {accept:?}, {ct}");
        }
    }
    for accept in [
        "text/csv",
        "application/json;q=0, application/x-protobuf;q=0",
        "image/*",
    ] {
        let r = app.post_bytes(path, PACKED, accept, packed(&qs)).await;
        let p = problem(r, 406).await;
        assert_eq!(p["type"], "urn:kinserve:problem:not-acceptable");
        assert!(p["detail"].as_str().unwrap().contains(PACKED), "{p}");
    }
    // The IK batch has no packed form: asking for it is 406, sending it 415.
    let ik = "/v1/robots/planar_2dof/ik/batch";
    let body = serde_json::to_vec(
        &json!({"targets": [{"position": [0.5, 0.3, 0.0]}], "position_only": true}),
    )
    .unwrap();
    problem(
        app.post_bytes(ik, "application/json", PACKED, body).await,
        406,
    )
    .await;
    let p = problem(app.post_bytes(ik, PACKED, "", packed(&qs)).await, 415).await;
    let detail = p["detail"].as_str().unwrap();
    assert!(detail.contains("application/x-protobuf, got"), "{p}");
}

#[tokio::test]
async fn binary_refusals_are_problems_naming_what_is_wrong() {
    let app = spawn_app().await;
    let path = "/v1/robots/puma560/fk/batch";
    // A length that is not a whole number of 6-joint configurations (48 bytes):
    // 13 numbers, 7 bytes, two configurations of the 2-joint arm.
    for (body, what) in [
        (vec![0u8; 13 * 8], "13 numbers"),
        (vec![0u8; 7], "7 bytes"),
        (
            packed(&[vec![0.1, 0.2], vec![0.3, 0.4]]),
            "planar configurations",
        ),
    ] {
        let p = problem(app.post_bytes(path, PACKED, PACKED, body).await, 400).await;
        assert_eq!(fields(&p), ["body"], "{what}");
        assert!(
            p["detail"].as_str().unwrap().contains("48 bytes"),
            "{what}: {p}"
        );
    }
    // An empty packed body is an empty batch.
    assert!(
        ok_bytes(
            app.post_bytes(path, PACKED, PACKED, Vec::new()).await,
            PACKED
        )
        .await
        .is_empty()
    );
    // A value JSON cannot carry: refused like an out-of-range one, naming it.
    let mut qs = configs(3, 6);
    qs[2][4] = f64::NAN;
    let p = problem(app.post_bytes(path, PACKED, PACKED, packed(&qs)).await, 422).await;
    assert_eq!(fields(&p), ["configurations[2][4]"]);
    // Protobuf: a configuration of the wrong length, another robot's
    // message, bytes that are no message, frames asked of a batch.
    let mut msg = fk_message("puma560", &configs(3, 6), "matrix");
    msg.configurations[1].joints.pop();
    let p = problem(
        app.post_bytes(path, PROTOBUF, PROTOBUF, msg.encode_to_vec())
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["configurations[1]"]);
    let msg = fk_message("ur5e", &configs(3, 6), "matrix");
    let p = problem(
        app.post_bytes(path, PROTOBUF, PROTOBUF, msg.encode_to_vec())
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["robot"]);
    let p = problem(
        app.post_bytes(path, PROTOBUF, PROTOBUF, vec![0xff; 9])
            .await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["body"]);
    let mut msg = fk_message("", &configs(1, 6), "full");
    msg.options = Some(pb::FkOptions {
        frames: Some(true),
        ..Default::default()
    });
    let p = problem(
        app.post_bytes(path, PROTOBUF, PROTOBUF, msg.encode_to_vec())
            .await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["options.frames"]);
    // Another media type: the usual 415, listing the three.
    let p = problem(
        app.post_bytes(path, "text/plain", PACKED, b"1 2 3".to_vec())
            .await,
        415,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains(PROTOBUF), "{p}");
    // An unknown robot is 404 whatever the body.
    problem(
        app.post_bytes("/v1/robots/nope/fk/batch", PACKED, PACKED, vec![0; 48])
            .await,
        404,
    )
    .await;
}

#[tokio::test]
async fn binary_batches_have_the_json_limits() {
    let app = spawn_app_with(|c| {
        c.max_batch = 3;
        c.max_batch_body_bytes = 4096;
    })
    .await;
    let path = "/v1/robots/planar_2dof/fk/batch";
    let ok = ok_bytes(
        app.post_bytes(path, PACKED, PACKED, packed(&configs(3, 2)))
            .await,
        PACKED,
    )
    .await;
    assert_eq!(ok.len(), 3 * 12 * 8);
    let p = problem(
        app.post_bytes(path, PACKED, PACKED, packed(&configs(4, 2)))
            .await,
        413,
    )
    .await;
    assert_eq!(fields(&p), ["configurations"]);
    let msg = fk_message("", &configs(4, 2), "matrix").encode_to_vec();
    let p = problem(app.post_bytes(path, PROTOBUF, PROTOBUF, msg).await, 413).await;
    assert_eq!(fields(&p), ["configurations"]);
    let jac = "/v1/robots/planar_2dof/jacobian/batch";
    problem(
        app.post_bytes(jac, PACKED, PACKED, packed(&configs(4, 2)))
            .await,
        413,
    )
    .await;
    // Over the batch body limit.
    let p = problem(
        app.post_bytes(path, PACKED, PACKED, vec![0; 4096 + 16])
            .await,
        413,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("4096"), "{p}");
}

#[tokio::test]
async fn jacobian_batch_answers_in_every_format_are_the_json_answer_bit_for_bit() {
    let app = spawn_app().await;
    let mut grpc = app.grpc_client().await;
    for (robot, dof) in [("puma560", 6), ("planar_2dof", 2)] {
        let path = format!("/v1/robots/{robot}/jacobian/batch");
        let mut qs = awkward_configs(20, dof);
        qs.push(vec![0.0; dof]); // singular: condition_number is null
        for frame in ["base", "tool"] {
            let what = format!("{robot} {frame}");
            let body = json!({"configurations": qs, "frame": frame});
            let json_text = ok_bytes(app.post(&path, &body).await, "application/json").await;
            let json: Value = serde_json::from_slice(&json_text).unwrap();
            let mut want = Vec::new();
            for r in json["results"].as_array().unwrap() {
                numbers(&r["jacobian"], &mut want);
                for key in ["manipulability", "condition_number", "singular"] {
                    numbers(&r[key], &mut want);
                }
                numbers(
                    &Value::from(r["pose"]["matrix"].as_array().unwrap()[..3].to_vec()),
                    &mut want,
                );
            }
            let query = format!("{path}?frame={frame}");
            let r = app.post_bytes(&query, PACKED, PACKED, packed(&qs)).await;
            let got = unpack(&ok_bytes(r, PACKED).await);
            assert_eq!(got.len(), qs.len() * (6 * dof + 15), "{what}");
            assert_bits_eq(&got, &want, &what);
            if robot == "planar_2dof" {
                // Stretched out: the smallest singular value is exactly 0.
                let last = json["results"].as_array().unwrap().last().unwrap();
                assert!(last["condition_number"].is_null(), "{last}");
            }

            let pb_frame = if frame == "tool" {
                pb::JacobianFrame::Tool
            } else {
                pb::JacobianFrame::Base
            };
            let msg = pb::JacobianBatchRequest {
                robot: robot.into(),
                configurations: qs
                    .iter()
                    .map(|q| pb::JointConfiguration { joints: q.clone() })
                    .collect(),
                frame: pb_frame as i32,
                ..Default::default()
            };
            let rest_pb = ok_bytes(
                app.post_bytes(&path, PROTOBUF, PROTOBUF, msg.encode_to_vec())
                    .await,
                PROTOBUF,
            )
            .await;
            let grpc_answer = grpc.jacobian_batch(msg.clone()).await.unwrap().into_inner();
            assert!(
                rest_pb == grpc_answer.encode_to_vec(),
                "{what}: REST protobuf ≠ gRPC"
            );
            let r = app
                .post_bytes(&path, PROTOBUF, "application/json", msg.encode_to_vec())
                .await;
            assert!(ok_bytes(r, "application/json").await == json_text, "{what}");
        }
    }
}

#[tokio::test]
async fn ik_batch_takes_and_gives_the_grpc_messages() {
    let app = spawn_app().await;
    let mut grpc = app.grpc_client().await;
    let path = "/v1/robots/planar_2dof/ik/batch";
    let targets = [[0.5, 0.3, 0.0], [0.5, 0.32, 0.0], [0.9, 0.9, 0.0]];
    let body = json!({
        "targets": targets.iter().map(|p| json!({"position": p})).collect::<Vec<_>>(),
        "position_only": true, "angle_unit": "deg",
    });
    let json_text = ok_bytes(app.post(path, &body).await, "application/json").await;
    let msg = pb::InverseKinematicsBatchRequest {
        targets: targets
            .iter()
            .map(|p| pb::IkTarget {
                position: Some(pb::Vector3 {
                    x: p[0],
                    y: p[1],
                    z: p[2],
                }),
                ..Default::default()
            })
            .collect(),
        position_only: true,
        angle_unit: pb::AngleUnit::Deg as i32,
        ..Default::default()
    };
    let r = app
        .post_bytes(path, PROTOBUF, "application/json", msg.encode_to_vec())
        .await;
    assert!(
        ok_bytes(r, "application/json").await == json_text,
        "JSON answer to the message"
    );
    let rest_pb = ok_bytes(
        app.post_bytes(path, PROTOBUF, PROTOBUF, msg.encode_to_vec())
            .await,
        PROTOBUF,
    )
    .await;
    let grpc_answer = grpc
        .inverse_kinematics_batch(pb::InverseKinematicsBatchRequest {
            robot: "planar_2dof".into(),
            ..msg
        })
        .await
        .unwrap()
        .into_inner();
    assert!(
        rest_pb == grpc_answer.encode_to_vec(),
        "REST protobuf ≠ gRPC"
    );
    let decoded = pb::InverseKinematicsBatchResponse::decode(rest_pb.as_slice()).unwrap();
    let json: Value = serde_json::from_slice(&json_text).unwrap();
    for (got, want) in decoded
        .results
        .iter()
        .zip(json["results"].as_array().unwrap())
    {
        let mut joints = Vec::new();
        numbers(&want["joints"], &mut joints);
        assert_bits_eq(&got.joints, &joints, "IK joints");
        assert_eq!(got.converged, want["converged"]);
    }
    assert_eq!(decoded.results.len(), 3);
    assert!(!decoded.results[2].converged, "out of reach");
}
