//! gRPC: request builders, protobuf models, status details and pose checks.

use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tonic::Status;
use tonic::transport::Channel;
use tonic_types::{RpcStatusExt, StatusExt};

use crate::helpers::*;

/// Field paths of the `google.rpc.BadRequest` detail of a status (empty if none).
pub(crate) fn status_fields(status: &Status) -> Vec<String> {
    status
        .get_details_bad_request()
        .map(|b| b.field_violations.into_iter().map(|v| v.field).collect())
        .unwrap_or_default()
}

/// Field paths of the `google.rpc.BadRequest` detail of a stream error.
pub(crate) fn rpc_status_fields(status: &tonic_types::Status) -> Vec<String> {
    status
        .get_details_bad_request()
        .map(|b| b.field_violations.into_iter().map(|v| v.field).collect())
        .unwrap_or_default()
}

/// The problem kind a gRPC error names: the `google.rpc.ErrorInfo` reason
/// (domain `kinserve`) in REST's spelling (`INVALID_INPUT` -> `invalid-input`);
/// empty when the status carries none.
pub(crate) fn status_kind(status: &Status) -> String {
    status
        .get_details_error_info()
        .filter(|i| i.domain == "kinserve")
        .map(|i| i.reason.to_ascii_lowercase().replace('_', "-"))
        .unwrap_or_default()
}

/// [`status_kind`] of a stream error.
pub(crate) fn rpc_status_kind(status: &tonic_types::Status) -> String {
    status
        .get_details_error_info()
        .filter(|i| i.domain == "kinserve")
        .map(|i| i.reason.to_ascii_lowercase().replace('_', "-"))
        .unwrap_or_default()
}

/// A unary FK request.
pub(crate) fn fk_request(
    robot: &str,
    joints: &[f64],
    options: Option<pb::FkOptions>,
) -> pb::ForwardKinematicsRequest {
    pb::ForwardKinematicsRequest {
        robot: robot.to_string(),
        joints: joints.to_vec(),
        options,
    }
}

/// FK options in degrees.
pub(crate) fn deg() -> Option<pb::FkOptions> {
    Some(pb::FkOptions {
        angle_unit: pb::AngleUnit::Deg as i32,
        ..Default::default()
    })
}

/// A stream request.
pub(crate) fn stream_request(
    id: u64,
    robot: &str,
    joints: &[f64],
    options: Option<pb::FkOptions>,
) -> pb::StreamForwardKinematicsRequest {
    pb::StreamForwardKinematicsRequest {
        id,
        robot: robot.to_string(),
        joints: joints.to_vec(),
        options,
        ..Default::default()
    }
}

/// The 2-DoF planar arm of `helpers::planar_model`, as a protobuf message.
pub(crate) fn planar_pb(name: &str) -> pb::Robot {
    pb::Robot {
        name: name.to_string(),
        convention: pb::Convention::Standard as i32,
        angle_unit: pb::AngleUnit::Deg as i32,
        length_unit: pb::LengthUnit::M as i32,
        links: vec![
            pb::Link {
                joint: pb::JointType::Revolute as i32,
                a: Some(0.5),
                limits: Some(pb::Limits {
                    lo: -170.0,
                    hi: 170.0,
                }),
                alpha: Some(0.0),
                d: Some(0.0),
                theta: Some(0.0),
                ..Default::default()
            },
            pb::Link {
                joint: pb::JointType::Revolute as i32,
                a: Some(0.3),
                alpha: Some(0.0),
                d: Some(0.0),
                theta: Some(0.0),
                ..Default::default()
            },
        ],
        ..Default::default()
    }
}

/// A richer model: names, description, base (rpy), tool (quaternion), a prismatic
/// joint and a fixed row, in millimetres and degrees.
pub(crate) fn rich_pb(name: &str) -> pb::Robot {
    pb::Robot {
        name: name.to_string(),
        description: Some("test arm".into()),
        source: Some("tests/api/grpc.rs".into()),
        convention: pb::Convention::Standard as i32,
        angle_unit: pb::AngleUnit::Deg as i32,
        length_unit: pb::LengthUnit::Mm as i32,
        base: Some(pb::FixedTransform {
            translation: Some(pb::Vector3 {
                x: 10.0,
                y: -20.0,
                z: 300.0,
            }),
            rotation: Some(pb::fixed_transform::Rotation::Rpy(pb::Rpy {
                roll: 0.0,
                pitch: 0.0,
                yaw: 30.0,
            })),
        }),
        tool: Some(pb::FixedTransform {
            translation: Some(pb::Vector3 {
                x: 0.0,
                y: 0.0,
                z: 50.0,
            }),
            rotation: Some(pb::fixed_transform::Rotation::Quaternion(pb::Quaternion {
                w: 0.9238795325112867,
                x: 0.0,
                y: 0.0,
                z: 0.3826834323650898,
            })),
        }),
        links: vec![
            pb::Link {
                name: Some("waist".into()),
                joint: pb::JointType::Revolute as i32,
                d: Some(200.0),
                alpha: Some(-90.0),
                limits: Some(pb::Limits {
                    lo: -180.0,
                    hi: 180.0,
                }),
                a: Some(0.0),
                theta: Some(0.0),
            },
            pb::Link {
                name: Some("slide".into()),
                joint: pb::JointType::Prismatic as i32,
                theta: Some(-90.0),
                a: Some(20.0),
                limits: Some(pb::Limits { lo: 0.0, hi: 400.0 }),
                alpha: Some(0.0),
                d: Some(0.0),
            },
            pb::Link {
                name: Some("wrist".into()),
                joint: pb::JointType::Revolute as i32,
                a: Some(100.0),
                alpha: Some(90.0),
                d: Some(0.0),
                theta: Some(0.0),
                ..Default::default()
            },
            pb::Link {
                name: Some("flange".into()),
                joint: pb::JointType::Fixed as i32,
                d: Some(30.0),
                a: Some(0.0),
                alpha: Some(0.0),
                theta: Some(0.0),
                ..Default::default()
            },
        ],
    }
}

