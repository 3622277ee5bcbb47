//! The token rule under attack: every mutation needs the token, reads leak
//! nothing, and the token never appears in the logs.

use futures_util::SinkExt;
use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use tokio_tungstenite::tungstenite::Message;
use tonic::Code;

use crate::helpers::*;

// ---------------------------------------------------------------- auth

/// The token rule on every mutating route and RPC: without the token (or with
/// a wrong one, in the wrong place or scheme) every mutation is 401 /
/// UNAUTHENTICATED before anything else is looked at (body, robot, name), and
/// changes nothing. Reads, FK, the WebSocket stream and reflection need no
/// token and give nothing private away.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_mutation_needs_the_token_and_reads_leak_nothing() {
    const TOKEN: &str = "tok-3f9a1c77e2";
    let app = spawn_app_with(|c| c.api_token = Some(TOKEN.into())).await;
    let url = |p: &str| format!("{}{p}", app.http);
    let model = planar_model("guarded");
    let bad_auth: [Option<(&'static str, String)>; 8] = [
        None,
        Some(("authorization", "Bearer wrong".into())),
        Some(("authorization", format!("Bearer {TOKEN}x"))),
        Some((
            "authorization",
            format!("Bearer {}", &TOKEN[..TOKEN.len() - 1]),
        )),
        Some(("authorization", format!("Basic {TOKEN}"))),
        Some(("authorization", TOKEN.to_owned())),
        Some(("x-api-token", TOKEN.to_owned())),
        Some(("cookie", format!("token={TOKEN}"))),
    ];
    let mutations = [
        ("POST", "/v1/robots", Some(model.to_string())),
        ("POST", "/v1/robots", Some("{not json".to_owned())),
        ("PUT", "/v1/robots/guarded", Some(model.to_string())),
        ("PUT", "/v1/robots/puma560", Some(model.to_string())),
        ("PUT", "/v1/robots/..%2Fx", Some("{}".to_owned())),
        ("DELETE", "/v1/robots/puma560", None),
        ("DELETE", "/v1/robots/nope", None),
        (
            "POST",
            &format!("/v1/robots?token={TOKEN}&access_token={TOKEN}"),
            Some(model.to_string()),
        ),
    ];
    let mut tried = 0;
    for (method, path, body) in &mutations {
        for auth in &bad_auth {
            let mut req = app.client.request(
                reqwest::Method::from_bytes(method.as_bytes()).unwrap(),
                url(path),
            );
            if let Some(b) = body {
                req = req
                    .header("content-type", "application/json")
                    .body(b.clone());
            }
            if let Some((k, v)) = auth {
                req = req.header(*k, v);
            }
            let r = req.send().await.unwrap();
            let p = crate::helpers::problem(r, 401).await;
            assert_eq!(
                p["type"], "urn:kinserve:problem:unauthenticated",
                "{method} {path}"
            );
            tried += 1;
        }
    }
    // Nothing changed.
    assert_eq!(app.get("/v1/robots/guarded").await.status(), 404);
    assert_eq!(app.get("/v1/robots/puma560").await.status(), 200);
    // gRPC: RegisterRobot and DeleteRobot, even with an invalid robot or an unknown name.
    let mut c = app.grpc_client().await;
    for auth in &bad_auth {
        fn with<T>(auth: &Option<(&'static str, String)>, msg: T) -> tonic::Request<T> {
            let mut req = tonic::Request::new(msg);
            if let Some((k, v)) = auth {
                req.metadata_mut().insert(*k, v.parse().unwrap());
            }
            req
        }
        let err = c
            .register_robot(with(
                auth,
                pb::RegisterRobotRequest {
                    robot: None,
                    replace: true,
                    ..Default::default()
                },
            ))
            .await
            .unwrap_err();
        assert_eq!(err.code(), Code::Unauthenticated, "{auth:?}");
        let err = c
            .delete_robot(with(
                auth,
                pb::DeleteRobotRequest {
                    name: "puma560".into(),
                    ..Default::default()
                },
            ))
            .await
            .unwrap_err();
        assert_eq!(err.code(), Code::Unauthenticated, "{auth:?}");
        tried += 2;
    }
    // The right token (any case of the scheme) works.
    let r = app
        .client
        .put(url("/v1/robots/guarded"))
        .header("authorization", format!("bearer {TOKEN}"))
        .json(&model)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    // Reads, FK and the WebSocket need no token; the stream cannot mutate anything.
    assert_eq!(app.get("/v1/robots").await.status(), 200);
    let mut ws = open_ws(&app, "guarded").await;
    ws.send(Message::Text(r#"{"id": 1, "delete": "guarded"}"#.into()))
        .await
        .unwrap();
    let reply = next_text(&mut ws).await.unwrap();
    assert_eq!(reply["error"]["status"], 400, "{reply}");
    assert_eq!(app.get("/v1/robots/guarded").await.status(), 200);
    // No response carries the token.
    for path in [
        "/v1/robots",
        "/v1/robots/guarded",
        "/metrics",
        "/openapi.json",
        "/readyz",
    ] {
        let text = app.get(path).await.text().await.unwrap();
        assert!(!text.contains(TOKEN), "{path} leaks the token");
    }
    // Reflection lists only the public services and describes only the public protos.
    {
        use tonic_reflection::pb::v1::ServerReflectionRequest;
        use tonic_reflection::pb::v1::server_reflection_client::ServerReflectionClient;
        use tonic_reflection::pb::v1::server_reflection_request::MessageRequest;
        use tonic_reflection::pb::v1::server_reflection_response::MessageResponse;
        let mut r = ServerReflectionClient::new(crate::helpers::channel(&app).await);
        let ask = |m| ServerReflectionRequest {
            host: String::new(),
            message_request: Some(m),
        };
        let mut stream = r
            .server_reflection_info(tokio_stream::iter(vec![
                ask(MessageRequest::ListServices(String::new())),
                ask(MessageRequest::FileContainingSymbol(
                    "kinematics.v1.KinematicsService".into(),
                )),
            ]))
            .await
            .unwrap()
            .into_inner();
        let mut services = Vec::new();
        let mut bytes = Vec::new();
        while let Some(m) = stream.message().await.unwrap() {
            match m.message_response.unwrap() {
                MessageResponse::ListServicesResponse(l) => {
                    services = l.service.into_iter().map(|s| s.name).collect()
                }
                MessageResponse::FileDescriptorResponse(f) => {
                    bytes.extend(f.file_descriptor_proto.into_iter().flatten())
                }
                other => panic!("{other:?}"),
            }
        }
        services.sort();
        assert_eq!(
            services,
            [
                "grpc.health.v1.Health",
                "grpc.reflection.v1.ServerReflection",
                "grpc.reflection.v1alpha.ServerReflection",
                "kinematics.v1.KinematicsService",
            ]
        );
        let text = String::from_utf8_lossy(&bytes);
        assert!(!text.contains(TOKEN));
        for private in [
            "/work",
            "/root",
            "/home",
            "/tmp",
            env!("CARGO_MANIFEST_DIR"),
        ] {
            assert!(
                !text.contains(private),
                "reflection shows the path {private}"
            );
        }
    }
    println!("auth: {tried} unauthenticated mutation attempts, all 401 / UNAUTHENTICATED");
}

/// The binary with `RUST_LOG=trace` and a token: after authenticated,
/// unauthenticated and wrong-token calls over REST, gRPC and WebSocket, the
/// token appears nowhere in the logs.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_token_never_appears_in_the_logs() {
    const TOKEN: &str = "tok-Zq8Lw2NvY4kP";
    let tmp = tempfile::tempdir().unwrap();
    let mut server = crate::helpers::start_server(
        tmp.path(),
        &[("KINSERVE_API_TOKEN", TOKEN), ("RUST_LOG", "trace")],
        None,
    )
    .await;
    let client = reqwest::Client::new();
    let url = |p: &str| format!("{}{p}", server.http);
    for auth in [
        format!("Bearer {TOKEN}"),
        format!("Bearer {TOKEN}-wrong"),
        format!("Basic {TOKEN}"),
        "Bearer nope".to_owned(),
    ] {
        let _ = client
            .put(url("/v1/robots/logged"))
            .header("authorization", &auth)
            .json(&planar_model("logged"))
            .send()
            .await
            .unwrap();
        let _ = client
            .delete(url("/v1/robots/nothing"))
            .header("authorization", &auth)
            .send()
            .await
            .unwrap();
        let mut g = KinematicsServiceClient::connect(server.grpc.clone())
            .await
            .unwrap();
        let mut req = tonic::Request::new(pb::DeleteRobotRequest {
            name: "nothing".into(),
            ..Default::default()
        });
        req.metadata_mut()
            .insert("authorization", auth.parse().unwrap());
        let _ = g.delete_robot(req).await;
    }
    let _ = client
        .post(url("/v1/robots"))
        .json(&planar_model("x"))
        .send()
        .await;
    let (mut ws, _) = tokio_tungstenite::connect_async(format!(
        "{}/v1/robots/logged/fk/stream",
        server.http.replace("http://", "ws://")
    ))
    .await
    .unwrap();
    ws.send(Message::Text(r#"{"id": 1, "joints": [0, 0]}"#.into()))
        .await
        .unwrap();
    assert!(next_text(&mut ws).await.unwrap()["pose"].is_object());
    drop(ws);
    assert_eq!(
        client
            .get(url("/v1/robots/logged"))
            .send()
            .await
            .unwrap()
            .status(),
        200,
        "the authenticated PUT went through"
    );
    server.terminate();
    let logs = server.stderr();
    assert!(
        logs.len() > 1000,
        "trace logs were written: {} bytes",
        logs.len()
    );
    assert!(!logs.contains(TOKEN), "the token is in the logs");
    assert!(
        !logs.contains(&TOKEN[4..]),
        "part of the token is in the logs"
    );
    println!(
        "token in logs: {} bytes of trace logs checked, token absent",
        logs.len()
    );
}
