//! Many configurations in one FK stream message (`configurations`): the
//! reply equals `ForwardKinematicsBatch`'s answer byte for byte in every pose
//! format, single and multi messages interleave in order, refusals and bad
//! values are error replies naming the field (the stream goes on), the batch
//! limit, and the poses counted in metrics.

use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use prost::Message;
use tonic::Code;
use tonic::transport::Channel;

use crate::helpers::*;

/// Configurations as the batch messages carry them.
fn rows(configs: &[Vec<f64>]) -> Vec<pb::JointConfiguration> {
    configs
        .iter()
        .map(|joints| pb::JointConfiguration {
            joints: joints.clone(),
        })
        .collect()
}

/// A stream message with many configurations.
fn multi(
    id: u64,
    robot: &str,
    configs: &[Vec<f64>],
    options: Option<pb::FkOptions>,
) -> pb::StreamForwardKinematicsRequest {
    pb::StreamForwardKinematicsRequest {
        id,
        robot: robot.to_string(),
        configurations: rows(configs),
        options,
        ..Default::default()
    }
}

fn format_options(format: pb::PoseFormat, deg: bool) -> Option<pb::FkOptions> {
    let angle_unit = if deg {
        pb::AngleUnit::Deg
    } else {
        pb::AngleUnit::Rad
    };
    Some(pb::FkOptions {
        angle_unit: angle_unit as i32,
        pose_format: format as i32,
        ..Default::default()
    })
}

/// Sends `msgs` on one stream, half-closes and collects every reply.
async fn exchange(
    c: &mut KinematicsServiceClient<Channel>,
    msgs: &[pb::StreamForwardKinematicsRequest],
) -> Vec<pb::StreamForwardKinematicsResponse> {
    let (tx, mut rx) = open_stream(c, msgs.len().max(1)).await;
    for m in msgs {
        tx.send(m.clone()).await.unwrap();
    }
    drop(tx);
    let mut out = Vec::new();
    while let Some(m) = rx.message().await.expect("no stream error") {
        out.push(m);
    }
    assert_eq!(out.len(), msgs.len(), "one reply per message");
    out
}

/// PUMA configurations in degrees (the zero configuration included: its
/// negative zeros are compared too) and Panda configurations in radians.
fn puma_deg(n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|i| {
            let t = i as f64 * 3.7;
            vec![t, -t / 2.0, t / 3.0, 10.0 - t, t / 4.0, -t]
        })
        .collect()
}

fn panda_rad(n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|i| {
            let t = (i % 97) as f64 / 97.0;
            vec![t, -t, 0.0, -1.0 - t, 0.0, 1.0 + t, 0.0]
        })
        .collect()
}

#[tokio::test]
async fn a_multi_configuration_reply_equals_the_unary_batch_byte_for_byte() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let cases = [
        ("puma560", puma_deg(25), true),
        ("panda", panda_rad(40), false),
    ];
    let formats = [
        (pb::PoseFormat::Full, 0),
        (pb::PoseFormat::Matrix, 12),
        (pb::PoseFormat::Position, 3),
    ];
    let mut msgs = Vec::new();
    let mut expected = Vec::new();
    for (robot, configs, deg) in &cases {
        for (format, k) in formats {
            let options = format_options(format, *deg);
            let unary = c
                .forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
                    robot: robot.to_string(),
                    configurations: rows(configs),
                    options,
                    ..Default::default()
                })
                .await
                .unwrap()
                .into_inner();
            msgs.push(multi(msgs.len() as u64 + 100, robot, configs, options));
            expected.push((unary, configs.len(), k, format));
        }
    }
    let replies = exchange(&mut c, &msgs).await;
    for (i, (reply, (unary, n, k, format))) in replies.into_iter().zip(expected).enumerate() {
        let what = format!("message {i} ({format:?})");
        assert_eq!(reply.id, i as u64 + 100, "{what}");
        assert!(reply.result.is_none(), "{what}: no single pose");
        assert!(
            reply.frames.is_empty() && reply.packed_frames.is_none(),
            "{what}"
        );
        if k == 0 {
            assert_eq!(reply.poses.len(), n, "{what}");
            assert!(reply.packed_poses.is_none(), "{what}");
        } else {
            let packed = reply.packed_poses.as_ref().expect("packed_poses");
            assert_eq!(packed.format, format as i32, "{what}");
            assert_eq!(packed.values.len(), n * k, "{what}");
            assert!(reply.poses.is_empty(), "{what}");
        }
        let as_batch = pb::ForwardKinematicsBatchResponse {
            robot: unary.robot.clone(),
            length_unit: reply.length_unit,
            poses: reply.poses,
            packed_poses: reply.packed_poses.map(|p| *p),
        };
        assert_eq!(
            as_batch.encode_to_vec(),
            unary.encode_to_vec(),
            "{what}: the same bytes as ForwardKinematicsBatch"
        );
    }
}