/// A plain channel to the gRPC listener (for the health and reflection clients).
pub(crate) async fn channel(app: &TestApp) -> Channel {
    Channel::from_shared(app.grpc.clone())
        .expect("valid uri")
        .connect()
        .await
        .expect("grpc connects")
}

pub(crate) fn with_token<T>(msg: T, token: &str) -> tonic::Request<T> {
    let mut req = tonic::Request::new(msg);
    req.metadata_mut()
        .insert("authorization", token.parse().expect("ascii metadata"));
    req
}

pub(crate) fn library_robot(name: &str) -> kinserve::model::Robot {
    kinserve::model::load_robot_file(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("robots/{name}.json")),
    )
    .expect("built-in robot file loads")
}

/// Asserts a protobuf pose equals a library transform to `tol`.
pub(crate) fn assert_pose_eq(
    got: &pb::Pose,
    want: &kinserve::kinematics::Transform,
    tol: f64,
    what: &str,
) {
    let m: Vec<f64> = want.matrix().iter().flatten().copied().collect();
    assert_eq!(got.matrix.len(), 16, "{what}: 16 matrix values");
    for (k, (a, b)) in got.matrix.iter().zip(&m).enumerate() {
        assert_close(*a, *b, tol, &format!("{what}: matrix[{k}]"));
    }
    let p = got.position.as_ref().expect("position");
    let wp = want.position();
    for (a, b) in [p.x, p.y, p.z].iter().zip(wp) {
        assert_close(*a, b, tol, &format!("{what}: position"));
    }
    let q = got.quaternion.as_ref().expect("quaternion");
    let wq = want.quaternion();
    for (a, b) in [q.w, q.x, q.y, q.z].iter().zip(wq) {
        assert_close(*a, b, tol, &format!("{what}: quaternion"));
    }
    let r = got.rpy.as_ref().expect("rpy");
    let wr = want.rpy();
    for (a, b) in [r.roll, r.pitch, r.yaw].iter().zip(wr) {
        assert_close(*a, b, tol, &format!("{what}: rpy"));
    }
}

pub(crate) fn assert_same_pose(a: &pb::Pose, b: &pb::Pose, what: &str) {
    assert_eq!(a.matrix.len(), 16, "{what}");
    for (x, y) in a.matrix.iter().zip(&b.matrix) {
        assert_close(*x, *y, 1e-12, what);
    }
    let p = |x: &pb::Pose| {
        let v = x.position.expect("position");
        [v.x, v.y, v.z]
    };
    let q = |x: &pb::Pose| {
        let v = x.quaternion.expect("quaternion");
        [v.w, v.x, v.y, v.z]
    };
    let r = |x: &pb::Pose| {
        let v = x.rpy.expect("rpy");
        [v.roll, v.pitch, v.yaw]
    };
    for (x, y) in p(a).iter().zip(p(b)) {
        assert_close(*x, y, 1e-12, &format!("{what}: position"));
    }
    for (x, y) in q(a).iter().zip(q(b)) {
        assert_close(*x, y, 1e-12, &format!("{what}: orientation"));
    }
    for (x, y) in r(a).iter().zip(r(b)) {
        assert_close(*x, y, 1e-12, &format!("{what}: rpy"));
    }
}

pub(crate) async fn fk(
    client: &mut KinematicsServiceClient<Channel>,
    req: pb::ForwardKinematicsRequest,
) -> Result<pb::ForwardKinematicsResponse, Status> {
    client.forward_kinematics(req).await.map(|r| r.into_inner())
}

/// Opens an FK stream fed by a channel of `capacity` requests.
pub(crate) async fn open_stream(
    client: &mut KinematicsServiceClient<Channel>,
    capacity: usize,
) -> (
    mpsc::Sender<pb::StreamForwardKinematicsRequest>,
    tonic::Streaming<pb::StreamForwardKinematicsResponse>,
) {
    let (tx, rx) = mpsc::channel(capacity);
    let resp = client
        .stream_forward_kinematics(ReceiverStream::new(rx))
        .await
        .expect("stream opens");
    (tx, resp.into_inner())
}
