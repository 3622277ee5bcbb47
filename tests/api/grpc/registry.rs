//! gRPC registry RPCs: list, get, register, replace and delete, read-only
//! built-ins, invalid models, the bearer token, and the one registry shared
//! with REST.

use kinserve::api::grpc::pb;
use serde_json::json;
use tonic::Code;

use crate::helpers::*;

// ---------------------------------------------------------------- registry RPCs

#[tokio::test]
async fn list_robots_is_sorted_and_describes_builtins() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let robots = c
        .list_robots(pb::ListRobotsRequest::default())
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
    assert_eq!(robot.links[2].theta, Some(-90.0));
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
            ..Default::default()
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
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::AlreadyExists, "{err:?}");

    // With replace: replaced (created = false), and the new table is used.
    let mut longer = planar_pb("arm");
    longer.links[0].a = Some(1.0);
    let r = c
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(longer),
            replace: true,
            ..Default::default()
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
    assert_eq!(got.robot.unwrap().links[0].a, Some(1.0));

    let list = c
        .list_robots(pb::ListRobotsRequest::default())
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
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    assert!(r.created, "replace of an absent robot creates it");

    c.delete_robot(pb::DeleteRobotRequest {
        name: "arm".into(),
        ..Default::default()
    })
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
        .delete_robot(pb::DeleteRobotRequest {
            name: "arm".into(),
            ..Default::default()
        })
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
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::FailedPrecondition, "{err:?}");
    for replace in [true, false] {
        let err = c
            .register_robot(pb::RegisterRobotRequest {
                robot: Some(planar_pb("puma560")),
                replace,
                ..Default::default()
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
            ..Default::default()
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
    m.links[0].alpha = Some(f64::NAN);
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
        .list_robots(pb::ListRobotsRequest::default())
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
        ..Default::default()
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
            ..Default::default()
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
    c.list_robots(pb::ListRobotsRequest::default())
        .await
        .unwrap();
    fk(&mut c, fk_request("guarded", &[0.0, 0.0], None))
        .await
        .unwrap();

    let del = || pb::DeleteRobotRequest {
        name: "guarded".into(),
        ..Default::default()
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
            ..Default::default()
        },
        "Bearer whatever",
    ))
    .await
    .unwrap();
    c.delete_robot(pb::DeleteRobotRequest {
        name: "open".into(),
        ..Default::default()
    })
    .await
    .unwrap();
}

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
            ..Default::default()
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
        ..Default::default()
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
            ..Default::default()
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
