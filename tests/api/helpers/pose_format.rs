//! Compact pose formats (`pose_format`) over every front door: one FK call
//! answered as plain numbers per pose, whatever the door and the format, so
//! that compact answers can be compared with full ones number for number.
//! Over REST and the WebSocket each format has its own fields ([`format_fields`]):
//! the answer must carry those of its format and none of the others'.

use futures_util::SinkExt;
use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;

use crate::helpers::*;

/// A front door that computes single FK.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Door {
    Rest,
    WebSocket,
    GrpcUnary,
    GrpcStream,
}

impl Door {
    pub(crate) const ALL: [Door; 4] = [
        Door::Rest,
        Door::WebSocket,
        Door::GrpcUnary,
        Door::GrpcStream,
    ];
}

/// The formats by their REST names.
pub(crate) const FORMATS: [&str; 3] = ["full", "matrix", "position"];

/// The gRPC enum value of a format named as over REST.
pub(crate) fn pb_format(name: &str) -> pb::PoseFormat {
    match name {
        "full" => pb::PoseFormat::Full,
        "matrix" => pb::PoseFormat::Matrix,
        "position" => pb::PoseFormat::Position,
        other => panic!("no format {other}"),
    }
}

/// Numbers per pose as [`Numbers`] holds them (`full`: the matrix's 16).
pub(crate) fn stride(format: &str) -> usize {
    match format {
        "full" => 16,
        "matrix" => 12,
        "position" => 3,
        other => panic!("no format {other}"),
    }
}

/// What a compact format keeps of a full pose's 16 matrix values.
pub(crate) fn compact_of(full16: &[f64], format: &str) -> Vec<f64> {
    assert_eq!(full16.len(), 16, "a full matrix");
    match format {
        "full" => full16.to_vec(),
        "matrix" => full16[..12].to_vec(),
        "position" => vec![full16[3], full16[7], full16[11]],
        other => panic!("no format {other}"),
    }
}

/// Bit-for-bit equality of two lists of numbers.
pub(crate) fn assert_bits_eq(got: &[f64], want: &[f64], what: &str) {
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(got), bits(want), "{what}: {got:?} != {want:?}");
}

/// One FK answer as numbers: the tool pose and, when asked for, every frame.
#[derive(Clone, Debug)]
pub(crate) struct Numbers {
    pub(crate) pose: Vec<f64>,
    pub(crate) frames: Option<Vec<Vec<f64>>>,
}

/// The JSON fields of a format: (single pose, frames, batch poses).
pub(crate) fn format_fields(format: &str) -> (&'static str, &'static str, &'static str) {
    match format {
        "full" => ("pose", "frames", "poses"),
        "matrix" => ("matrix", "frame_matrices", "matrices"),
        "position" => ("position", "frame_positions", "positions"),
        other => panic!("no format {other}"),
    }
}

/// Asserts that `v` has none of the pose fields of the formats other than
/// `format`.
pub(crate) fn assert_only_fields_of(v: &Value, format: &str) {
    for other in FORMATS.into_iter().filter(|f| *f != format) {
        let (a, b, c) = format_fields(other);
        for name in [a, b, c] {
            assert!(v.get(name).is_none(), "{format}: no `{name}` field: {v}");
        }
    }
}

/// A JSON pose as numbers: an object's matrix (`full`) or the array itself.
pub(crate) fn json_numbers(pose: &Value, format: &str) -> Vec<f64> {
    if format == "full" {
        assert!(pose.is_object(), "a full pose is an object: {pose}");
        return matrix16(pose);
    }
    let a = pose.as_array().expect("a compact pose is an array");
    assert_eq!(a.len(), stride(format), "{format}: numbers per pose");
    a.iter().map(|x| x.as_f64().expect("a number")).collect()
}

/// A JSON list of poses as numbers.
pub(crate) fn json_list(poses: &Value, format: &str) -> Vec<Vec<f64>> {
    poses
        .as_array()
        .expect("an array of poses")
        .iter()
        .map(|p| json_numbers(p, format))
        .collect()
}

/// An FK answer (REST or WebSocket) as numbers, read from the fields of
/// `format` (and only there).
fn json_answer(v: &Value, format: &str) -> Numbers {
    assert_only_fields_of(v, format);
    let (pose, frames, _) = format_fields(format);
    Numbers {
        pose: json_numbers(&v[pose], format),
        frames: v.get(frames).map(|f| json_list(f, format)),
    }
}

