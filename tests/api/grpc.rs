//! gRPC contract tests: a tonic client against the real server on port 0.
//!
//! Every RPC of `kinematics.v1.KinematicsService` with its success path and every
//! status code the issue names, health, reflection (v1 and v1alpha), the
//! bidirectional stream (invalid message in the middle, slow reader, cancel,
//! shutdown) and the registry shared with REST.

use std::collections::BTreeSet;

use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use prost::Message;
use serde_json::json;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tonic::transport::Channel;
use tonic::{Code, Status};
use tonic_types::{RpcStatusExt, StatusExt};

use crate::helpers::*;

// ---------------------------------------------------------------- helpers

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
fn deg() -> Option<pb::FkOptions> {
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
    }
}

/// The 2-DoF planar arm of `helpers::planar_model`, as a protobuf message.
fn planar_pb(name: &str) -> pb::Robot {
    pb::Robot {
        name: name.to_string(),
        convention: pb::Convention::Standard as i32,
        angle_unit: pb::AngleUnit::Deg as i32,
        length_unit: pb::LengthUnit::M as i32,
        links: vec![
            pb::Link {
                joint: pb::JointType::Revolute as i32,
                a: 0.5,
                limits: Some(pb::Limits {
                    lo: -170.0,
                    hi: 170.0,
                }),
                ..Default::default()
            },
            pb::Link {
                joint: pb::JointType::Revolute as i32,
                a: 0.3,
                ..Default::default()
            },
        ],
        ..Default::default()
    }
}

/// A richer model: names, description, base (rpy), tool (quaternion), a prismatic
/// joint and a fixed row, in millimetres and degrees.
fn rich_pb(name: &str) -> pb::Robot {
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
                d: 200.0,
                alpha: -90.0,
                limits: Some(pb::Limits {
                    lo: -180.0,
                    hi: 180.0,
                }),
                ..Default::default()
            },
            pb::Link {
                name: Some("slide".into()),
                joint: pb::JointType::Prismatic as i32,
                theta: -90.0,
                a: 20.0,
                limits: Some(pb::Limits { lo: 0.0, hi: 400.0 }),
                ..Default::default()
            },
            pb::Link {
                name: Some("wrist".into()),
                joint: pb::JointType::Revolute as i32,
                a: 100.0,
                alpha: 90.0,
                ..Default::default()
            },
            pb::Link {
                name: Some("flange".into()),
                joint: pb::JointType::Fixed as i32,
                d: 30.0,
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

fn with_token<T>(msg: T, token: &str) -> tonic::Request<T> {
    let mut req = tonic::Request::new(msg);
    req.metadata_mut()
        .insert("authorization", token.parse().expect("ascii metadata"));
    req
}

fn library_robot(name: &str) -> kinserve::model::Robot {
    kinserve::model::load_robot_file(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("robots/{name}.json")),
    )
    .expect("built-in robot file loads")
}

