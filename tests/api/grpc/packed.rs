//! `packed_configurations` of the gRPC batch requests (FK and Jacobian): the
//! same answers as the repeated `configurations`, byte for byte, over gRPC
//! and REST's `application/x-protobuf` body; the same limits; and errors
//! naming the packed field when it is what is wrong.

use kinserve::api::grpc::pb;
use kinserve_testkit::SplitMix64;
use prost::Message;
use tonic::Code;

use crate::helpers::*;

/// `n` configurations of `dof` joints, ±0.5 rad.
fn configurations(n: usize, dof: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = SplitMix64(seed);
    (0..n)
        .map(|_| (0..dof).map(|_| rng.range(-0.5, 0.5)).collect())
        .collect()
}

fn repeated(qs: &[Vec<f64>]) -> Vec<pb::JointConfiguration> {
    qs.iter()
        .map(|q| pb::JointConfiguration { joints: q.clone() })
        .collect()
}

fn packed(qs: &[Vec<f64>], joint_count: u32) -> Option<pb::PackedConfigurations> {
    Some(pb::PackedConfigurations {
        joint_count,
        values: qs.concat(),
    })
}

fn fk_batch(robot: &str, format: pb::PoseFormat) -> pb::ForwardKinematicsBatchRequest {
    pb::ForwardKinematicsBatchRequest {
        robot: robot.into(),
        options: Some(pb::FkOptions {
            pose_format: format as i32,
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// `options` with the limit check off (values of ±0.5 rad are outside some
/// limits, e.g. the Panda's fourth joint).
fn unchecked(options: Option<pb::FkOptions>) -> Option<pb::FkOptions> {
    Some(pb::FkOptions {
        check_limits: Some(false),
        ..options.unwrap_or_default()
    })
}

#[tokio::test]
async fn packed_configurations_answer_as_repeated_ones_byte_for_byte() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let formats = [
        pb::PoseFormat::Full,
        pb::PoseFormat::Matrix,
        pb::PoseFormat::Position,
    ];
    for (robot, dof) in [("puma560", 6), ("panda", 7), ("stanford", 6)] {
        let qs = configurations(37, dof, dof as u64);
        for format in formats {
            let mut one = fk_batch(robot, format);
            one.configurations = repeated(&qs);
            one.options = unchecked(one.options.take());
            let mut other = one.clone();
            other.configurations.clear();
            other.packed_configurations = packed(&qs, dof as u32);
            let a = c.forward_kinematics_batch(one).await.unwrap().into_inner();
            let b = c
                .forward_kinematics_batch(other.clone())
                .await
                .unwrap()
                .into_inner();
            let n = a.poses.len() + a.packed_poses.as_ref().map_or(0, |p| p.values.len());
            assert!(n >= qs.len(), "{robot} {format:?}: {n} numbers");
            assert_eq!(a.encode_to_vec(), b.encode_to_vec(), "{robot} {format:?}");

            // REST's protobuf body takes the same message (robot in the path).
            other.robot.clear();
            let path = format!("/v1/robots/{robot}/fk/batch");
            let protobuf = "application/x-protobuf";
            let r = app
                .post_bytes(&path, protobuf, protobuf, other.encode_to_vec())
                .await;
            assert_eq!(r.status(), 200, "{robot} {format:?}");
            assert_eq!(r.bytes().await.unwrap(), a.encode_to_vec(), "REST {robot}");
        }
        let jacobians = |packed_form: bool| pb::JacobianBatchRequest {
            robot: robot.into(),
            configurations: if packed_form { vec![] } else { repeated(&qs) },
            packed_configurations: if packed_form {
                packed(&qs, dof as u32)
            } else {
                None
            },
            frame: pb::JacobianFrame::Tool as i32,
            options: unchecked(None),
        };
        let a = c
            .jacobian_batch(jacobians(false))
            .await
            .unwrap()
            .into_inner();
        let b = c
            .jacobian_batch(jacobians(true))
            .await
            .unwrap()
            .into_inner();
        assert_eq!(a.results.len(), qs.len());
        assert_eq!(a.encode_to_vec(), b.encode_to_vec(), "{robot} Jacobians");
    }
}

#[tokio::test]
async fn packed_configurations_are_checked_and_errors_name_the_field() {
    let app = spawn_app_with(|c| c.max_batch = 6).await;
    let mut c = app.grpc_client().await;
    let ok = configurations(3, 6, 7);
    let send = |configurations: Vec<pb::JointConfiguration>,
                packed_configurations: Option<pb::PackedConfigurations>| {
        let mut req = fk_batch("puma560", pb::PoseFormat::Matrix);
        req.configurations = configurations;
        req.packed_configurations = packed_configurations;
        req
    };

    let both = refused(&mut c, send(repeated(&ok), packed(&ok, 6))).await;
    assert_eq!(both.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&both), ["packed_configurations"]);

    // 7 values per configuration for a 6-joint robot (42 = 6 × 7 values: a
    // whole number of either, so only joint_count can tell).
    let seven = configurations(6, 7, 8);
    let err = refused(&mut c, send(vec![], packed(&seven, 7))).await;
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["packed_configurations.joint_count"]);
    assert!(err.message().contains("6 joints"), "{}", err.message());
    let zero = Some(pb::PackedConfigurations {
        joint_count: 0,
        values: vec![0.1, 0.2, 0.3],
    });
    let err = refused(&mut c, send(vec![], zero)).await;
    assert_eq!(status_fields(&err), ["packed_configurations.joint_count"]);

    let mut ragged = packed(&ok, 6);
    if let Some(p) = ragged.as_mut() {
        p.values.pop();
    }
    let err = refused(&mut c, send(vec![], ragged)).await;
    assert_eq!(status_fields(&err), ["packed_configurations.values"]);
    assert!(err.message().contains("17 values"), "{}", err.message());

    // A value out of its limit is named as in the repeated field.
    let mut far = ok.clone();
    far[1][2] = 500.0;
    let err = refused(&mut c, send(vec![], packed(&far, 6))).await;
    assert_eq!(status_fields(&err), ["configurations[1][2]"]);
    let err = refused(&mut c, send(repeated(&far), None)).await;
    assert_eq!(status_fields(&err), ["configurations[1][2]"]);

    // The batch limit counts packed configurations: 6 pass, 7 do not, and
    // neither do 36 values declared as 36 one-joint configurations.
    let six = configurations(6, 6, 9);
    let answer = c
        .forward_kinematics_batch(send(vec![], packed(&six, 6)))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(answer.packed_poses.map(|p| p.values.len()), Some(6 * 12));
    for (qs, joint_count) in [(configurations(7, 6, 10), 6), (six.clone(), 1)] {
        let err = refused(&mut c, send(vec![], packed(&qs, joint_count))).await;
        assert_eq!(err.code(), Code::ResourceExhausted, "{err:?}");
        assert_eq!(status_fields(&err), ["configurations"]);
    }

    // An empty packed field is an empty batch.
    let empty = c
        .forward_kinematics_batch(send(vec![], packed(&[], 6)))
        .await
        .unwrap()
        .into_inner();
    assert!(empty.poses.is_empty() && empty.packed_poses.is_none_or(|p| p.values.is_empty()));

    // The Jacobian batch checks the same way.
    let err = c
        .jacobian_batch(pb::JacobianBatchRequest {
            robot: "puma560".into(),
            packed_configurations: packed(&seven, 7),
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(status_fields(&err), ["packed_configurations.joint_count"]);

    // REST's protobuf body: the same check, as a 422 naming the field.
    let mut msg = send(vec![], packed(&seven, 7));
    msg.robot.clear();
    let path = "/v1/robots/puma560/fk/batch";
    let r = app
        .post_bytes(path, "application/x-protobuf", "", msg.encode_to_vec())
        .await;
    let p = problem(r, 422).await;
    assert_eq!(fields(&p), ["packed_configurations.joint_count"]);
}

type Client = pb::kinematics_service_client::KinematicsServiceClient<tonic::transport::Channel>;

/// The status of a refused FK batch.
async fn refused(c: &mut Client, req: pb::ForwardKinematicsBatchRequest) -> tonic::Status {
    c.forward_kinematics_batch(req).await.unwrap_err()
}