#[tokio::test]
async fn single_and_multi_messages_interleave_in_order() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let q = panda_rad(5);
    let matrix = format_options(pb::PoseFormat::Matrix, false);
    let position = format_options(pb::PoseFormat::Position, false);
    let msgs = vec![
        stream_request(1, "panda", &q[0], None),
        multi(
            2,
            "panda",
            &[q[0].clone(), q[1].clone(), q[2].clone()],
            None,
        ),
        stream_request(3, "panda", &q[1], None),
        multi(4, "panda", &q[3..4], matrix),
        stream_request(5, "panda", &q[3], matrix),
        multi(6, "puma560", &puma_deg(2), deg()),
        multi(6, "panda", &q, position),
        stream_request(1, "panda", &q[4], position),
    ];
    let replies = exchange(&mut c, &msgs).await;
    let ids: Vec<u64> = replies.iter().map(|r| r.id).collect();
    assert_eq!(ids, [1, 2, 3, 4, 5, 6, 6, 1], "ids echoed in order");

    let single = |i: usize| match &replies[i].result {
        Some(StreamResult::Pose(p)) => p.clone(),
        other => panic!("reply {i} should be a pose: {other:?}"),
    };
    assert_eq!(replies[1].poses.len(), 3);
    assert_same_pose(&replies[1].poses[0], &single(0), "multi 0 vs single");
    assert_same_pose(&replies[1].poses[1], &single(2), "multi 1 vs single");
    for i in [0, 2, 4, 7] {
        assert!(replies[i].poses.is_empty() && replies[i].packed_poses.is_none());
    }

    let Some(StreamResult::PackedPose(one)) = &replies[4].result else {
        panic!("reply 4 should be a packed pose: {:?}", replies[4]);
    };
    let batch = replies[3].packed_poses.as_ref().expect("packed_poses");
    assert_eq!(batch.values.len(), 12);
    for (a, b) in batch.values.iter().zip(&one.values) {
        assert_close(*a, *b, 1e-12, "matrix of one configuration");
    }
    assert_eq!(replies[5].poses.len(), 2, "puma in degrees");
    let positions = replies[6].packed_poses.as_ref().expect("positions");
    assert_eq!(positions.values.len(), 15);
    let Some(StreamResult::PackedPose(last)) = &replies[7].result else {
        panic!("reply 7 should be a packed pose: {:?}", replies[7]);
    };
    for (a, b) in positions.values[12..].iter().zip(&last.values) {
        assert_close(*a, *b, 1e-12, "position of the last configuration");
    }
}

#[tokio::test]
async fn refusals_and_bad_values_are_error_replies_and_the_stream_goes_on() {
    let app = spawn_app_with(|c| c.max_batch = 4).await;
    let mut c = app.grpc_client().await;
    let ok = vec![0.0; 6];
    let puma = |id: u64, configs: &[Vec<f64>]| multi(id, "puma560", configs, deg());
    let with = |id: u64, f: &dyn Fn(&mut pb::StreamForwardKinematicsRequest)| {
        let mut m = puma(id, &[ok.clone(), ok.clone()]);
        f(&mut m);
        m
    };
    let msgs = vec![
        with(0, &|m| m.joints = vec![0.0; 6]),
        with(1, &|m| m.ik = Some(Box::default())),
        with(2, &|m| m.ik_path = Some(Default::default())),
        with(3, &|m| m.include_jacobian = true),
        with(4, &|m| m.include_link_transforms = true),
        with(5, &|m| {
            if let Some(o) = m.options.as_mut() {
                o.frames = Some(true);
            }
        }),
        puma(6, &[ok.clone(), vec![0.0, 0.0, 500.0, 0.0, 0.0, 0.0]]),
        puma(7, &[ok.clone(), ok.clone(), vec![0.0; 3]]),
        puma(8, &[ok.clone(), vec![0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]]),
        puma(9, &vec![ok.clone(); 5]),
        puma(10, &vec![ok.clone(); 4]),
        multi(11, "no_such_robot", std::slice::from_ref(&ok), None),
        stream_request(12, "puma560", &ok, None),
    ];
    let replies = exchange(&mut c, &msgs).await;
    let ids: Vec<u64> = replies.iter().map(|r| r.id).collect();
    assert_eq!(ids, (0..13).collect::<Vec<u64>>());
    let expect_error = |i: usize, code: Code, fields: &[&str]| {
        let Some(StreamResult::Error(e)) = &replies[i].result else {
            panic!("reply {i} should be an error: {:?}", replies[i]);
        };
        assert_eq!(e.code, code as i32, "reply {i}: {e:?}");
        assert!(!e.message.is_empty());
        assert_eq!(rpc_status_fields(e), fields, "reply {i}");
        assert!(replies[i].poses.is_empty() && replies[i].packed_poses.is_none());
    };
    expect_error(0, Code::InvalidArgument, &["configurations"]);
    expect_error(1, Code::InvalidArgument, &["configurations"]);
    expect_error(2, Code::InvalidArgument, &["configurations"]);
    expect_error(3, Code::InvalidArgument, &["include_jacobian"]);
    expect_error(4, Code::InvalidArgument, &["include_link_transforms"]);
    expect_error(5, Code::InvalidArgument, &["options.frames"]);
    expect_error(6, Code::InvalidArgument, &["configurations[1][2]"]);
    expect_error(7, Code::InvalidArgument, &["configurations[2]"]);
    expect_error(8, Code::InvalidArgument, &["configurations[1][1]"]);
    // One over the limit is RESOURCE_EXHAUSTED; exactly at it is answered.
    expect_error(9, Code::ResourceExhausted, &["configurations"]);
    assert_eq!(replies[10].poses.len(), 4, "{:?}", replies[10]);
    expect_error(11, Code::NotFound, &[]);
    assert!(
        matches!(replies[12].result, Some(StreamResult::Pose(_))),
        "the stream goes on: {:?}",
        replies[12]
    );
}