/// Asserts a protobuf pose equals a library transform to `tol`.
fn assert_pose_eq(got: &pb::Pose, want: &kinserve::kinematics::Transform, tol: f64, what: &str) {
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
    let q = got.orientation.as_ref().expect("orientation");
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

fn assert_same_pose(a: &pb::Pose, b: &pb::Pose, what: &str) {
    assert_eq!(a.matrix.len(), 16, "{what}");
    for (x, y) in a.matrix.iter().zip(&b.matrix) {
        assert_close(*x, *y, 1e-12, what);
    }
    let p = |x: &pb::Pose| {
        let v = x.position.expect("position");
        [v.x, v.y, v.z]
    };
    let q = |x: &pb::Pose| {
        let v = x.orientation.expect("orientation");
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

async fn fk(
    client: &mut KinematicsServiceClient<Channel>,
    req: pb::ForwardKinematicsRequest,
) -> Result<pb::ForwardKinematicsResponse, Status> {
    client.forward_kinematics(req).await.map(|r| r.into_inner())
}

/// Opens an FK stream fed by a channel of `capacity` requests.
async fn open_stream(
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

// ---------------------------------------------------------------- registry RPCs

#[tokio::test]
async fn list_robots_is_sorted_and_describes_builtins() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let robots = c
        .list_robots(pb::ListRobotsRequest {})
        .await
        .unwrap()
        .into_inner()
        .robots;
    let names: Vec<&str> = robots.iter().map(|r| r.name.as_str()).collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(names, sorted, "sorted by name");
    let find = |n: &str| robots.iter().find(|r| r.name == n).expect(n).clone();
    let puma = find("puma560");
    assert_eq!(puma.dof, 6);
    assert_eq!(puma.convention, pb::Convention::Standard as i32);
    assert_eq!(puma.length_unit, pb::LengthUnit::M as i32);
    assert_eq!(puma.source, pb::RobotSource::Builtin as i32);
    let panda = find("panda");
    assert_eq!(panda.dof, 7, "the fixed flange row is not a joint");
    assert_eq!(panda.convention, pb::Convention::Modified as i32);
    let alpha = find("alpha_ii");
    assert_eq!(alpha.dof, 5);
    assert_eq!(alpha.length_unit, pb::LengthUnit::Mm as i32);

    // The same list as REST.
    let rest: serde_json::Value = app.get("/v1/robots").await.json().await.unwrap();
    let rest_names: Vec<&str> = rest["robots"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, rest_names);
}

#[tokio::test]
async fn get_robot_returns_the_model_and_unknown_is_not_found() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let r = c
        .get_robot(pb::GetRobotRequest {
            name: "stanford".into(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(r.source, pb::RobotSource::Builtin as i32);
    let robot = r.robot.unwrap();
    assert_eq!(robot.name, "stanford");
    assert_eq!(robot.convention, pb::Convention::Standard as i32);
    assert_eq!(robot.angle_unit, pb::AngleUnit::Deg as i32);
    assert_eq!(robot.links.len(), 6);
    assert_eq!(robot.links[2].joint, pb::JointType::Prismatic as i32);
    assert_eq!(robot.links[2].theta, -90.0);
    assert_eq!(
        robot.links[2].limits,
        Some(pb::Limits {
            lo: 0.3048,
            hi: 1.27
        })
    );
    assert_eq!(robot.links[2].name.as_deref(), Some("j3_prismatic"));

    let err = c
        .get_robot(pb::GetRobotRequest {
            name: "no_such_robot".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::NotFound, "{err:?}");
}

#[tokio::test]
async fn register_replace_get_fk_and_delete_a_robot() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;

    let r = c
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(planar_pb("arm")),
            replace: false,
        })
        .await
        .unwrap()
        .into_inner();
    assert!(r.created);
    assert_eq!(r.robot.as_ref().unwrap().name, "arm");

    // Taken without replace: ALREADY_EXISTS.
    let err = c
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(planar_pb("arm")),
            replace: false,
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::AlreadyExists, "{err:?}");

    // With replace: replaced (created = false), and the new table is used.
    let mut longer = planar_pb("arm");
    longer.links[0].a = 1.0;
    let r = c
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(longer),
            replace: true,
        })
        .await
        .unwrap()
        .into_inner();
    assert!(!r.created);

    let got = c
        .get_robot(pb::GetRobotRequest { name: "arm".into() })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(got.source, pb::RobotSource::Registered as i32);
    assert_eq!(got.robot.unwrap().links[0].a, 1.0);

    let list = c
        .list_robots(pb::ListRobotsRequest {})
        .await
        .unwrap()
        .into_inner();
    let arm = list.robots.iter().find(|r| r.name == "arm").unwrap();
    assert_eq!(arm.source, pb::RobotSource::Registered as i32);
    assert_eq!(arm.dof, 2);

    // Both joints at 0 (model angle unit deg, request in rad): x = 1.0 + 0.3.
    let pose = fk(&mut c, fk_request("arm", &[0.0, 0.0], None))
        .await
        .unwrap()
        .pose
        .unwrap();
    assert_close(pose.position.unwrap().x, 1.3, 1e-12, "x");

    // Replace with replace=true creates when absent.
    let r = c
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(planar_pb("arm2")),
            replace: true,
        })
        .await
        .unwrap()
        .into_inner();
    assert!(r.created, "replace of an absent robot creates it");

    c.delete_robot(pb::DeleteRobotRequest { name: "arm".into() })
        .await
        .unwrap();
    let err = c
        .get_robot(pb::GetRobotRequest { name: "arm".into() })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::NotFound);
    let err = fk(&mut c, fk_request("arm", &[0.0, 0.0], None))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::NotFound);
    let err = c
        .delete_robot(pb::DeleteRobotRequest { name: "arm".into() })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::NotFound, "second delete: {err:?}");
}

