//! No client can take the CPU: the attacks of a hostile run (issue 22) from
//! 127.0.0.1 against the binary at default settings, while a well-behaved
//! client on 127.0.0.2 asks for FK every 50 ms and `/healthz`; every one of
//! its answers must be correct and within 1 s, the server's peak RSS within
//! 300 MiB, and its CPU back to idle within 2 s of the attackers leaving.
//! Each test prints the well-behaved client's p50/p99 (SECURITY.md has them).

use std::time::Duration;

use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use serde_json::{Value, json};

use crate::helpers::*;

/// An IK target puma560 cannot reach: every target takes its whole time limit.
fn unreachable_targets(n: usize) -> Vec<Value> {
    (0..n)
        .map(|_| json!({"position": [4.0, 0, 0], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}}))
        .collect()
}

fn unreachable_pb_targets(n: usize) -> Vec<pb::IkTarget> {
    let target = pb::IkTarget {
        position: Some(pb::Vector3 {
            x: 4.0,
            y: 0.0,
            z: 0.0,
        }),
        quaternion: Some(pb::Quaternion {
            w: 1.0,
            ..Default::default()
        }),
        ..Default::default()
    };
    vec![target; n]
}

async fn server() -> (tempfile::TempDir, Server) {
    let dir = tempfile::tempdir().unwrap();
    let server = start_server(dir.path(), &[], None).await;
    (dir, server)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn abandoned_ik_floods_are_refused_or_stopped_and_leave_the_cpu() {
    let (_dir, server) = server().await;
    let witness = Witness::start(&server.http);
    // gRPC: 200 IK batches of 400 unreachable targets at once, each with a
    // 50 ms deadline (tonic sends grpc-timeout), over 4 connections.
    let mut calls = Vec::new();
    for c in 0..4 {
        let client = KinematicsServiceClient::connect(server.grpc.clone())
            .await
            .unwrap();
        for _ in 0..50 {
            let mut g = client.clone();
            let _ = c;
            calls.push(tokio::spawn(async move {
                let mut req = tonic::Request::new(pb::InverseKinematicsBatchRequest {
                    robot: "puma560".into(),
                    targets: unreachable_pb_targets(400),
                    ..Default::default()
                });
                req.set_timeout(Duration::from_millis(50));
                g.inverse_kinematics_batch(req).await.map(|_| ())
            }));
        }
    }
    let mut codes = std::collections::BTreeMap::new();
    for call in calls {
        let code = match call.await.unwrap() {
            Ok(()) => "OK".to_string(),
            // The server may close a connection whose client resets its
            // calls in a flood (h2's reset limit): the client's own transport
            // error, not a status the server sent.
            Err(s)
                if s.code() == tonic::Code::Unknown
                    && std::error::Error::source(&s)
                        .is_some_and(|e| e.is::<tonic::transport::Error>()) =>
            {
                "transport error (connection closed)".to_string()
            }
            Err(s) => format!("{:?}", s.code()),
        };
        *codes.entry(code).or_insert(0) += 1;
    }
    println!("gRPC IK flood: {codes:?}");
    assert!(
        !codes.contains_key("OK"),
        "no batch of unreachable targets ends in 50 ms: {codes:?}"
    );
    assert!(
        !codes.contains_key("Internal") && !codes.contains_key("Unknown"),
        "{codes:?}"
    );
    // REST: 150 IK batches whose clients hang up 0.1 s after sending.
    let attacker = client_from([127, 0, 0, 1]);
    let mut posts = Vec::new();
    for _ in 0..150 {
        let req = attacker
            .post(format!("{}/v1/robots/puma560/ik/batch", server.http))
            .json(&json!({"targets": unreachable_targets(400)}))
            .timeout(Duration::from_millis(100));
        posts.push(tokio::spawn(
            async move { req.send().await.map(|r| r.status()) },
        ));
    }
    for p in posts {
        // Refused at once (503) or abandoned (the client's timeout).
        if let Ok(status) = p.await.unwrap() {
            assert_eq!(
                status, 503,
                "an IK batch of unreachable targets cannot succeed in 0.1 s"
            );
        }
    }
    assert_idle_after_attack(&server, "IK floods").await;
    witness.finish("IK floods").await;
    assert_memory_bounded(&server, "IK floods");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn ik_batches_of_one_client_do_not_starve_anothers_batches() {
    let (_dir, server) = server().await;
    let witness = Witness::start(&server.http);
    // One client keeps 3 IK batches in flight (each runs up to 15 s) …
    let attacker = client_from([127, 0, 0, 1]);
    let url = format!("{}/v1/robots/puma560/ik/batch", server.http);
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let mut loops = Vec::new();
    for _ in 0..3 {
        let (attacker, url, stop) = (attacker.clone(), url.clone(), stop.clone());
        loops.push(tokio::spawn(async move {
            while !stop.load(std::sync::atomic::Ordering::Acquire) {
                let sent = attacker
                    .post(&url)
                    .json(&json!({"targets": unreachable_targets(400)}))
                    .timeout(Duration::from_secs(3))
                    .send()
                    .await;
                if let Ok(r) = sent {
                    assert!(r.status() == 200 || r.status() == 503, "{}", r.status());
                }
            }
        }));
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    // … while another asks for 2-configuration FK batches: each answered within 1 s.
    let other = client_from(WITNESS_ADDR);
    let q = [[0.1, 0.2, 0.3, 0.4, 0.5, 0.6], [0.0; 6]];
    for _ in 0..20 {
        let start = std::time::Instant::now();
        let r = other
            .post(format!("{}/v1/robots/puma560/fk/batch", server.http))
            .json(&json!({"configurations": q}))
            .send()
            .await
            .unwrap();
        let took = start.elapsed();
        assert_eq!(r.status(), 200, "{}", r.text().await.unwrap_or_default());
        let v: Value = r.json().await.unwrap();
        assert_eq!(v["poses"].as_array().map(Vec::len), Some(2));
        assert!(
            took <= SERVED_WITHIN,
            "an FK batch of 2 waited {took:?} behind another client's IK batches"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    stop.store(true, std::sync::atomic::Ordering::Release);
    for l in loops {
        l.abort();
    }
    assert_idle_after_attack(&server, "IK batches vs FK batches").await;
    witness.finish("IK batches vs FK batches").await;
    assert_memory_bounded(&server, "IK batches vs FK batches");
}

/// The closed-form attack model: 8 twisted revolute rows, then identity
/// fixed rows up to the default link limit.
fn costly_closed_form_model(name: &str) -> Value {
    let mut links: Vec<Value> = (0..8)
        .map(|i| json!({"joint": "revolute", "a": 0.1 + 0.01 * i as f64, "alpha": 17, "d": 0.05, "theta": 0}))
        .collect();
    links.extend(
        (0..248).map(|_| json!({"joint": "fixed", "a": 0, "alpha": 0, "d": 0, "theta": 0})),
    );
    json!({"name": name, "convention": "standard", "angle_unit": "deg", "length_unit": "m", "links": links})
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn closed_forms_of_a_costly_model_do_not_stall_the_server() {
    let (_dir, server) = server().await;
    let attacker = client_from([127, 0, 0, 1]);
    let r = attacker
        .post(format!("{}/v1/robots", server.http))
        .json(&costly_closed_form_model("twisted_tail"))
        .send()
        .await
        .unwrap();
    let registered = r.status();
    assert!(
        registered == 201 || registered == 422 || registered == 413,
        "{registered}"
    );
    let witness = Witness::start(&server.http);
    let mut reads = Vec::new();
    for _ in 0..4 {
        let req = attacker.get(format!(
            "{}/v1/robots/twisted_tail/closed-form",
            server.http
        ));
        reads.push(tokio::spawn(
            async move { req.send().await.map(|r| r.status()) },
        ));
    }
    let mut statuses = Vec::new();
    for r in reads {
        statuses.push(r.await.unwrap().unwrap().as_u16());
    }
    println!("closed form of the costly model: registration {registered}, reads {statuses:?}");
    assert!(
        statuses.contains(&413),
        "one read computes it: {statuses:?}"
    );
    for s in &statuses {
        assert!(
            [413, 503].contains(s),
            "past the work limit, or the client's share busy: {statuses:?}"
        );
    }
    // Computed once per version: later reads are answered from the cache, at once.
    for _ in 0..4 {
        let start = std::time::Instant::now();
        let r = attacker
            .get(format!(
                "{}/v1/robots/twisted_tail/closed-form",
                server.http
            ))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 413);
        let p: Value = r.json().await.unwrap();
        assert_eq!(p["errors"][0]["field"], "links", "{p}");
        assert!(start.elapsed() <= SERVED_WITHIN);
    }
    assert_idle_after_attack(&server, "closed forms").await;
    witness.finish("closed forms").await;
    assert_memory_bounded(&server, "closed forms");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn one_client_cannot_hold_every_stream_and_silent_streams_close() {
    let dir = tempfile::tempdir().unwrap();
    let server = start_server(
        dir.path(),
        &[("KINSERVE_STREAM_FIRST_MESSAGE_TIMEOUT", "2s")],
        None,
    )
    .await;
    let ws_url = format!("{}/v1/robots/puma560/fk/stream", server.ws());
    // One client opens as many WebSockets as it is given (and sends nothing).
    let mut held = Vec::new();
    let mut refused = 0;
    for _ in 0..80 {
        match ws_connect_from([127, 0, 0, 1], &ws_url).await {
            Ok(sock) => held.push(sock),
            Err(status) => {
                assert_eq!(status, 503);
                refused += 1;
            }
        }
    }
    println!(
        "streams: one client got {} of 64, {refused} refused",
        held.len()
    );
    assert!(
        held.len() <= 32,
        "one client holds {} streams, more than half",
        held.len()
    );
    // Another client still opens one and is answered.
    let mut mine = ws_connect_from(WITNESS_ADDR, &ws_url)
        .await
        .expect("another client's stream opens");
    let reply = ws_ask(&mut mine, &json!({"id": 1, "joints": [0, 0, 0, 0, 0, 0]})).await;
    assert!(reply["pose"].is_object(), "{reply}");
    // The silent ones are closed after the first-message timeout.
    tokio::time::sleep(Duration::from_secs(3)).await;
    let mut closed = 0;
    for sock in &mut held {
        if ws_is_closed(sock).await {
            closed += 1;
        }
    }
    assert_eq!(
        closed,
        held.len(),
        "silent streams are closed after the first-message timeout"
    );
}

#[tokio::test]
async fn a_jacobian_batch_whose_answer_cannot_fit_is_refused_before_computing() {
    let app = spawn_app_with(|c| c.max_buffered_response_bytes = 100_000).await;
    let body = json!({"configurations": configs(1000, 6)});
    let start = std::time::Instant::now();
    let p = problem(
        app.post("/v1/robots/puma560/jacobian/batch", &body).await,
        413,
    )
    .await;
    assert_eq!(fields(&p), ["configurations"]);
    let detail = p["detail"].as_str().unwrap();
    assert!(
        detail.contains("--max-buffered-response-bytes") && detail.contains("at most"),
        "{detail}"
    );
    assert!(start.elapsed() <= SERVED_WITHIN);
    // What fits is still answered.
    let small = json!({"configurations": configs(10, 6)});
    let r = app.post("/v1/robots/puma560/jacobian/batch", &small).await;
    assert_eq!(r.status(), 200);
}

/// A gRPC client whose connection comes from `from`.
async fn grpc_from(from: [u8; 4], url: &str) -> KinematicsServiceClient<tonic::transport::Channel> {
    let channel = tonic::transport::Endpoint::from_shared(url.to_owned())
        .unwrap()
        .local_address(Some(std::net::IpAddr::from(from)))
        .connect()
        .await
        .unwrap();
    KinematicsServiceClient::new(channel)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_client_holding_its_compute_share_is_refused_at_once_and_another_is_served() {
    let app = spawn_app_with(|c| c.compute_threads = 2).await;
    let attacker = grpc_from([127, 0, 0, 1], &app.grpc).await;
    // One long IK batch takes the attacker's one permit (its share of 2) …
    let mut busy = attacker.clone();
    let long = tokio::spawn(async move {
        busy.inverse_kinematics_batch(pb::InverseKinematicsBatchRequest {
            robot: "puma560".into(),
            targets: unreachable_pb_targets(40),
            ..Default::default()
        })
        .await
    });
    tokio::time::sleep(Duration::from_millis(300)).await;
    // … so its next one is refused at once,
    let mut again = attacker.clone();
    let start = std::time::Instant::now();
    let refused = again
        .inverse_kinematics_batch(pb::InverseKinematicsBatchRequest {
            robot: "puma560".into(),
            targets: unreachable_pb_targets(1),
            ..Default::default()
        })
        .await
        .expect_err("over its share");
    assert_eq!(
        refused.code(),
        tonic::Code::ResourceExhausted,
        "{refused:?}"
    );
    assert!(
        start.elapsed() <= SERVED_WITHIN,
        "refused at once, not queued"
    );
    // The refusal says whose share, of what, and what to do.
    let why = refused.message();
    for part in [
        "client 127.0.0.1 holds 1 of the server's 2 computations on the compute pool",
        "--client-share-percent of --compute-threads",
        "or retry in a second",
    ] {
        assert!(why.contains(part), "{why:?} says {part:?}");
    }
    // … and how long to wait: google.rpc.RetryInfo, REST's Retry-After.
    use tonic_types::StatusExt;
    let retry = refused
        .get_details_retry_info()
        .expect("a RetryInfo detail");
    assert_eq!(retry.retry_delay, Some(Duration::from_secs(1)));
    // A small FK batch is computed on the request's thread, as a single FK
    // is, so it is served even now; one past that size needs the pool and
    // is refused the same way.
    let fk_batch = |n: usize| pb::ForwardKinematicsBatchRequest {
        robot: "puma560".into(),
        configurations: vec![
            pb::JointConfiguration {
                joints: vec![0.1; 6]
            };
            n
        ],
        ..Default::default()
    };
    let small = again
        .forward_kinematics_batch(fk_batch(kinserve::service::FK_BATCH_INLINE))
        .await
        .expect("a small FK batch is served while the share is held");
    assert_eq!(
        small.into_inner().poses.len(),
        kinserve::service::FK_BATCH_INLINE
    );
    let large = again
        .forward_kinematics_batch(fk_batch(kinserve::service::FK_BATCH_INLINE + 1))
        .await
        .expect_err("a larger FK batch needs the share");
    assert_eq!(large.code(), tonic::Code::ResourceExhausted, "{large:?}");
    // … while another client's batch is computed.
    let mut other = grpc_from(WITNESS_ADDR, &app.grpc).await;
    let q = kinserve::api::grpc::pb::JointConfiguration {
        joints: vec![0.1; 6],
    };
    let served = other
        .forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "puma560".into(),
            configurations: vec![q.clone(), q],
            ..Default::default()
        })
        .await
        .expect("another client's batch is served")
        .into_inner();
    assert_eq!(served.poses.len(), 2);
    // The single FK path never waits for the pool.
    let fk = again
        .forward_kinematics(pb::ForwardKinematicsRequest {
            robot: "puma560".into(),
            joints: vec![0.0; 6],
            ..Default::default()
        })
        .await;
    assert!(fk.is_ok(), "{fk:?}");
    long.abort();
}

#[tokio::test]
async fn behind_a_trusted_proxy_the_forwarded_address_is_the_client() {
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    async fn open(app: &TestApp, forwarded: &str) -> Result<Ws, u16> {
        let url = format!("{}/v1/robots/puma560/fk/stream", app.ws);
        let mut req = url.into_client_request().unwrap();
        req.headers_mut()
            .insert("x-forwarded-for", forwarded.parse().unwrap());
        match tokio_tungstenite::connect_async(req).await {
            Ok((ws, _)) => Ok(ws),
            Err(tokio_tungstenite::tungstenite::Error::Http(r)) => Err(r.status().as_u16()),
            Err(e) => panic!("{e}"),
        }
    }
    // Two streams, one per client.
    let trusting = spawn_app_with(|c| {
        c.max_streams = 2;
        c.trust_forwarded_for = true;
    })
    .await;
    let _a = open(&trusting, "198.51.100.1").await.expect("first client");
    assert_eq!(
        open(&trusting, "203.0.113.5, 198.51.100.1").await.err(),
        Some(503),
        "same last hop, same client"
    );
    let _b = open(&trusting, "198.51.100.2")
        .await
        .expect("another client");
    // Not trusted (the default): the header is ignored, every socket is the peer's.
    let plain = spawn_app_with(|c| c.max_streams = 2).await;
    let _c = open(&plain, "198.51.100.1").await.expect("first");
    assert_eq!(
        open(&plain, "198.51.100.2").await.err(),
        Some(503),
        "the header does not make a new client"
    );
}
