//! Slow and greedy clients: slowloris connections, floods of batches, and a
//! panicking handler.

use std::sync::Arc;
use std::time::{Duration, Instant};

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

/// How long a refusal may take, from sending a small request to its 503 /
/// RESOURCE_EXHAUSTED, while the permits are held by work that runs for
/// seconds: a queued request would wait for that work. Loose (a busy
/// two-core runner), a fraction of how long the holders run.
const REFUSED_WITHIN: Duration = Duration::from_secs(1);

/// One flood answer: the protocol's outcome and how long it took.
#[derive(Debug)]
enum Flood {
    Served,
    Refused(Duration),
}

/// 200 concurrent REST batches of 2,000 puma560 configurations: 200 or an
/// immediate 503 problem+json with Retry-After, nothing else, every one answered.
async fn rest_flood(app: &TestApp) -> Vec<tokio::task::JoinHandle<Flood>> {
    let configs: Vec<[f64; 6]> = (0..2000).map(|i| [i as f64 * 1e-5; 6]).collect();
    let body = Arc::new(json!({"configurations": configs}));
    let client = reqwest::Client::new();
    let url = format!("{}/v1/robots/puma560/fk/batch", app.http);
    (0..200)
        .map(|_| {
            let (client, body, url) = (client.clone(), body.clone(), url.clone());
            tokio::spawn(async move {
                let t = Instant::now();
                let r = client.post(url).json(&*body).send().await.unwrap();
                let took = t.elapsed();
                let status = r.status().as_u16();
                let retry = r.headers().get("retry-after").is_some();
                let ct = r
                    .headers()
                    .get("content-type")
                    .map(|v| v.to_str().unwrap().to_owned());
                let body = r.bytes().await.expect("the answer is read whole");
                match (status, retry, ct.as_deref()) {
                    (200, _, _) => {
                        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
                        assert_eq!(v["poses"].as_array().map(Vec::len), Some(2000));
                        Flood::Served
                    }
                    (503, true, Some("application/problem+json")) => Flood::Refused(took),
                    other => panic!("REST flood answer {other:?}"),
                }
            })
        })
        .collect()
}

/// The same flood over gRPC on one channel: OK or RESOURCE_EXHAUSTED.
async fn grpc_flood(app: &TestApp) -> Vec<tokio::task::JoinHandle<Flood>> {
    let channel = crate::helpers::channel(app).await;
    (0..200)
        .map(|_| {
            let mut c = KinematicsServiceClient::new(channel.clone());
            let configurations = (0..2000)
                .map(|i| pb::JointConfiguration {
                    joints: vec![i as f64 * 1e-5; 6],
                })
                .collect();
            tokio::spawn(async move {
                let t = Instant::now();
                let r = c
                    .forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
                        robot: "puma560".into(),
                        configurations,
                        options: None,
                        ..Default::default()
                    })
                    .await;
                match r {
                    Ok(answer) => {
                        assert_eq!(answer.into_inner().poses.len(), 2000);
                        Flood::Served
                    }
                    Err(s) if s.code() == Code::ResourceExhausted => Flood::Refused(t.elapsed()),
                    Err(other) => panic!("gRPC flood answer {other:?}"),
                }
            })
        })
        .collect()
}

/// Served and refused counts of one protocol's flood, and its slowest refusal
/// (reported: under a flood it includes uploading and scheduling, so the
/// "at once" bound is checked by the probe test below); fails unless every
/// request was answered, some were served and some refused.
async fn tally(what: &str, tasks: Vec<tokio::task::JoinHandle<Flood>>) -> (usize, usize, Duration) {
    let n = tasks.len();
    let (mut ok, mut refused, mut slowest) = (0, 0, Duration::ZERO);
    for t in tasks {
        match t.await.expect("every flood request is answered") {
            Flood::Served => ok += 1,
            Flood::Refused(took) => {
                refused += 1;
                slowest = slowest.max(took);
            }
        }
    }
    assert_eq!(ok + refused, n, "{what}: every request answered");
    assert!(ok > 0, "{what}: none served ({refused} refused)");
    assert!(
        refused > 0,
        "{what}: none refused ({ok} served): a queue, not a budget"
    );
    (ok, refused, slowest)
}

/// A flood of concurrent batch requests against a small concurrency limit,
/// per protocol: every REST request is answered 200 or 503 (problem+json,
/// Retry-After), every gRPC call OK or RESOURCE_EXHAUSTED; each protocol
/// has some served and some refused; the server answers normally
/// afterwards. (That refusals come at once: the probe test below.) One client (127.0.0.1) may hold the whole budget
/// (`client_share_percent = 100`): the test is about the total.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_flood_of_batches_gets_503_and_resource_exhausted_not_a_queue() {
    // The limit is below the 4 worker threads: gRPC batch handlers hold their
    // permit only while computing, so they can only be refused when more of
    // them compute at once than the limit allows.
    let app = spawn_app_with(|c| {
        c.max_concurrent_requests = 2;
        c.client_share_percent = 100;
    })
    .await;
    let rest = rest_flood(&app).await;
    let grpc = grpc_flood(&app).await;
    let (ok, refused, rest_slowest) = tally("REST", rest).await;
    let (gok, grefused, grpc_slowest) = tally("gRPC", grpc).await;
    // Afterwards: normal service.
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    checker.finish().await;
    println!(
        "flood (limit 2): REST {ok} ok / {refused} refused (slowest refusal {rest_slowest:?}), \
         gRPC {gok} ok / {grefused} refused (slowest refusal {grpc_slowest:?})"
    );
}

