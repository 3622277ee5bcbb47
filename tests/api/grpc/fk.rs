//! gRPC FK RPCs: unary and batch forward kinematics, their options and bad
//! inputs, and the message size limit.

use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use prost::Message;
use tonic::Code;

use crate::helpers::grpc::assert_pose_eq;
use crate::helpers::*;
use kinserve_testkit::RobotExt;

// ---------------------------------------------------------------- FK RPCs

#[tokio::test]
async fn forward_kinematics_matches_the_library_with_default_options() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let puma = library_robot("puma560");
    let q = [0.1, -0.4, 0.3, 1.0, -0.5, 2.0];
    let r = fk(&mut c, fk_request("puma560", &q, None)).await.unwrap();
    assert_eq!(r.robot, "puma560");
    assert_eq!(r.length_unit, pb::LengthUnit::M as i32);
    assert!(r.frames.is_empty(), "absent options: no frames");
    assert_pose_eq(&r.pose.unwrap(), &puma.fk_unchecked(&q), 1e-12, "puma");

    // Degrees give the same pose.
    let q_deg: Vec<f64> = q.iter().map(|x| x.to_degrees()).collect();
    let r = fk(&mut c, fk_request("puma560", &q_deg, deg()))
        .await
        .unwrap();
    assert_pose_eq(&r.pose.unwrap(), &puma.fk_unchecked(&q), 1e-12, "deg");

    // Millimetre robot: positions in mm.
    let alpha = library_robot("alpha_ii");
    let q = [10.0, -20.0, 30.0, 40.0, 50.0];
    let r = fk(&mut c, fk_request("alpha_ii", &q, deg())).await.unwrap();
    assert_eq!(r.length_unit, pb::LengthUnit::Mm as i32);
    let q_rad: Vec<f64> = q.iter().map(|x: &f64| x.to_radians()).collect();
    assert_pose_eq(
        &r.pose.unwrap(),
        &alpha.fk_unchecked(&q_rad),
        1e-9,
        "alpha_ii",
    );
}

#[tokio::test]
async fn forward_kinematics_frames_and_limit_options() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let panda = library_robot("panda");
    let q = [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7];

    let r = fk(
        &mut c,
        fk_request(
            "panda",
            &q,
            Some(pb::FkOptions {
                frames: Some(true),
                ..Default::default()
            }),
        ),
    )
    .await
    .unwrap();
    // Base frame plus one per DH row (7 joints + the fixed flange row).
    assert_eq!(r.frames.len(), 9);
    let (tool, frames) = panda
        .fk_frames(&q, &kinserve::model::FkOptions::default())
        .unwrap();
    assert_pose_eq(r.pose.as_ref().unwrap(), &tool, 1e-12, "tool");
    for (i, (g, w)) in r.frames.iter().zip(&frames).enumerate() {
        assert_pose_eq(g, w, 1e-12, &format!("frame {i}"));
    }
    // No tool: the last frame is the tool pose.
    assert_same_pose(r.frames.last().unwrap(), r.pose.as_ref().unwrap(), "flange");

    // Joint 4 of the panda must be in [-3.0718, -0.0698]: 0 is out of limits.
    let out = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    for options in [None, Some(pb::FkOptions::default())] {
        let err = fk(&mut c, fk_request("panda", &out, options))
            .await
            .unwrap_err();
        assert_eq!(err.code(), Code::InvalidArgument, "{options:?}");
        assert_eq!(status_fields(&err), ["joints[3]"]);
    }
    let r = fk(
        &mut c,
        fk_request(
            "panda",
            &out,
            Some(pb::FkOptions {
                check_limits: Some(false),
                ..Default::default()
            }),
        ),
    )
    .await
    .unwrap();
    assert_pose_eq(&r.pose.unwrap(), &panda.fk_unchecked(&out), 1e-12, "skip");

    // An angle unit that is not in the enum.
    let err = fk(
        &mut c,
        fk_request(
            "panda",
            &q,
            Some(pb::FkOptions {
                angle_unit: 17,
                ..Default::default()
            }),
        ),
    )
    .await
    .unwrap_err();
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["options.angle_unit"]);
}

#[tokio::test]
async fn forward_kinematics_bad_inputs() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;

    let err = fk(&mut c, fk_request("puma560", &[0.0; 5], None))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["joints"]);

    let err = fk(&mut c, fk_request("puma560", &[], None))
        .await
        .unwrap_err();
    assert_eq!(status_fields(&err), ["joints"]);

    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let err = fk(
            &mut c,
            fk_request("puma560", &[0.0, 0.0, bad, 0.0, 0.0, 0.0], None),
        )
        .await
        .unwrap_err();
        assert_eq!(err.code(), Code::InvalidArgument, "{bad}");
        assert_eq!(status_fields(&err), ["joints[2]"], "{bad}");
    }
    // Non-finite values are rejected even with the limit check off.
    let err = fk(
        &mut c,
        fk_request(
            "puma560",
            &[f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0],
            Some(pb::FkOptions {
                check_limits: Some(false),
                ..Default::default()
            }),
        ),
    )
    .await
    .unwrap_err();
    assert_eq!(status_fields(&err), ["joints[0]"]);

    // Puma joint 2 is limited to ±110 deg.
    let err = fk(
        &mut c,
        fk_request("puma560", &[0.0, 120.0, 0.0, 0.0, 0.0, 0.0], deg()),
    )
    .await
    .unwrap_err();
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["joints[1]"]);

    // Stanford's prismatic joint 3 lives in [0.3048, 1.27] m.
    let err = fk(
        &mut c,
        fk_request("stanford", &[0.0, 0.0, 0.1, 0.0, 0.0, 0.0], None),
    )
    .await
    .unwrap_err();
    assert_eq!(status_fields(&err), ["joints[2]"]);

    let err = fk(&mut c, fk_request("nope", &[0.0], None))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::NotFound);

    // A long unknown name is not echoed back whole.
    let long = "x".repeat(10_000);
    let err = fk(&mut c, fk_request(&long, &[0.0], None))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::NotFound);
    assert!(err.message().len() < 500, "{}", err.message().len());
}