#[tokio::test]
async fn builtins_are_read_only_failed_precondition() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let err = c
        .delete_robot(pb::DeleteRobotRequest {
            name: "puma560".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::FailedPrecondition, "{err:?}");
    for replace in [true, false] {
        let err = c
            .register_robot(pb::RegisterRobotRequest {
                robot: Some(planar_pb("puma560")),
                replace,
            })
            .await
            .unwrap_err();
        assert_eq!(
            err.code(),
            Code::FailedPrecondition,
            "replace={replace}: {err:?}"
        );
    }
    // Still the built-in.
    let r = c
        .get_robot(pb::GetRobotRequest {
            name: "puma560".into(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(r.robot.unwrap().links.len(), 6);
}

#[tokio::test]
async fn invalid_models_are_invalid_argument_with_field_paths() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let mut register = async |robot: Option<pb::Robot>| {
        c.register_robot(pb::RegisterRobotRequest {
            robot,
            replace: false,
        })
        .await
        .unwrap_err()
    };

    let err = register(None).await;
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["robot"]);

    let mut m = planar_pb("bad");
    m.convention = pb::Convention::Unspecified as i32;
    let err = register(Some(m)).await;
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["convention"]);

    let mut m = planar_pb("bad");
    m.links[1].joint = pb::JointType::Unspecified as i32;
    let err = register(Some(m)).await;
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["links[1].joint"]);

    let mut m = planar_pb("bad");
    m.links[1].joint = 42; // not a JointType
    let err = register(Some(m)).await;
    assert_eq!(status_fields(&err), ["links[1].joint"]);

    let mut m = planar_pb("bad");
    m.base = Some(pb::FixedTransform {
        translation: None,
        rotation: Some(pb::fixed_transform::Rotation::Matrix(pb::Matrix4 {
            values: vec![1.0, 0.0, 0.0],
        })),
    });
    let err = register(Some(m)).await;
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["base.matrix"]);

    let err = register(Some(planar_pb("Bad Name!"))).await;
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["name"]);

    let mut m = planar_pb("bad");
    m.links[0].alpha = f64::NAN;
    let err = register(Some(m)).await;
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["links[0].alpha"]);

    let mut m = planar_pb("bad");
    m.links.clear();
    let err = register(Some(m)).await;
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&err), ["links"]);

    // Nothing was stored.
    let list = c
        .list_robots(pb::ListRobotsRequest {})
        .await
        .unwrap()
        .into_inner();
    assert!(list.robots.iter().all(|r| r.name != "bad"));
}

#[tokio::test]
async fn register_and_delete_need_the_bearer_token_when_one_is_set() {
    let app = spawn_app_with(|c| c.api_token = Some("s3cret".into())).await;
    let mut c = app.grpc_client().await;
    let reg = || pb::RegisterRobotRequest {
        robot: Some(planar_pb("guarded")),
        replace: false,
    };

    let err = c.register_robot(reg()).await.unwrap_err();
    assert_eq!(err.code(), Code::Unauthenticated, "no token: {err:?}");
    for bad in ["Bearer wrong", "Basic s3cret", "s3cret", "Bearer s3cret2"] {
        let err = c.register_robot(with_token(reg(), bad)).await.unwrap_err();
        assert_eq!(err.code(), Code::Unauthenticated, "{bad}: {err:?}");
    }
    // Unauthenticated beats validation: an invalid model without a token is still 401-like.
    let err = c
        .register_robot(pb::RegisterRobotRequest {
            robot: None,
            replace: false,
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::Unauthenticated);

    let ok = c
        .register_robot(with_token(reg(), "Bearer s3cret"))
        .await
        .unwrap()
        .into_inner();
    assert!(ok.created);

    // Reads need no token.
    c.get_robot(pb::GetRobotRequest {
        name: "guarded".into(),
    })
    .await
    .unwrap();
    c.list_robots(pb::ListRobotsRequest {}).await.unwrap();
    fk(&mut c, fk_request("guarded", &[0.0, 0.0], None))
        .await
        .unwrap();

    let del = || pb::DeleteRobotRequest {
        name: "guarded".into(),
    };
    let err = c.delete_robot(del()).await.unwrap_err();
    assert_eq!(err.code(), Code::Unauthenticated);
    let err = c
        .delete_robot(with_token(del(), "Bearer nope"))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::Unauthenticated);
    // The scheme is case-insensitive.
    c.delete_robot(with_token(del(), "bearer s3cret"))
        .await
        .unwrap();
}

#[tokio::test]
async fn without_a_token_register_and_delete_are_open() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    // Any (or no) authorization metadata is accepted.
    c.register_robot(with_token(
        pb::RegisterRobotRequest {
            robot: Some(planar_pb("open")),
            replace: false,
        },
        "Bearer whatever",
    ))
    .await
    .unwrap();
    c.delete_robot(pb::DeleteRobotRequest {
        name: "open".into(),
    })
    .await
    .unwrap();
}

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
                include_frames: true,
                ..Default::default()
            }),
        ),
    )
    .await
    .unwrap();
    // Base frame plus one per DH row (7 joints + the fixed flange row).
    assert_eq!(r.frames.len(), 9);
    let (tool, frames) = panda
        .fk_frames_checked(&q, &kinserve::model::FkOptions::default())
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
                skip_limit_check: true,
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
                skip_limit_check: true,
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

// ---------------------------------------------------------------- streaming