/// `n` unreachable IK targets (4 m away): a batch of them runs until the IK
/// batch time limit.
fn unreachable_targets(n: usize) -> Vec<serde_json::Value> {
    let target = json!({"position": [4.0, 0, 0], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}});
    vec![target; n]
}

/// Refusals come at once on both protocols: with both request permits held
/// by IK batches that run until their time limit (2 s: half the 4 s request
/// timeout), a small REST FK request is answered 503 `overloaded` and a gRPC
/// FK call RESOURCE_EXHAUSTED, each within [`REFUSED_WITHIN`] and while the
/// holders still run (a queue would answer them after the holders, 200).
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn refusals_past_the_request_limit_come_at_once_on_both_protocols() {
    let app = spawn_app_with(|c| {
        c.max_concurrent_requests = 2;
        c.client_share_percent = 100;
        c.request_timeout = Duration::from_secs(4);
    })
    .await;
    let started = Instant::now();
    let holders: Vec<_> = (0..2)
        .map(|_| {
            let req = app
                .client
                .post(format!("{}/v1/robots/puma560/ik/batch", app.http))
                .json(&json!({"targets": unreachable_targets(400)}));
            tokio::spawn(async move { req.send().await.map(|r| r.status().as_u16()) })
        })
        .collect();
    // The holders are admitted once a probe is refused; until then a probe
    // may still get a permit (and is served).
    let mut probes = 0;
    let rest_refusal = loop {
        probes += 1;
        let t = Instant::now();
        let r = app
            .post(
                "/v1/robots/puma560/fk",
                &json!({"joints": [0, 0, 0, 0, 0, 0]}),
            )
            .await;
        let took = t.elapsed();
        if r.status() == 503 {
            let p: serde_json::Value = r.json().await.unwrap();
            assert_eq!(p["type"], "urn:kinserve:problem:overloaded", "{p}");
            break took;
        }
        assert_eq!(r.status(), 200);
        assert!(probes < 100, "no probe refused while two IK batches run");
        tokio::time::sleep(Duration::from_millis(10)).await;
    };
    let mut grpc = app.grpc_client().await;
    let t = Instant::now();
    let call = grpc
        .forward_kinematics(pb::ForwardKinematicsRequest {
            robot: "puma560".into(),
            joints: vec![0.0; 6],
            options: None,
        })
        .await;
    let grpc_refusal = t.elapsed();
    assert_eq!(
        call.map(drop).map_err(|s| s.code()),
        Err(Code::ResourceExhausted)
    );
    let holders_still_ran = holders.iter().all(|h| !h.is_finished());
    let probed_at = started.elapsed();
    for h in holders {
        let status = h.await.unwrap().expect("the IK batch is answered");
        assert!(status == 200 || status == 503, "IK holder: {status}");
    }
    let holders_ran = started.elapsed();
    println!(
        "refusal at once (limit 2): REST 503 in {rest_refusal:?}, gRPC RESOURCE_EXHAUSTED in \
         {grpc_refusal:?}, {probed_at:?} after start; the IK holders ran {holders_ran:?}"
    );
    assert!(
        holders_still_ran,
        "the holders ended before the probes: nothing was tested"
    );
    for (what, took) in [("REST", rest_refusal), ("gRPC", grpc_refusal)] {
        assert!(
            took <= REFUSED_WITHIN,
            "{what}: the refusal took {took:?} (> {REFUSED_WITHIN:?}): it waited, as if queued"
        );
    }
    fk_ok(&app, "planar_2dof", json!({"joints": [0, 0]})).await;
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
    use kinserve::service::{Service, ServiceLimits, WriteAccess};

    let limits = ServiceLimits::default();
    let registry = Registry::new(Box::new(MemoryStore));
    registry.load_builtins(None, &limits.model);
    let service = Arc::new(Service::new(registry, limits, WriteAccess::Open));
    service.set_ready(true);
    let config = kinserve::config::ServeConfig::for_tests(std::env::temp_dir());
    let state = AppState::new(AppInner {
        service,
        settings: config.rest_settings(),
        shutdown: tokio_util::sync::CancellationToken::new(),
        metrics: kinserve::telemetry::metrics_handle(),
        permits: kinserve::compute::FairBudget::new(
            "requests in flight",
            "--max-concurrent-requests",
            1,
            1,
        ),
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
