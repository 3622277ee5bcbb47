//! Slow and greedy clients: slowloris connections, floods of batches, and a
//! panicking handler.

use std::sync::Arc;
use std::time::Duration;

use futures_util::SinkExt;
use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use serde_json::json;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tonic::Code;

use crate::helpers::*;

// ---------------------------------------------------------------- slow clients

/// Reads from `s` until the server closes it (EOF or error), with a generous bound.
async fn server_closes(s: &mut TcpStream) -> bool {
    let mut buf = [0u8; 4096];
    tokio::time::timeout(EVENTUALLY, async {
        loop {
            match s.read(&mut buf).await {
                Ok(0) | Err(_) => return,
                Ok(_) => continue,
            }
        }
    })
    .await
    .is_ok()
}

/// Slowloris: connections that send nothing, half a request head, a head one
/// byte at a time, or part of the HTTP/2 preface are closed after the header
/// timeout; an idle kept-alive connection too. WebSocket upgrades are not
/// affected, and normal clients are served throughout.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn slowloris_connections_are_closed_after_the_header_timeout() {
    let app = spawn_app_with(|c| c.header_timeout = Duration::from_millis(300)).await;
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    let addr = addr_of(&app.http);
    let silent = TcpStream::connect(&addr).await.unwrap();
    let mut half = TcpStream::connect(&addr).await.unwrap();
    half.write_all(b"POST /v1/robots/planar_2dof/fk HTTP/1.1\r\nHost: x\r\nContent-Ty")
        .await
        .unwrap();
    let mut preface = TcpStream::connect(&addr).await.unwrap();
    preface.write_all(b"PRI * HTTP/2.0\r\n").await.unwrap();
    // One byte every 100 ms: each arrives well within any per-read timeout.
    let mut trickle = TcpStream::connect(&addr).await.unwrap();
    let trickler = tokio::spawn(async move {
        for b in b"GET /v1/robots HTTP/1.1\r\nHost: x\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa" {
            if trickle.write_all(&[*b]).await.is_err() {
                return (trickle, true);
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        (trickle, false)
    });
    // A complete request, then the connection is kept open idle.
    let mut idle = TcpStream::connect(&addr).await.unwrap();
    idle.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .unwrap();
    let mut buf = [0u8; 1024];
    let n = idle.read(&mut buf).await.unwrap();
    assert!(buf[..n].starts_with(b"HTTP/1.1 200"));
    // A WebSocket outlives the header timeout.
    let mut ws = open_ws(&app, "planar_2dof").await;

    for (name, mut s) in [
        ("silent", silent),
        ("half head", half),
        ("h2 preface", preface),
    ] {
        assert!(server_closes(&mut s).await, "{name} connection still open");
    }
    assert!(
        server_closes(&mut idle).await,
        "idle keep-alive connection still open"
    );
    let (mut trickle, cut_while_writing) = trickler.await.unwrap();
    assert!(
        cut_while_writing || server_closes(&mut trickle).await,
        "trickling connection still open"
    );
    tokio::time::sleep(Duration::from_millis(400)).await;
    ws.send(Message::Text(r#"{"id": 1, "joints": [0, 0]}"#.into()))
        .await
        .unwrap();
    assert_eq!(next_text(&mut ws).await.unwrap()["id"], 1);
    checker.finish().await;
}

// ---------------------------------------------------------------- overload

/// A flood of concurrent batch requests against a small concurrency limit:
/// every answer is 200 or an immediate 503 (REST, with Retry-After) /
/// RESOURCE_EXHAUSTED (gRPC), some are refused, none fails otherwise; the
/// server answers normally afterwards.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_flood_of_batches_gets_503_and_resource_exhausted_not_a_queue() {
    // The limit is below the 4 worker threads: gRPC batch handlers hold their
    // permit only while computing, so they can only be refused when more of
    // them compute at once than the limit allows.
    let app = spawn_app_with(|c| c.max_concurrent_requests = 2).await;
    let configs: Vec<[f64; 6]> = (0..2000).map(|i| [i as f64 * 1e-5; 6]).collect();
    let body = Arc::new(json!({"configurations": configs}));
    let client = reqwest::Client::new();
    let mut rest = Vec::new();
    for _ in 0..200 {
        let (client, body, url) = (
            client.clone(),
            body.clone(),
            format!("{}/v1/robots/puma560/fk/batch", app.http),
        );
        rest.push(tokio::spawn(async move {
            let r = client.post(url).json(&*body).send().await.unwrap();
            let status = r.status().as_u16();
            let retry = r.headers().get("retry-after").is_some();
            let ct = r
                .headers()
                .get("content-type")
                .map(|v| v.to_str().unwrap().to_owned());
            let _ = r.bytes().await;
            (status, retry, ct)
        }));
    }
    let channel = crate::helpers::channel(&app).await;
    let mut grpc = Vec::new();
    for _ in 0..200 {
        let mut c = KinematicsServiceClient::new(channel.clone());
        let configurations = (0..2000)
            .map(|i| pb::JointConfiguration {
                joints: vec![i as f64 * 1e-5; 6],
            })
            .collect();
        grpc.push(tokio::spawn(async move {
            c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
                robot: "puma560".into(),
                configurations,
                options: None,
            })
            .await
            .map(drop)
            .map_err(|s| s.code())
        }));
    }
    let (mut ok, mut refused) = (0, 0);
    for t in rest {
        match t.await.unwrap() {
            (200, _, _) => ok += 1,
            (503, true, Some(ct)) if ct == "application/problem+json" => refused += 1,
            other => panic!("REST flood answer {other:?}"),
        }
    }
    let (mut gok, mut grefused) = (0, 0);
    for t in grpc {
        match t.await.unwrap() {
            Ok(()) => gok += 1,
            Err(Code::ResourceExhausted) => grefused += 1,
            Err(other) => panic!("gRPC flood answer {other:?}"),
        }
    }
    assert!(ok > 0 && gok > 0, "some are served: {ok} {gok}");
    assert!(refused + grefused > 0, "some are refused");
    // Afterwards: normal service.
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    checker.finish().await;
    println!(
        "flood (limit 2): REST {ok} ok / {refused} refused, gRPC {gok} ok / {grefused} refused"
    );
}