#[tokio::test]
async fn stream_answers_each_request_in_order_and_survives_invalid_messages() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 64).await;

    let ok_puma = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6];
    let requests = vec![
        stream_request(10, "puma560", &ok_puma, None),
        stream_request(7, "panda", &[0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7], None),
        // Invalid in the middle: wrong count, NaN, out of limits, unknown robot, bad option.
        stream_request(7, "puma560", &[0.0; 5], None),
        stream_request(
            u64::MAX,
            "puma560",
            &[0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0],
            None,
        ),
        stream_request(0, "puma560", &[0.0, 0.0, 170.0, 0.0, 0.0, 0.0], deg()),
        stream_request(3, "no_such_robot", &[0.0], None),
        stream_request(
            4,
            "puma560",
            &ok_puma,
            Some(pb::FkOptions {
                angle_unit: 99,
                ..Default::default()
            }),
        ),
        // And valid again, with frames and a mm robot.
        stream_request(
            5,
            "alpha_ii",
            &[10.0, 20.0, 30.0, 40.0, 50.0],
            Some(pb::FkOptions {
                angle_unit: pb::AngleUnit::Deg as i32,
                include_frames: true,
                skip_limit_check: false,
            }),
        ),
        stream_request(6, "puma560", &ok_puma, None),
    ];
    for r in &requests {
        tx.send(r.clone()).await.unwrap();
    }
    drop(tx); // half-close: the server ends the stream after the last answer

    let mut responses = Vec::new();
    while let Some(m) = rx.message().await.expect("no stream error") {
        responses.push(m);
    }
    assert_eq!(responses.len(), requests.len(), "exactly one response each");
    let ids: Vec<u64> = responses.iter().map(|r| r.id).collect();
    let want: Vec<u64> = requests.iter().map(|r| r.id).collect();
    assert_eq!(ids, want, "in order, ids echoed");

    let expect_error = |i: usize, code: Code, fields: &[&str]| {
        let Some(StreamResult::Error(e)) = &responses[i].result else {
            panic!("response {i} should be an error: {:?}", responses[i]);
        };
        assert_eq!(e.code, code as i32, "response {i}: {e:?}");
        assert!(!e.message.is_empty());
        assert_eq!(rpc_status_fields(e), fields, "response {i}");
        assert!(responses[i].frames.is_empty());
    };
    expect_error(2, Code::InvalidArgument, &["joints"]);
    expect_error(3, Code::InvalidArgument, &["joints[1]"]);
    expect_error(4, Code::InvalidArgument, &["joints[2]"]);
    expect_error(5, Code::NotFound, &[]);
    expect_error(6, Code::InvalidArgument, &["options.angle_unit"]);

    // Poses agree with the unary RPC.
    for i in [0usize, 1, 7, 8] {
        let Some(StreamResult::Pose(p)) = &responses[i].result else {
            panic!("response {i} should be a pose: {:?}", responses[i]);
        };
        let req = &requests[i];
        let unary = fk(&mut c, fk_request(&req.robot, &req.joints, req.options))
            .await
            .unwrap();
        assert_same_pose(p, unary.pose.as_ref().unwrap(), &format!("response {i}"));
        assert_eq!(responses[i].length_unit, unary.length_unit);
        assert_eq!(responses[i].frames.len(), unary.frames.len());
        for (a, b) in responses[i].frames.iter().zip(&unary.frames) {
            assert_same_pose(a, b, "frame");
        }
    }
    assert_eq!(responses[7].length_unit, pb::LengthUnit::Mm as i32);
    assert_eq!(responses[7].frames.len(), 6);
}

#[tokio::test]
async fn stream_with_a_slow_reader_delivers_every_response_in_order() {
    const N: u64 = 2000;
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, N as usize).await;
    let robots = ["puma560", "panda", "stanford", "alpha_ii"];
    let joints = |i: u64| -> (&'static str, Vec<f64>) {
        let t = (i % 97) as f64 / 97.0;
        match i % 4 {
            0 => ("puma560", vec![t, -t, t / 2.0, 0.1, -0.2, t]),
            1 => ("panda", vec![t, -t, 0.0, -1.0 - t, 0.0, 1.0 + t, 0.0]),
            2 => ("stanford", vec![t, -t, 0.5 + t / 2.0, t, 0.2, -t]),
            _ => ("alpha_ii", vec![t, 2.0 * t, -t, 0.3, t]),
        }
    };
    // Every 100th request is invalid (wrong joint count).
    for i in 0..N {
        let (robot, mut q) = joints(i);
        if i % 100 == 99 {
            q.pop();
        }
        tx.send(stream_request(i, robot, &q, None)).await.unwrap();
    }
    drop(tx);
    // Nothing read so far: the server had to stop and wait for this reader.
    let libs: Vec<_> = robots.iter().map(|r| library_robot(r)).collect();
    let mut n = 0u64;
    while let Some(m) = rx.message().await.expect("no stream error") {
        assert_eq!(m.id, n, "in order");
        let (robot, q) = joints(n);
        match (&m.result, n % 100 == 99) {
            (Some(StreamResult::Pose(p)), false) => {
                let lib = &libs[robots.iter().position(|r| *r == robot).unwrap()];
                assert_pose_eq(p, &lib.fk_unchecked(&q), 1e-12, &format!("id {n}"));
            }
            (Some(StreamResult::Error(e)), true) => {
                assert_eq!(e.code, Code::InvalidArgument as i32);
            }
            other => panic!("id {n}: unexpected {other:?}"),
        }
        n += 1;
    }
    assert_eq!(n, N, "every response arrived");
}