/// The value of the sample `name{labels}` in a Prometheus page.
fn sample(text: &str, name_and_labels: &str) -> Option<f64> {
    text.lines()
        .find_map(|l| l.strip_prefix(name_and_labels)?.strip_prefix(' '))
        .and_then(|v| v.trim().parse().ok())
}

#[tokio::test]
async fn every_pose_of_a_multi_message_is_counted() {
    // A built-in robot no other test computes, so the count is this test's.
    const SERIES: &str = r#"kinserve_poses_computed_total{robot="ur10e",protocol="grpc"}"#;
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let count = |text: String| sample(&text, SERIES).unwrap_or(0.0);
    let before = count(app.get("/metrics").await.text().await.unwrap());
    let configs: Vec<Vec<f64>> = (0..37).map(|i| vec![i as f64 / 50.0; 6]).collect();
    let replies = exchange(&mut c, &[multi(1, "ur10e", &configs, None)]).await;
    assert_eq!(replies[0].poses.len(), 37, "{:?}", replies[0].result);
    let after = count(app.get("/metrics").await.text().await.unwrap());
    assert_eq!(after - before, 37.0, "{SERIES}: {before} -> {after}");
}

#[tokio::test]
async fn packed_configurations_answer_as_repeated_ones_and_are_checked() {
    let app = spawn_app_with(|c| c.max_batch = 8).await;
    let mut c = app.grpc_client().await;
    let q = puma_deg(6);
    let matrix = format_options(pb::PoseFormat::Matrix, true);
    let packed = |id: u64, joint_count: u32, values: Vec<f64>| {
        let mut m = multi(id, "puma560", &[], matrix);
        m.packed_configurations = Some(Box::new(pb::PackedConfigurations {
            joint_count,
            values,
        }));
        m
    };
    // Both forms, 2 + 2 configurations (under the limit, which counts both).
    let mut both = packed(3, 6, q[..2].concat());
    both.configurations = rows(&q[..2]);
    let mut with_joints = packed(4, 6, q.concat());
    with_joints.joints = vec![0.0; 6];
    let mut far = q.clone();
    far[2][1] = 500.0;
    let msgs = vec![
        multi(0, "puma560", &q, matrix),
        packed(1, 6, q.concat()),
        packed(2, 7, q.concat()),
        both,
        with_joints,
        packed(5, 6, far.concat()),
        packed(6, 1, q.concat()),
        packed(7, 6, Vec::new()),
        packed(8, 6, q.concat()),
    ];
    let replies = exchange(&mut c, &msgs).await;
    assert_eq!(replies.len(), msgs.len());
    let body = |r: &pb::StreamForwardKinematicsResponse| {
        let mut r = r.clone();
        r.id = 0;
        r.encode_to_vec()
    };
    assert!(replies[0].packed_poses.is_some(), "{:?}", replies[0]);
    assert_eq!(body(&replies[1]), body(&replies[0]), "packed vs repeated");
    assert_eq!(body(&replies[8]), body(&replies[0]), "after the errors");
    let error = |i: usize| match &replies[i].result {
        Some(StreamResult::Error(e)) => (e.code, rpc_status_fields(e)),
        other => panic!("reply {i} should be an error: {other:?}"),
    };
    let invalid = Code::InvalidArgument as i32;
    assert_eq!(
        error(2),
        (
            invalid,
            vec!["packed_configurations.joint_count".to_string()]
        )
    );
    assert_eq!(
        error(3),
        (invalid, vec!["packed_configurations".to_string()])
    );
    assert_eq!(
        error(4),
        (invalid, vec!["packed_configurations".to_string()])
    );
    assert_eq!(
        error(5),
        (invalid, vec!["configurations[2][1]".to_string()])
    );
    // 36 values as 36 one-joint configurations: over the batch limit of 8.
    let exhausted = Code::ResourceExhausted as i32;
    assert_eq!(error(6), (exhausted, vec!["configurations".to_string()]));
    // Present but empty: FK of no configuration.
    assert!(replies[7].poses.is_empty(), "{:?}", replies[7]);
    assert!(!matches!(replies[7].result, Some(StreamResult::Error(_))));
}