/// Packed poses cut into poses, checking the format they say they are in.
pub(crate) fn unpack(p: &pb::PackedPoses, format: &str) -> Vec<Vec<f64>> {
    assert_eq!(p.format, pb_format(format) as i32, "packed format");
    let k = stride(format);
    assert_eq!(p.values.len() % k, 0, "{format}: whole poses");
    p.values.chunks(k).map(<[f64]>::to_vec).collect()
}

fn pb_answer(
    pose: Option<&pb::Pose>,
    frames: &[pb::Pose],
    packed_pose: Option<&pb::PackedPoses>,
    packed_frames: Option<&pb::PackedPoses>,
    format: &str,
    with_frames: bool,
) -> Numbers {
    if format == "full" {
        assert!(
            packed_pose.is_none() && packed_frames.is_none(),
            "full: no packed poses"
        );
        return Numbers {
            pose: pose.expect("a Pose").matrix.clone(),
            frames: with_frames.then(|| frames.iter().map(|p| p.matrix.clone()).collect()),
        };
    }
    assert!(
        pose.is_none() && frames.is_empty(),
        "{format}: no Pose messages"
    );
    let single = unpack(packed_pose.expect("packed_pose"), format);
    assert_eq!(single.len(), 1, "one tool pose");
    Numbers {
        pose: single.into_iter().next().unwrap(),
        frames: with_frames.then(|| unpack(packed_frames.expect("packed_frames"), format)),
    }
}

/// FK options asking for `format` (and frames).
pub(crate) fn format_options(format: &str, frames: bool) -> Option<pb::FkOptions> {
    Some(pb::FkOptions {
        frames: Some(frames),
        pose_format: pb_format(format) as i32,
        ..Default::default()
    })
}

/// One FK call on `door` in `format`; panics on an error answer.
pub(crate) async fn fk_numbers(
    app: &TestApp,
    door: Door,
    robot: &str,
    joints: &[f64],
    frames: bool,
    format: &str,
) -> Numbers {
    let body = json!({"joints": joints, "frames": frames, "pose_format": format});
    match door {
        Door::Rest => {
            let v = fk_ok(app, robot, body).await;
            json_answer(&v, format)
        }
        Door::WebSocket => {
            let mut ws = open_ws(app, robot).await;
            let mut msg = body;
            msg["id"] = json!(7);
            ws.send(Message::Text(msg.to_string().into()))
                .await
                .unwrap();
            let reply = next_text(&mut ws).await.expect("a reply");
            assert!(reply.get("error").is_none(), "{reply}");
            assert_eq!(reply["id"], 7);
            json_answer(&reply, format)
        }
        Door::GrpcUnary => {
            let mut c = app.grpc_client().await;
            let r = fk(
                &mut c,
                fk_request(robot, joints, format_options(format, frames)),
            )
            .await
            .expect("FK answers");
            pb_answer(
                r.pose.as_ref(),
                &r.frames,
                r.packed_pose.as_ref(),
                r.packed_frames.as_ref(),
                format,
                frames,
            )
        }
        Door::GrpcStream => {
            let m = stream_once(app, robot, joints, format_options(format, frames)).await;
            let (pose, packed) = match &m.result {
                Some(StreamResult::Pose(p)) => (Some(&**p), None),
                Some(StreamResult::PackedPose(p)) => (None, Some(p)),
                other => panic!("stream answer {other:?}"),
            };
            pb_answer(
                pose,
                &m.frames,
                packed,
                m.packed_frames.as_deref(),
                format,
                frames,
            )
        }
    }
}

/// One message on a fresh FK stream and its answer.
pub(crate) async fn stream_once(
    app: &TestApp,
    robot: &str,
    joints: &[f64],
    options: Option<pb::FkOptions>,
) -> pb::StreamForwardKinematicsResponse {
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 1).await;
    tx.send(stream_request(3, robot, joints, options))
        .await
        .unwrap();
    let m = rx
        .message()
        .await
        .expect("no stream error")
        .expect("a reply");
    assert_eq!(m.id, 3);
    m
}