#[tokio::test]
async fn backpressure_reaches_the_sender_when_nobody_reads() {
    // The client sends one small request at a time (each its own DATA frame, as
    // a control loop would) and reads nothing. If the server buffered without
    // bound, the client could hand over all N requests (~2 MB). With flow control
    // end to end, the server stops reading once its bounded response queue and
    // the HTTP/2 windows are full, so the client's sender blocks part way; the
    // connection must survive that (h2 once closed it with GOAWAY
    // ENHANCE_YOUR_CALM "too_many_data_frames" after ~2,700 unread requests).
    // Then everything is read back, in order.
    const N: u64 = 30_000;
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 1).await;
    let sent = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let counter = sent.clone();
    let sender = tokio::spawn(async move {
        for i in 0..N {
            let q = [0.001 * (i % 1000) as f64, 0.0, 0.0, 0.0, 0.0, 0.0];
            if tx
                .send(stream_request(i, "puma560", &q, None))
                .await
                .is_err()
            {
                return;
            }
            counter.store(i + 1, std::sync::atomic::Ordering::SeqCst);
        }
    });
    // Wait until the sender makes no more progress (quiescence, not a deadline).
    let mut last = u64::MAX;
    for _ in 0..100 {
        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
        let now = sent.load(std::sync::atomic::Ordering::SeqCst);
        if now == last || now == N {
            break;
        }
        last = now;
    }
    let stalled_at = sent.load(std::sync::atomic::Ordering::SeqCst);
    assert!(
        stalled_at < N,
        "the client pushed all {N} requests with nobody reading: unbounded buffering"
    );
    // Now read: the sender resumes and every response arrives, in order.
    let mut n = 0u64;
    while let Some(m) = rx
        .message()
        .await
        .unwrap_or_else(|e| panic!("stream error after {n} responses: {e:?}"))
    {
        assert_eq!(m.id, n, "in order");
        assert!(matches!(m.result, Some(StreamResult::Pose(_))), "id {n}");
        n += 1;
    }
    assert_eq!(n, N);
    sender.await.unwrap();
}