// ---------------------------------------------------------------- panics

/// A handler that panics gets a problem+json 500, the panic does not take the
/// server down, and its admission permit is released (with a limit of one
/// request in flight, later requests are still admitted).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panicking_handler_is_a_500_problem_and_the_server_survives() {
    use axum::routing::get;
    use kinserve::api::rest::{AppInner, AppState, router_with};
    use kinserve::registry::{MemoryStore, Registry};
    use kinserve::service::{Service, ServiceLimits};

    let limits = ServiceLimits::default();
    let registry = Registry::new(Box::new(MemoryStore));
    registry.load_builtins(None, &limits.model);
    let service = Arc::new(Service::new(registry, limits, None));
    service.set_ready(true);
    let config = kinserve::config::ServeConfig::for_tests(std::env::temp_dir());
    let state = AppState::new(AppInner {
        service,
        settings: config.rest_settings(),
        shutdown: tokio_util::sync::CancellationToken::new(),
        metrics: kinserve::telemetry::metrics_handle(),
        permits: kinserve::compute::FairBudget::new(1, 1),
        streams: config.stream_budget(),
        request_bytes: config.request_byte_budget(),
    });
    let boom = axum::Router::new()
        .route(
            "/boom",
            get(|| async {
                panic!("boom: a bug");
                #[allow(unreachable_code)]
                ""
            }),
        )
        .route(
            "/v1/robots/{name}/boom",
            get(
                |axum::extract::Path(name): axum::extract::Path<String>| async move {
                    let v: Vec<u8> = name.into_bytes();
                    #[allow(clippy::indexing_slicing)]
                    let b = v[1000]; // indexing on request data: the kind of bug the lints forbid
                    b.to_string()
                },
            ),
        );
    let router = router_with(state, boom);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, router).await });
    let client = reqwest::Client::new();
    for path in ["/boom", "/v1/robots/x/boom", "/boom"] {
        let r = client
            .get(format!("http://{addr}{path}"))
            .send()
            .await
            .unwrap();
        let p = crate::helpers::problem(r, 500).await;
        assert_eq!(p["type"], "urn:kinserve:problem:internal");
        assert!(
            !p["detail"].as_str().unwrap().contains("boom"),
            "the panic message stays in the log: {p}"
        );
    }
    // Same server, same single permit: still answering.
    let r = client
        .post(format!("http://{addr}/v1/robots/puma560/fk"))
        .json(&json!({"joints": [0, 0, 0, 0, 0, 0]}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
}
