//! One vocabulary on every front door: the same names (`frames`,
//! `check_limits`, `quaternion`, `length_unit`), "missing" is an error
//! everywhere, and options a call does not support are refused, not ignored.
//! The deprecated gRPC names still work and may not contradict the new ones.

use futures_util::SinkExt;
use kinserve::api::grpc::pb;
use serde_json::json;
use tokio_tungstenite::tungstenite::Message;
use tonic::Code;

use crate::helpers::*;

#[tokio::test]
async fn a_link_without_alpha_is_refused_over_rest_and_grpc_naming_it() {
    let app = spawn_app().await;
    let mut model = planar_model("no-alpha");
    model["links"][0].as_object_mut().unwrap().remove("alpha");
    let p = problem(app.post("/v1/robots", &model).await, 400).await;
    assert_eq!(fields(&p), ["links[0].alpha"]);
    let mut robot = planar_pb("no-alpha");
    robot.links[0].alpha = None;
    let mut client = app.grpc_client().await;
    let e = client
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(robot),
            replace: false,
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&e), ["links[0].alpha"]);
    assert!(
        e.message().contains("missing field `alpha`"),
        "{}",
        e.message()
    );
}

#[tokio::test]
async fn frames_in_a_batch_are_refused_on_both_protocols() {
    let app = spawn_app().await;
    let body = json!({"configurations": [[0, 0]], "frames": true});
    let p = problem(
        app.post("/v1/robots/planar_2dof/fk/batch", &body).await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["frames"]);
    let mut client = app.grpc_client().await;
    for options in [
        pb::FkOptions {
            frames: Some(true),
            ..Default::default()
        },
        #[allow(deprecated)]
        pb::FkOptions {
            include_frames: true,
            ..Default::default()
        },
    ] {
        let e = client
            .forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
                robot: "planar_2dof".into(),
                configurations: vec![pb::JointConfiguration {
                    joints: vec![0.0, 0.0],
                }],
                options: Some(options),
                ..Default::default()
            })
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument);
        assert_eq!(status_fields(&e), ["options.frames"]);
    }
}

#[tokio::test]
#[allow(deprecated, reason = "checks that the deprecated names still work")]
async fn new_and_deprecated_grpc_option_names_agree_and_twins_may_not_conflict() {
    let app = spawn_app().await;
    let mut client = app.grpc_client().await;
    // 10 rad is outside the PUMA's waist limits: only check_limits = false accepts it.
    let q = [10.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let run = |options: pb::FkOptions| {
        let mut c = client.clone();
        async move {
            c.forward_kinematics(fk_request("puma560", &q, Some(options)))
                .await
        }
    };
    let new = run(pb::FkOptions {
        check_limits: Some(false),
        frames: Some(true),
        ..Default::default()
    })
    .await
    .unwrap()
    .into_inner();
    let old = run(pb::FkOptions {
        skip_limit_check: true,
        include_frames: true,
        ..Default::default()
    })
    .await
    .unwrap()
    .into_inner();
    assert_eq!(new.frames.len(), 7);
    assert_eq!(new, old);
    let checked = run(pb::FkOptions {
        check_limits: Some(true),
        ..Default::default()
    })
    .await
    .unwrap_err();
    assert_eq!(checked.code(), Code::InvalidArgument);
    let conflict = run(pb::FkOptions {
        check_limits: Some(true),
        skip_limit_check: true,
        ..Default::default()
    })
    .await
    .unwrap_err();
    assert_eq!(status_fields(&conflict), ["options.check_limits"]);
    let conflict = run(pb::FkOptions {
        frames: Some(false),
        include_frames: true,
        ..Default::default()
    })
    .await
    .unwrap_err();
    assert_eq!(status_fields(&conflict), ["options.frames"]);
    // The pose's orientation is `quaternion`, as over REST; the old name carries the same value.
    let pose = new.pose.unwrap();
    assert_eq!(pose.quaternion, pose.orientation);
    assert!(pose.quaternion.is_some());
    client
        .get_robot(pb::GetRobotRequest {
            name: "planar_2dof".into(),
        })
        .await
        .unwrap();
}

#[tokio::test]
async fn websocket_replies_carry_the_length_unit_like_rest_and_grpc() {
    let app = spawn_app().await;
    let mut ws = open_ws(&app, "alpha_ii").await;
    ws.send(Message::Text(
        json!({"id": 1, "joints": [0, 0, 0, 0, 0]})
            .to_string()
            .into(),
    ))
    .await
    .unwrap();
    let reply = next_text(&mut ws).await.unwrap();
    assert_eq!(reply["length_unit"], "mm", "{reply}");
    let rest: serde_json::Value = app
        .post(
            "/v1/robots/alpha_ii/fk",
            &json!({"joints": [0, 0, 0, 0, 0]}),
        )
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(rest["length_unit"], reply["length_unit"]);
}
