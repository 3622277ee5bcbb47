//! Secure by default: without a token the registry is read-only unless
//! `--allow-unauthenticated-writes`; web pages of other origins may compute
//! FK but not change the registry unless `--cors-origin` names them; one
//! Authorization header only; tokens with stray whitespace; a bounded registry.

use kinserve::api::grpc::pb;
use serde_json::json;
use tonic::Code;

use crate::helpers::*;

const STRANGER: &str = "https://stranger.example";

async fn post_from(
    app: &TestApp,
    path: &str,
    origin: &str,
    body: &serde_json::Value,
) -> reqwest::Response {
    app.client
        .post(format!("{}{path}", app.http))
        .header("origin", origin)
        .json(body)
        .send()
        .await
        .unwrap()
}

/// The real default (no token, writes not opened): every registry write is
/// 403 / PERMISSION_DENIED with the fix, whatever token is presented, on REST
/// and gRPC; reads and FK are served; nothing is written.
#[tokio::test]
async fn without_a_token_the_registry_is_read_only_by_default_on_every_door() {
    let defaults = kinserve::config::ServeConfig::flag_defaults();
    assert!(defaults.api_token.is_none() && !defaults.allow_unauthenticated_writes);
    let app = spawn_app_with(|c| {
        c.api_token = defaults.api_token.clone();
        c.allow_unauthenticated_writes = defaults.allow_unauthenticated_writes;
    })
    .await;
    let url = |path: &str| format!("{}{path}", app.http);
    let writes = [
        app.client.post(url("/v1/robots")).json(&planar_model("w1")),
        app.client
            .put(url("/v1/robots/w2"))
            .bearer_auth("any-token")
            .json(&planar_model("w2")),
        app.client.delete(url("/v1/robots/planar_2dof")),
    ];
    for write in writes {
        let p = problem(write.send().await.unwrap(), 403).await;
        assert_eq!(p["type"], "urn:kinserve:problem:forbidden");
        let detail = p["detail"].as_str().unwrap();
        for fix in [
            "--api-token",
            "KINSERVE_API_TOKEN",
            "--allow-unauthenticated-writes",
        ] {
            assert!(detail.contains(fix), "{fix} in {p}");
        }
    }
    for name in ["w1", "w2"] {
        assert_eq!(app.get(&format!("/v1/robots/{name}")).await.status(), 404);
    }
    assert_eq!(app.get("/v1/robots/planar_2dof").await.status(), 200);
    let fk = app
        .post("/v1/robots/planar_2dof/fk", &json!({"joints": [0, 0]}))
        .await;
    assert_eq!(fk.status(), 200);
    let mut client = app.grpc_client().await;
    let e = client
        .register_robot(pb::RegisterRobotRequest::default())
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied, "{e:?}");
    assert!(e.message().contains("--api-token"), "{e:?}");
    let e = client
        .import_urdf(pb::ImportUrdfRequest::default())
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied, "{e:?}");
    let e = client
        .delete_robot(pb::DeleteRobotRequest {
            name: "planar_2dof".into(),
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied, "{e:?}");
    // Opened on purpose, the same write goes through.
    let open = spawn_app_with(|c| c.allow_unauthenticated_writes = true).await;
    assert_eq!(
        open.post("/v1/robots", &planar_model("w1")).await.status(),
        201
    );
}

#[tokio::test]
async fn a_strangers_page_may_compute_but_not_write_by_default() {
    let app = spawn_app().await;
    let preflight = app
        .client
        .request(
            reqwest::Method::OPTIONS,
            format!("{}/v1/robots/x", app.http),
        )
        .header("origin", STRANGER)
        .header("access-control-request-method", "DELETE")
        .send()
        .await
        .unwrap();
    let methods = preflight
        .headers()
        .get("access-control-allow-methods")
        .map(|v| v.to_str().unwrap().to_string());
    assert!(
        !methods.clone().unwrap_or_default().contains("DELETE"),
        "{methods:?}"
    );
    let fk = post_from(
        &app,
        "/v1/robots/planar_2dof/fk",
        STRANGER,
        &json!({"joints": [0, 0]}),
    )
    .await;
    assert_eq!(fk.status(), 200);
    assert_eq!(fk.headers()["access-control-allow-origin"], "*");
    let p = problem(
        post_from(&app, "/v1/robots", STRANGER, &planar_model("cross")).await,
        403,
    )
    .await;
    assert_eq!(p["type"], "urn:kinserve:problem:forbidden");
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("--cors-origin https://stranger.example"),
        "{p}"
    );
    assert_eq!(
        app.get("/v1/robots/cross").await.status(),
        404,
        "nothing was written"
    );
    // The server's own pages (same origin) and non-browser clients (no Origin) may write.
    let own = app.http.clone();
    assert_eq!(
        post_from(&app, "/v1/robots", &own, &planar_model("own"))
            .await
            .status(),
        201
    );
    assert_eq!(
        app.post("/v1/robots", &planar_model("cli")).await.status(),
        201
    );
}