#[tokio::test]
async fn a_stream_outlives_the_request_timeout() {
    // The request timeout bounds unary calls; a live stream is bounded by its idle timeout only.
    let app = spawn_app_with(|c| c.request_timeout = std::time::Duration::from_millis(100)).await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    for id in 0..4 {
        tx.send(stream_request(id, "puma560", &[0.0; 6], None))
            .await
            .unwrap();
        assert_eq!(rx.message().await.unwrap().unwrap().id, id);
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    drop(tx);
    assert!(rx.message().await.unwrap().is_none(), "clean end");
}

/// Calls ListRobots until it is admitted (a liveness check with a generous
/// bound, not a timing assertion). Every refusal must be RESOURCE_EXHAUSTED.
async fn eventually_admitted(c: &mut KinematicsServiceClient<Channel>) -> bool {
    for _ in 0..1000 {
        match c.list_robots(pb::ListRobotsRequest {}).await {
            Ok(_) => return true,
            Err(e) => assert_eq!(e.code(), Code::ResourceExhausted, "{e:?}"),
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    false
}

/// A TCP proxy to `target` for one connection; aborting the returned task cuts
/// the connection abruptly (a client that vanishes without a word).
async fn one_shot_proxy(target: &str) -> (String, tokio::task::JoinHandle<()>) {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let target = target.trim_start_matches("http://").to_string();
    let task = tokio::spawn(async move {
        let (mut inbound, _) = listener.accept().await.unwrap();
        let mut outbound = tokio::net::TcpStream::connect(target).await.unwrap();
        let _ = tokio::io::copy_bidirectional(&mut inbound, &mut outbound).await;
    });
    (format!("http://{addr}"), task)
}

#[tokio::test]
async fn over_the_concurrency_limit_calls_are_resource_exhausted_and_a_finished_stream_frees_its_slot()
 {
    // One request in flight at a time: the open stream holds the only permit.
    let app = spawn_app_with(|c| c.max_concurrent_requests = 1).await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    tx.send(stream_request(1, "puma560", &[0.0; 6], None))
        .await
        .unwrap();
    assert_eq!(rx.message().await.unwrap().unwrap().id, 1);

    let err = c.list_robots(pb::ListRobotsRequest {}).await.unwrap_err();
    assert_eq!(err.code(), Code::ResourceExhausted, "{err:?}");
    let err = c
        .forward_kinematics(fk_request("puma560", &[0.0; 6], None))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::ResourceExhausted, "{err:?}");

    // The client drops both halves of the call (tonic: END_STREAM, then the
    // stream is reset because the response is no longer wanted).
    drop(rx);
    drop(tx);
    assert!(
        eventually_admitted(&mut c).await,
        "the dropped stream still holds its permit"
    );
}

#[tokio::test]
async fn cancelling_a_stream_blocked_on_a_slow_reader_releases_the_server_side_work() {
    // The server is blocked sending (the client never reads) when the client goes.
    let app = spawn_app_with(|c| c.max_concurrent_requests = 1).await;
    let mut c = app.grpc_client().await;
    let (proxy, cut) = one_shot_proxy(&app.grpc).await;
    let mut via_proxy = KinematicsServiceClient::connect(proxy).await.unwrap();
    let (tx, rx) = open_stream(&mut via_proxy, 500).await;
    for i in 0..500 {
        tx.send(stream_request(i, "puma560", &[0.0; 6], None))
            .await
            .unwrap();
    }
    // Cut the connection with the request side still open: no END_STREAM, no
    // RST_STREAM, just gone.
    cut.abort();
    let _ = cut.await;
    assert!(
        eventually_admitted(&mut c).await,
        "the abandoned stream still holds its permit"
    );
    drop((tx, rx));
}

#[tokio::test]
async fn a_client_that_vanishes_mid_stream_releases_the_server_side_work() {
    // The server is waiting for the next request when the connection dies.
    let app = spawn_app_with(|c| c.max_concurrent_requests = 1).await;
    let mut c = app.grpc_client().await;
    let (proxy, cut) = one_shot_proxy(&app.grpc).await;
    let mut via_proxy = KinematicsServiceClient::connect(proxy).await.unwrap();
    let (tx, mut rx) = open_stream(&mut via_proxy, 4).await;
    tx.send(stream_request(1, "puma560", &[0.0; 6], None))
        .await
        .unwrap();
    assert_eq!(rx.message().await.unwrap().unwrap().id, 1);
    assert_eq!(
        c.list_robots(pb::ListRobotsRequest {})
            .await
            .unwrap_err()
            .code(),
        Code::ResourceExhausted
    );
    cut.abort();
    let _ = cut.await;
    assert!(
        eventually_admitted(&mut c).await,
        "the abandoned stream still holds its permit"
    );
    drop((tx, rx));
}

#[tokio::test]
async fn an_idle_stream_is_closed_with_deadline_exceeded() {
    let app =
        spawn_app_with(|c| c.stream_idle_timeout = std::time::Duration::from_millis(200)).await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    tx.send(stream_request(1, "puma560", &[0.0; 6], None))
        .await
        .unwrap();
    assert_eq!(rx.message().await.unwrap().unwrap().id, 1);
    // Send nothing more: the server gives up on the stream.
    let err = rx.message().await.unwrap_err();
    assert_eq!(err.code(), Code::DeadlineExceeded, "{err:?}");
    drop(tx);
}

// ---------------------------------------------------------------- health and shutdown

#[tokio::test]
async fn health_reports_serving_for_the_server_and_the_service() {
    use tonic_health::pb::HealthCheckRequest;
    use tonic_health::pb::health_check_response::ServingStatus;
    use tonic_health::pb::health_client::HealthClient;

    let app = spawn_app().await;
    let mut h = HealthClient::new(channel(&app).await);
    for service in ["", "kinematics.v1.KinematicsService"] {
        let r = h
            .check(HealthCheckRequest {
                service: service.into(),
            })
            .await
            .unwrap()
            .into_inner();
        assert_eq!(r.status, ServingStatus::Serving as i32, "'{service}'");
    }
    let err = h
        .check(HealthCheckRequest {
            service: "no.such.Service".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::NotFound);
}

#[tokio::test]
async fn shutdown_flips_health_to_not_serving_and_ends_fk_streams() {
    use tonic_health::pb::HealthCheckRequest;
    use tonic_health::pb::health_check_response::ServingStatus;
    use tonic_health::pb::health_client::HealthClient;

    let app = spawn_app_with(|c| c.shutdown_timeout = std::time::Duration::from_secs(2)).await;
    let mut h = HealthClient::new(channel(&app).await);
    let mut watches = Vec::new();
    for service in ["", "kinematics.v1.KinematicsService"] {
        let mut w = h
            .watch(HealthCheckRequest {
                service: service.into(),
            })
            .await
            .unwrap()
            .into_inner();
        let first = w.message().await.unwrap().unwrap();
        assert_eq!(first.status, ServingStatus::Serving as i32, "'{service}'");
        watches.push((service, w));
    }
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    tx.send(stream_request(1, "puma560", &[0.0; 6], None))
        .await
        .unwrap();
    assert_eq!(rx.message().await.unwrap().unwrap().id, 1);

    let stopping = tokio::spawn(app.stop());

    for (service, mut w) in watches {
        let next = w.message().await;
        match next {
            Ok(Some(m)) => assert_eq!(
                m.status,
                ServingStatus::NotServing as i32,
                "'{service}' while shutting down"
            ),
            other => {
                panic!("'{service}': expected NOT_SERVING before the watch ends, got {other:?}")
            }
        }
    }
    let err = match rx.message().await {
        Ok(Some(m)) => panic!("unexpected response {m:?}"),
        Ok(None) => panic!("stream ended without UNAVAILABLE"),
        Err(e) => e,
    };
    assert_eq!(err.code(), Code::Unavailable, "{err:?}");
    drop(tx);
    stopping.await.unwrap().unwrap();
}

// ---------------------------------------------------------------- reflection

macro_rules! reflection_suite {
    ($name:ident, $module:path) => {
        #[tokio::test]
        async fn $name() {
            use r::server_reflection_client::ServerReflectionClient;
            use r::server_reflection_request::MessageRequest;
            use r::server_reflection_response::MessageResponse;
            use $module as r;

            let app = spawn_app().await;
            let mut client = ServerReflectionClient::new(channel(&app).await);
            let ask = |m: MessageRequest| r::ServerReflectionRequest {
                host: String::new(),
                message_request: Some(m),
            };
            let requests = vec![
                ask(MessageRequest::ListServices(String::new())),
                ask(MessageRequest::FileContainingSymbol(
                    "kinematics.v1.KinematicsService".into(),
                )),
                ask(MessageRequest::FileContainingSymbol(
                    "kinematics.v1.KinematicsService.StreamForwardKinematics".into(),
                )),
                ask(MessageRequest::FileContainingSymbol(
                    "kinematics.v1.StreamForwardKinematicsResponse".into(),
                )),
                ask(MessageRequest::FileByFilename(
                    "google/rpc/status.proto".into(),
                )),
                ask(MessageRequest::FileContainingSymbol(
                    "no.such.Symbol".into(),
                )),
            ];
            let n = requests.len();
            let mut responses = client
                .server_reflection_info(tokio_stream::iter(requests))
                .await
                .unwrap()
                .into_inner();
            let mut got = Vec::new();
            let end = loop {
                match responses.message().await {
                    Ok(Some(m)) => got.push(m.message_response.expect("a response")),
                    other => break other,
                }
            };
            // tonic-reflection answers an unknown symbol by ending the stream with
            // NOT_FOUND (not with an ErrorResponse message): accept either form.
            match end {
                Err(e) => {
                    assert_eq!(e.code(), Code::NotFound, "{e:?}");
                    assert_eq!(got.len(), n - 1);
                }
                Ok(None) => {
                    assert_eq!(got.len(), n);
                    let MessageResponse::ErrorResponse(e) = &got[n - 1] else {
                        panic!("unknown symbol: {:?}", got[n - 1]);
                    };
                    assert_eq!(e.error_code, Code::NotFound as i32);
                }
                Ok(Some(_)) => unreachable!(),
            }

            let MessageResponse::ListServicesResponse(list) = &got[0] else {
                panic!("list: {:?}", got[0]);
            };
            let services: BTreeSet<&str> = list.service.iter().map(|s| s.name.as_str()).collect();
            for s in ["kinematics.v1.KinematicsService", "grpc.health.v1.Health"] {
                assert!(services.contains(s), "{s} in {services:?}");
            }

            let files = |i: usize| -> Vec<prost_types::FileDescriptorProto> {
                let MessageResponse::FileDescriptorResponse(f) = &got[i] else {
                    panic!("response {i}: {:?}", got[i]);
                };
                f.file_descriptor_proto
                    .iter()
                    .map(|b| prost_types::FileDescriptorProto::decode(b.as_slice()).unwrap())
                    .collect()
            };
            for i in 1..=3 {
                let fds = files(i);
                let kin = fds
                    .iter()
                    .find(|f| f.name() == "kinematics/v1/kinematics.proto")
                    .unwrap_or_else(|| {
                        panic!(
                            "response {i}: {:?}",
                            fds.iter().map(|f| f.name()).collect::<Vec<_>>()
                        )
                    });
                assert_eq!(kin.package(), "kinematics.v1");
                let svc = kin
                    .service
                    .iter()
                    .find(|s| s.name() == "KinematicsService")
                    .expect("service in file");
                let methods: BTreeSet<&str> = svc.method.iter().map(|m| m.name()).collect();
                let want: BTreeSet<&str> = [
                    "ListRobots",
                    "GetRobot",
                    "RegisterRobot",
                    "DeleteRobot",
                    "ForwardKinematics",
                    "ForwardKinematicsBatch",
                    "StreamForwardKinematics",
                ]
                .into();
                assert_eq!(methods, want);
                let stream = svc
                    .method
                    .iter()
                    .find(|m| m.name() == "StreamForwardKinematics")
                    .unwrap();
                assert!(stream.client_streaming() && stream.server_streaming());
                assert!(
                    kin.dependency
                        .iter()
                        .any(|d| d == "google/rpc/status.proto")
                );
            }
            // The imported file (for the oneof's google.rpc.Status) resolves too.
            let status = files(4);
            assert!(status.iter().any(|f| f.name() == "google/rpc/status.proto"));
        }
    };
}

reflection_suite!(
    reflection_v1_lists_services_and_finds_the_kinematics_file,
    tonic_reflection::pb::v1
);
reflection_suite!(
    reflection_v1alpha_lists_services_and_finds_the_kinematics_file,
    tonic_reflection::pb::v1alpha
);

// ---------------------------------------------------------------- one registry, two front doors

#[tokio::test]
async fn a_robot_registered_over_grpc_is_visible_over_rest_at_once() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let model = rich_pb("rich");
    let stored = c
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(model.clone()),
            replace: false,
        })
        .await
        .unwrap()
        .into_inner()
        .robot
        .unwrap();
    assert_eq!(stored, model, "stored as sent");

    let r = app.get("/v1/robots/rich").await;
    assert_eq!(r.status(), 200);
    let spec: serde_json::Value = r.json().await.unwrap();
    assert_eq!(spec["name"], "rich");
    assert_eq!(spec["description"], "test arm");
    assert_eq!(spec["convention"], "standard");
    assert_eq!(spec["angle_unit"], "deg");
    assert_eq!(spec["length_unit"], "mm");
    assert_eq!(spec["base"]["translation"], json!([10.0, -20.0, 300.0]));
    assert_eq!(spec["base"]["rpy"], json!([0.0, 0.0, 30.0]));
    assert_eq!(spec["tool"]["quaternion"]["z"], json!(0.3826834323650898));
    let links = spec["links"].as_array().unwrap();
    assert_eq!(links.len(), 4);
    assert_eq!(links[1]["joint"], "prismatic");
    assert_eq!(links[1]["name"], "slide");
    assert_eq!(links[1]["limits"], json!([0.0, 400.0]));
    assert_eq!(links[3]["joint"], "fixed");

    let list: serde_json::Value = app.get("/v1/robots").await.json().await.unwrap();
    let line = list["robots"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["name"] == "rich")
        .expect("listed over REST")
        .clone();
    assert_eq!(line["source"], "registered");
    assert_eq!(line["dof"], 3);

    // Same pose over both doors.
    let q = [25.0, 120.0, -40.0];
    let g = fk(&mut c, fk_request("rich", &q, deg()))
        .await
        .unwrap()
        .pose
        .unwrap();
    let rest: serde_json::Value = app
        .post(
            "/v1/robots/rich/fk",
            &json!({"joints": q, "angle_unit": "deg"}),
        )
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(rest["length_unit"], "mm");
    for (a, b) in g.matrix.iter().zip(matrix16(&rest["pose"])) {
        assert_close(*a, b, 1e-12, "matrix");
    }

    // Deleted over gRPC: gone over REST.
    c.delete_robot(pb::DeleteRobotRequest {
        name: "rich".into(),
    })
    .await
    .unwrap();
    assert_eq!(app.get("/v1/robots/rich").await.status(), 404);
}