#[tokio::test]
async fn batch_poses_come_in_request_order_and_match_unary() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let configs: Vec<Vec<f64>> = (0..25)
        .map(|i| {
            // Within stanford's limits: ±170 deg, [0.3048, 1.27] m, ±90 deg for joint 5.
            let t = i as f64 * 6.0;
            vec![t, -t / 2.0, 0.4 + t / 200.0, t - 60.0, -t / 3.0, 150.0 - t]
        })
        .collect();
    // stanford: prismatic joint 3 in metres, revolute in degrees.
    let r = c
        .forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "stanford".into(),
            configurations: configs
                .iter()
                .map(|q| pb::JointConfiguration { joints: q.clone() })
                .collect(),
            options: deg(),
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(r.robot, "stanford");
    assert_eq!(r.length_unit, pb::LengthUnit::M as i32);
    assert_eq!(r.poses.len(), configs.len());
    for (i, (q, pose)) in configs.iter().zip(&r.poses).enumerate() {
        let one = fk(&mut c, fk_request("stanford", q, deg()))
            .await
            .unwrap()
            .pose
            .unwrap();
        assert_same_pose(pose, &one, &format!("configuration {i}"));
    }

    let empty = c
        .forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "stanford".into(),
            configurations: vec![],
            options: None,
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    assert!(empty.poses.is_empty());
}

#[tokio::test]
async fn batch_errors_name_the_configuration() {
    let app = spawn_app_with(|c| c.max_batch = 4).await;
    let mut c = app.grpc_client().await;
    let batch = |configs: Vec<Vec<f64>>| pb::ForwardKinematicsBatchRequest {
        robot: "puma560".into(),
        configurations: configs
            .into_iter()
            .map(|joints| pb::JointConfiguration { joints })
            .collect(),
        options: deg(),
        ..Default::default()
    };
    let ok = vec![0.0; 6];

    let err = c
        .forward_kinematics_batch(batch(vec![
            ok.clone(),
            vec![0.0, 0.0, 500.0, 0.0, 0.0, 0.0],
        ]))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["configurations[1][2]"]);

    let err = c
        .forward_kinematics_batch(batch(vec![ok.clone(), ok.clone(), vec![0.0; 3]]))
        .await
        .unwrap_err();
    assert_eq!(status_fields(&err), ["configurations[2]"]);

    let err = c
        .forward_kinematics_batch(batch(vec![
            ok.clone(),
            vec![0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0],
        ]))
        .await
        .unwrap_err();
    assert_eq!(status_fields(&err), ["configurations[1][1]"]);

    // Exactly at the limit is fine; one more is RESOURCE_EXHAUSTED.
    c.forward_kinematics_batch(batch(vec![ok.clone(); 4]))
        .await
        .unwrap();
    let err = c
        .forward_kinematics_batch(batch(vec![ok.clone(); 5]))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::ResourceExhausted, "{err:?}");
    assert_eq!(status_fields(&err), ["configurations"]);

    let mut unknown = batch(vec![ok.clone()]);
    unknown.robot = "nope".into();
    let err = c.forward_kinematics_batch(unknown).await.unwrap_err();
    assert_eq!(err.code(), Code::NotFound);
}

#[tokio::test]
async fn messages_over_the_size_limit_are_resource_exhausted() {
    let app = spawn_app_with(|c| c.max_batch_body_bytes = 64 << 10).await;
    let mut c = app.grpc_client().await;
    // 5,000 configurations of 6 doubles: ~265 KB, over the 64 KiB message limit
    // (and under the batch count limit).
    let big = pb::ForwardKinematicsBatchRequest {
        robot: "puma560".into(),
        configurations: vec![
            pb::JointConfiguration {
                joints: vec![0.0; 6]
            };
            5_000
        ],
        options: None,
        ..Default::default()
    };
    assert!(big.encoded_len() > 64 << 10);
    let err = c.forward_kinematics_batch(big).await.unwrap_err();
    assert_eq!(err.code(), Code::ResourceExhausted, "batch: {err:?}");

    let err = fk(&mut c, fk_request("puma560", &vec![0.0; 20_000], None))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::ResourceExhausted, "unary: {err:?}");

    // On the stream: an oversized message ends the stream with RESOURCE_EXHAUSTED.
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    tx.send(stream_request(1, "puma560", &[0.0; 6], None))
        .await
        .unwrap();
    let first = rx.message().await.unwrap().unwrap();
    assert_eq!(first.id, 1);
    assert!(matches!(first.result, Some(StreamResult::Pose(_))));
    tx.send(stream_request(2, "puma560", &vec![0.0; 20_000], None))
        .await
        .unwrap();
    let err = match rx.message().await {
        Ok(Some(m)) => panic!("no response expected for an oversized message: {m:?}"),
        Ok(None) => panic!("stream ended without a status"),
        Err(e) => e,
    };
    assert_eq!(err.code(), Code::ResourceExhausted, "stream: {err:?}");

    // The server is fine afterwards.
    fk(&mut c, fk_request("puma560", &[0.0; 6], None))
        .await
        .unwrap();
}