#[tokio::test]
async fn a_named_origin_may_write_and_others_may_not_open_websockets() {
    let app = spawn_app_with(|c| c.cors_origins = vec![STRANGER.into()]).await;
    assert_eq!(
        post_from(&app, "/v1/robots", STRANGER, &planar_model("allowed"))
            .await
            .status(),
        201
    );
    let other = post_from(
        &app,
        "/v1/robots",
        "https://other.example",
        &planar_model("nope"),
    )
    .await;
    assert_eq!(other.status(), 403);
    let ws = |origin: &'static str| {
        let url = format!("{}/v1/robots/planar_2dof/fk/stream", app.ws);
        async move {
            let mut req =
                tokio_tungstenite::tungstenite::client::IntoClientRequest::into_client_request(url)
                    .unwrap();
            req.headers_mut().insert("origin", origin.parse().unwrap());
            tokio_tungstenite::connect_async(req).await
        }
    };
    assert!(
        ws(STRANGER).await.is_ok(),
        "an allowed origin opens the stream"
    );
    match ws("https://other.example").await {
        Err(tokio_tungstenite::tungstenite::Error::Http(resp)) => assert_eq!(resp.status(), 403),
        other => panic!("expected 403, got {:?}", other.map(|_| ())),
    }
}

#[tokio::test]
async fn two_authorization_headers_are_malformed_on_rest_and_grpc() {
    let app = spawn_app_with(|c| c.api_token = Some("s3cret".into())).await;
    let r = app
        .client
        .post(format!("{}/v1/robots", app.http))
        .header("authorization", "Bearer s3cret")
        .header("authorization", "Bearer wrong")
        .json(&planar_model("twice"))
        .send()
        .await
        .unwrap();
    let p = problem(r, 400).await;
    assert_eq!(fields(&p), ["authorization"]);
    let mut client = app.grpc_client().await;
    let mut req = tonic::Request::new(pb::DeleteRobotRequest {
        name: "twice".into(),
        etag: String::new(),
    });
    req.metadata_mut()
        .append("authorization", "Bearer s3cret".parse().unwrap());
    req.metadata_mut()
        .append("authorization", "Bearer wrong".parse().unwrap());
    let e = client.delete_robot(req).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
}

#[tokio::test]
async fn a_token_with_a_trailing_newline_is_trimmed_and_one_of_spaces_refused() {
    let app = spawn_app_with(|c| c.api_token = Some("s3cret\n".into())).await;
    let r = app
        .client
        .post(format!("{}/v1/robots", app.http))
        .header("authorization", "Bearer s3cret")
        .json(&planar_model("trimmed"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let dir = tempfile::tempdir().unwrap();
    let mut config = kinserve::config::ServeConfig::for_tests(dir.path().to_path_buf());
    config.api_token = Some("   ".into());
    let err = kinserve::App::build(config)
        .await
        .err()
        .expect("refused at start-up");
    assert!(err.to_string().contains("only whitespace"), "{err}");
}

#[tokio::test]
async fn the_registry_is_bounded_by_max_robots() {
    let app = spawn_app_with(|c| c.max_robots = 2).await;
    for name in ["one", "two"] {
        assert_eq!(
            app.post("/v1/robots", &planar_model(name)).await.status(),
            201
        );
    }
    let p = problem(app.post("/v1/robots", &planar_model("three")).await, 507).await;
    assert_eq!(p["type"], "urn:kinserve:problem:registry-full");
    assert!(
        p["detail"].as_str().unwrap().contains("--max-robots"),
        "{p}"
    );
    // Replacing one that exists is still allowed.
    let r = app
        .client
        .put(format!("{}/v1/robots/two", app.http))
        .json(&planar_model("two"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let mut client = app.grpc_client().await;
    let e = client
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(planar_pb("three")),
            replace: false,
            etag: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted);
}