#[tokio::test]
async fn a_robot_registered_over_rest_is_visible_over_grpc_at_once() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let r = app.post("/v1/robots", &planar_model("viarest")).await;
    assert_eq!(r.status(), 201);

    let got = c
        .get_robot(pb::GetRobotRequest {
            name: "viarest".into(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(got.source, pb::RobotSource::Registered as i32);
    assert_eq!(got.robot.unwrap(), planar_pb("viarest"));

    // Replace over REST (PUT): gRPC sees the new table at once.
    let mut longer = planar_model("viarest");
    longer["links"][0]["a"] = json!(2.0);
    let r = app
        .client
        .put(format!("{}/v1/robots/viarest", app.http))
        .json(&longer)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let pose = fk(&mut c, fk_request("viarest", &[90.0, 0.0], deg()))
        .await
        .unwrap()
        .pose
        .unwrap();
    let p = pose.position.unwrap();
    assert_close(p.x, 0.0, 1e-12, "x");
    assert_close(p.y, 2.3, 1e-12, "y");

    // Taken over REST: ALREADY_EXISTS over gRPC.
    let err = c
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(planar_pb("viarest")),
            replace: false,
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::AlreadyExists);

    let r = app
        .client
        .delete(format!("{}/v1/robots/viarest", app.http))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204);
    let err = c
        .get_robot(pb::GetRobotRequest {
            name: "viarest".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::NotFound);
}
