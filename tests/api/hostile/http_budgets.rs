//! Clients that hold the HTTP side hostage (issue 13, items 2, 4, 7, 12 and
//! the readiness drain): bodies that never arrive, answers nobody reads, big
//! uploads refused early, malformed framing headers, stalled request heads on
//! kept-alive connections, and `/readyz` during the shutdown grace.
//!
//! Each attack on resources runs against the real binary at its default
//! settings (only the time limits are shortened), while the parallel FK client
//! checks every answer, and the server's resident memory is sampled
//! throughout (bound: 300 MiB).

use std::time::{Duration, Instant};

use futures_util::future::join_all;
use serde_json::json;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpSocket, TcpStream};

use crate::helpers::*;

/// Highest resident memory the server may reach under any of these attacks.
const RSS_BOUND_MIB: u64 = 300;

fn ws_of(http: &str) -> String {
    http.replacen("http://", "ws://", 1)
}

async fn fk_served(http: &str) {
    let r = reqwest::Client::new()
        .post(format!("{http}/v1/robots/puma560/fk"))
        .json(&json!({"joints": [0, 0, 0, 0, 0, 0]}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let v: serde_json::Value = r.json().await.unwrap();
    assert!(v["pose"].is_object(), "{v}");
}

/// The server's peak resident memory is within [`RSS_BOUND_MIB`]: the
/// kernel's `VmHWM` (which the 50 ms samples can miss a short peak of), or
/// the highest sample where that is higher (the kernel's RSS counters are
/// per-CPU and may lag by a few pages).
async fn assert_rss_bounded(watch: RssWatch, what: &str) {
    let (max, hwm) = watch.finish().await;
    eprintln!("{what}: server VmRSS max sampled {max} MiB, VmHWM {hwm} MiB");
    assert!(hwm > 0, "{what}: VmHWM read as {hwm} MiB");
    let peak = hwm.max(max);
    assert!(
        peak <= RSS_BOUND_MIB,
        "{what}: peak RSS (VmHWM {hwm} MiB, sampled {max} MiB) > {RSS_BOUND_MIB} MiB"
    );
}

// ---------------------------------------------------------------- bodies that never arrive

/// 1,030 HTTP/1.1 connections (more than the 1,024 request permits) send
/// their headers and one byte of a 100-byte body, then nothing: they hold no
/// permit (FK is served meanwhile), and each is answered 408 problem+json
/// after the body timeout and closed.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn http1_bodies_that_never_arrive_hold_no_permit_and_get_408() {
    let tmp = tempfile::tempdir().unwrap();
    let server = start_server(tmp.path(), &[("KINSERVE_BODY_TIMEOUT", "5s")], None).await;
    let watch = RssWatch::start(server.pid());
    let checker = Checker::start(&server.http, &server.grpc, &ws_of(&server.http)).await;
    let addr = addr_of(&server.http);
    let head = b"POST /v1/robots/puma560/fk HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 100\r\n\r\n{";
    let mut stalled = Vec::new();
    for _ in 0..1030 {
        let mut s = TcpStream::connect(&addr).await.unwrap();
        s.write_all(head).await.unwrap();
        stalled.push(s);
    }
    fk_served(&server.http).await;
    let answers = join_all(stalled.iter_mut().map(|s| async move {
        let head = read_head(s, Duration::from_secs(20)).await;
        let closed = read_to_close(s, EVENTUALLY).await.is_some();
        (head, closed)
    }))
    .await;
    for (i, (head, closed)) in answers.iter().enumerate() {
        let head = head.as_deref().unwrap_or("");
        assert!(head.starts_with("HTTP/1.1 408"), "connection {i}: {head:?}");
        assert!(
            head.contains("application/problem+json"),
            "connection {i}: {head}"
        );
        assert!(*closed, "connection {i} still open after its 408");
    }
    checker.finish().await;
    assert_rss_bounded(watch, "1,030 stalled HTTP/1.1 bodies").await;
}

/// 6 h2c connections × 200 streams announcing `content-length: 100` and
/// sending no body: FK is served meanwhile, and every stream is answered 408
/// after the body timeout.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn h2c_streams_whose_bodies_never_arrive_get_408() {
    let tmp = tempfile::tempdir().unwrap();
    let server = start_server(tmp.path(), &[("KINSERVE_BODY_TIMEOUT", "5s")], None).await;
    let watch = RssWatch::start(server.pid());
    let checker = Checker::start(&server.http, &server.grpc, &ws_of(&server.http)).await;
    let addr = addr_of(&server.http);
    let mut pending = Vec::new();
    let mut held = Vec::new();
    for _ in 0..6 {
        let tcp = TcpStream::connect(&addr).await.unwrap();
        let (client, conn) = h2::client::handshake(tcp).await.unwrap();
        tokio::spawn(conn);
        for _ in 0..200 {
            let mut ready = client.clone().ready().await.unwrap();
            let req = axum::http::Request::post(format!("http://{addr}/v1/robots/puma560/fk"))
                .header("content-type", "application/json")
                .header("content-length", "100")
                .body(())
                .unwrap();
            let (resp, send) = ready.send_request(req, false).unwrap();
            pending.push(resp);
            held.push(send);
        }
    }
    fk_served(&server.http).await;
    let statuses = join_all(pending.into_iter().map(|resp| async move {
        match tokio::time::timeout(Duration::from_secs(20), resp).await {
            Ok(Ok(r)) => r.status().as_u16(),
            other => panic!("stream not answered: {other:?}"),
        }
    }))
    .await;
    assert!(statuses.iter().all(|s| *s == 408), "{statuses:?}");
    assert_eq!(statuses.len(), 1200);
    drop(held);
    checker.finish().await;
    assert_rss_bounded(watch, "1,200 stalled h2c bodies").await;
}

// ---------------------------------------------------------------- answers nobody reads

/// A batch request of `n` configurations of `robot` (planar_2dof or puma560;
/// 10,000 of planar_2dof: a 3.1 MB answer, of puma560: 5.2 MB).
fn batch_request(robot: &str, n: usize) -> Vec<u8> {
    let joints = if robot == "puma560" { 6 } else { 2 };
    let configs: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            let x = (i % 10_000) as f64 * 1e-4;
            (0..joints)
                .map(|j| if j % 2 == 0 { x } else { -x })
                .collect()
        })
        .collect();
    let body = serde_json::to_vec(&json!({ "configurations": configs })).unwrap();
    let mut req = format!(
        "POST /v1/robots/{robot}/fk/batch HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    )
    .into_bytes();
    req.extend_from_slice(&body);
    req
}

/// 64 clients with a 4 KiB receive buffer ask for 10,000-pose batch answers
/// (3.1 MB each, 197 MB in all, three times the budget) and never read: the answers the response
/// byte budget (64 MiB) holds stay within it (the others are refused 503),
/// the server's memory stays bounded, FK is served throughout, and every
/// connection is closed (after the write timeout, or the header timeout once
/// an answer went out whole) instead of being kept forever.
///
/// Batches take turns in the batch slots (one on two cores), so on a slow,
/// busy machine a late request may wait out the request timeout (503); the
/// reads wait longer than that timeout plus the header timeout, so the test
/// does not depend on how fast a debug build encodes 64 answers.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn unread_batch_answers_are_bounded_and_dropped_after_the_write_timeout() {
    const CLIENTS: usize = 64;
    const REQUEST_TIMEOUT: Duration = Duration::from_secs(20);
    let tmp = tempfile::tempdir().unwrap();
    let env = [
        ("KINSERVE_WRITE_TIMEOUT", "2s"),
        ("KINSERVE_REQUEST_TIMEOUT", "20s"),
        ("KINSERVE_HEADER_TIMEOUT", "10s"),
    ];
    let server = start_server(tmp.path(), &env, None).await;
    let watch = RssWatch::start(server.pid());
    let checker = Checker::start(&server.http, &server.grpc, &ws_of(&server.http)).await;
    let addr: std::net::SocketAddr = addr_of(&server.http).parse().unwrap();
    let request = std::sync::Arc::new(batch_request("planar_2dof", 10_000));
    let started = Instant::now();
    let conns = join_all((0..CLIENTS).map(|_| {
        let request = request.clone();
        async move {
            let socket = TcpSocket::new_v4().unwrap();
            socket.set_recv_buffer_size(4096).unwrap();
            let mut s = socket.connect(addr).await.unwrap();
            s.write_all(&request).await.unwrap();
            s
        }
    }))
    .await;
    fk_served(&server.http).await;
    // Nobody reads for a while: well past the write timeout.
    tokio::time::sleep(Duration::from_secs(4)).await;
    fk_served(&server.http).await;
    let results = join_all(conns.into_iter().map(|mut s| async move {
        // Every request is answered within the request timeout (a batch
        // being encoded then finishes), and every connection is closed at
        // most a header timeout (10 s) after its answer went out.
        let status = read_status(&mut s, REQUEST_TIMEOUT * 2).await;
        let rest = read_to_close(&mut s, REQUEST_TIMEOUT + Duration::from_secs(10)).await;
        (status, rest)
    }))
    .await;
    eprintln!("unread batches: done after {:?}", started.elapsed());
    let mut by_status = std::collections::BTreeMap::<u16, usize>::new();
    for (i, (status, rest)) in results.iter().enumerate() {
        let status = status.unwrap_or_else(|| panic!("request {i} was never answered"));
        assert!(
            rest.is_some(),
            "connection {i} was still open after its {status}"
        );
        *by_status.entry(status).or_default() += 1;
    }
    let whole = results
        .iter()
        .filter(|(_, r)| *r >= Some(3_080_535))
        .count();
    eprintln!("unread batches: answers by status {by_status:?}, {whole} read whole in the end");
    let (served, refused) = (by_status.get(&200), by_status.get(&503));
    assert_eq!(
        served.unwrap_or(&0) + refused.unwrap_or(&0),
        CLIENTS,
        "only 200 and 503: {by_status:?}"
    );
    // 197 MB of answers against a 64 MiB budget: some fit, the rest do not.
    assert!(served.is_some() && refused.is_some(), "{by_status:?}");
    checker.finish().await;
    assert_rss_bounded(watch, "64 unread 10,000-pose batch answers").await;
}

/// An answer larger than the kernel's socket buffers (about 12 MB) to a
/// client that reads nothing is cut off after the write timeout: the
/// connection closes before the answer's last chunk was sent. (Large batch
/// answers are produced a frame at a time, so they go out chunked.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_answer_nobody_reads_is_cut_off_after_the_write_timeout() {
    let app = spawn_app_with(|c| {
        c.write_timeout = Duration::from_secs(1);
        c.max_batch = 20_000;
    })
    .await;
    let addr: std::net::SocketAddr = addr_of(&app.http).parse().unwrap();
    let socket = TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let mut s = socket.connect(addr).await.unwrap();
    let request = batch_request("puma560", 20_000);
    s.write_all(&request).await.unwrap();
    let head = read_head(&mut s, EVENTUALLY).await.unwrap();
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert!(
        head.lines().any(|l| l == "transfer-encoding: chunked"),
        "a large answer is streamed: {head}"
    );
    tokio::time::sleep(Duration::from_secs(4)).await;
    let t = Instant::now();
    let got = read_to_close(&mut s, EVENTUALLY).await;
    let got = got.expect("the connection is closed");
    assert!(t.elapsed() < EVENTUALLY);
    // The same answer, read at once, is whole.
    let split = request.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4;
    let whole = app
        .client
        .post(format!("{}/v1/robots/puma560/fk/batch", app.http))
        .header("content-type", "application/json")
        .body(request[split..].to_vec())
        .send()
        .await
        .unwrap();
    assert_eq!(whole.status(), 200);
    let length = whole.bytes().await.unwrap().len();
    assert!(length > 10_000_000, "{length} bytes");
    assert!(got < length, "{got} of {length} bytes: not cut off");
    fk_ok(&app, "planar_2dof", json!({"joints": [0, 0]})).await;
}

/// The same over h2c, where flow control stops the stream without any write
/// blocking: a client that never opens its receive window is dropped after
/// the write timeout (no frame of its answer taken), not kept forever.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_h2c_answer_nobody_reads_is_dropped_after_the_write_timeout() {
    let app = spawn_app_with(|c| c.write_timeout = Duration::from_secs(2)).await;
    let addr = addr_of(&app.http);
    let tcp = TcpStream::connect(&addr).await.unwrap();
    let (client, conn) = h2::client::Builder::new()
        .initial_window_size(1024)
        .initial_connection_window_size(1024)
        .handshake::<_, axum::body::Bytes>(tcp)
        .await
        .unwrap();
    let driver = tokio::spawn(conn);
    let mut ready = client.ready().await.unwrap();
    let request = batch_request("puma560", 10_000);
    let split = request.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4;
    let req = axum::http::Request::post(format!("http://{addr}/v1/robots/puma560/fk/batch"))
        .header("content-type", "application/json")
        .body(())
        .unwrap();
    let (resp, mut send) = ready.send_request(req, false).unwrap();
    send.reserve_capacity(request.len() - split);
    send.send_data(axum::body::Bytes::copy_from_slice(&request[split..]), true)
        .unwrap();
    let resp = tokio::time::timeout(EVENTUALLY, resp)
        .await
        .unwrap()
        .unwrap();
    assert_eq!(resp.status(), 200);
    // The body is never read and the window never opened.
    let _body = resp.into_body();
    let t = Instant::now();
    let ended = tokio::time::timeout(EVENTUALLY, driver).await;
    eprintln!("h2c connection ended after {:?}: {ended:?}", t.elapsed());
    assert!(ended.is_ok(), "the stalled h2c connection is still open");
    fk_ok(&app, "planar_2dof", json!({"joints": [0, 0]})).await;
}

// ---------------------------------------------------------------- big uploads refused early

/// Sends `head` and then `body_len` bytes whole before reading (as urllib
/// does), then reads the answer's status.
async fn upload_then_read(addr: &str, head: &str, body_len: usize) -> Option<u16> {
    let mut s = TcpStream::connect(addr).await.unwrap();
    s.write_all(head.as_bytes()).await.ok()?;
    let chunk = vec![b' '; 64 << 10];
    let mut sent = 0;
    while sent < body_len {
        let n = chunk.len().min(body_len - sent);
        if let Err(e) = s.write_all(&chunk[..n]).await {
            panic!("upload failed after {sent} bytes: {e}");
        }
        sent += n;
    }
    read_status(&mut s, EVENTUALLY).await
}

/// A 20 MB upload to a route with a 1 MiB limit gets its 413, ten times out
/// of ten, and one to the registry without the token its 401: the server
/// keeps reading (and discarding) after answering, so the client neither
/// sees "broken pipe" nor loses the answer.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_20_mb_upload_gets_its_413_or_401_every_time() {
    let tmp = tempfile::tempdir().unwrap();
    let server = start_server(tmp.path(), &[("KINSERVE_API_TOKEN", "s3cret")], None).await;
    let watch = RssWatch::start(server.pid());
    let checker = Checker::start(&server.http, &server.grpc, &ws_of(&server.http)).await;
    let addr = addr_of(&server.http);
    const BIG: usize = 20_000_000;
    for path in ["/v1/robots/puma560/fk", "/v1/robots/puma560/fk/batch"] {
        let head = format!(
            "POST {path} HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {BIG}\r\n\r\n"
        );
        for i in 0..10 {
            let status = upload_then_read(&addr, &head, BIG).await;
            assert_eq!(status, Some(413), "{path}, attempt {i}");
        }
    }
    let head = format!(
        "POST /v1/robots HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {BIG}\r\n\r\n"
    );
    for i in 0..5 {
        let status = upload_then_read(&addr, &head, BIG).await;
        assert_eq!(status, Some(401), "registry upload, attempt {i}");
    }
    checker.finish().await;
    assert_rss_bounded(watch, "20 MB uploads").await;
}

// ---------------------------------------------------------------- message strictness

/// HTTP/1.1 without `Host` or with two is 400; a transfer coding other than
/// `chunked` is 501 (not read as chunked); all as problem+json. HTTP/1.0
/// without `Host` and plain `chunked` are served.
#[tokio::test]
async fn host_and_transfer_coding_are_checked() {
    let app = spawn_app().await;
    let addr = addr_of(&app.http);
    let fk = r#"{"joints":[0,0]}"#;
    let cases: [(String, u16); 6] = [
        ("GET /healthz HTTP/1.1\r\n\r\n".into(), 400),
        (
            "GET /healthz HTTP/1.1\r\nHost: a\r\nHost: b\r\n\r\n".into(),
            400,
        ),
        ("GET /healthz HTTP/1.0\r\n\r\n".into(), 200),
        (
            format!(
                "POST /v1/robots/planar_2dof/fk HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nTransfer-Encoding: gzip, chunked\r\n\r\n{:x}\r\n{fk}\r\n0\r\n\r\n",
                fk.len()
            ),
            501,
        ),
        (
            format!(
                "POST /v1/robots/planar_2dof/fk HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nTransfer-Encoding: gzip\r\nTransfer-Encoding: chunked\r\n\r\n{:x}\r\n{fk}\r\n0\r\n\r\n",
                fk.len()
            ),
            501,
        ),
        (
            format!(
                "POST /v1/robots/planar_2dof/fk HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n{:x}\r\n{fk}\r\n0\r\n\r\n",
                fk.len()
            ),
            200,
        ),
    ];
    for (request, want) in cases {
        let (status, head) = raw_exchange(&addr, request.as_bytes()).await;
        assert_eq!(status, want, "{request:?} → {head}");
        if want != 200 {
            assert!(head.contains("application/problem+json"), "{head}");
        }
    }
}

// ---------------------------------------------------------------- header timeout

/// The header timeout holds for every request: a kept-alive HTTP/1.1
/// connection whose second request head stalls is closed, and an h2c
/// connection left with no request under way is closed (GOAWAY) too.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_header_timeout_covers_every_request_of_a_connection() {
    let app = spawn_app_with(|c| c.header_timeout = Duration::from_millis(500)).await;
    let addr = addr_of(&app.http);
    let mut s = TcpStream::connect(&addr).await.unwrap();
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .unwrap();
    let head = read_head(&mut s, EVENTUALLY).await.unwrap();
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    let mut ok = [0u8; 2];
    tokio::io::AsyncReadExt::read_exact(&mut s, &mut ok)
        .await
        .unwrap();
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Slow: aa")
        .await
        .unwrap();
    let t = Instant::now();
    assert!(
        read_to_close(&mut s, EVENTUALLY).await.is_some(),
        "h1 still open"
    );
    assert!(
        t.elapsed() >= Duration::from_millis(400),
        "{:?}",
        t.elapsed()
    );

    let tcp = TcpStream::connect(&addr).await.unwrap();
    let (client, conn) = h2::client::handshake(tcp).await.unwrap();
    let driver = tokio::spawn(conn);
    let mut ready = client.ready().await.unwrap();
    let req = axum::http::Request::get(format!("http://{addr}/healthz"))
        .body(())
        .unwrap();
    let (resp, _) = ready.send_request(req, true).unwrap();
    assert_eq!(resp.await.unwrap().status(), 200);
    let ended = tokio::time::timeout(EVENTUALLY, driver).await;
    assert!(ended.is_ok(), "h2c connection still open while idle");
    drop(ready);
}

// ---------------------------------------------------------------- readiness drain

/// On shutdown, `/readyz` answers 503 and gRPC health NOT_SERVING for the
/// grace period while FK is still served (on kept and new connections);
/// then the listener closes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn readyz_is_503_during_the_shutdown_grace_while_fk_is_served() {
    use tonic_health::pb::health_check_response::ServingStatus;
    use tonic_health::pb::{HealthCheckRequest, health_client::HealthClient};

    // The grace is long (12 s) so that the checks below fit in it on a
    // loaded runner; /readyz turns 503 at once (reported), asserted within
    // a third of the grace.
    const GRACE: Duration = Duration::from_secs(12);
    let app = spawn_app_with(|c| c.shutdown_grace = GRACE).await;
    let mut health = HealthClient::new(channel(&app).await);
    let t = Instant::now();
    app.begin_shutdown();
    let mut saw_503 = false;
    while t.elapsed() < GRACE / 3 {
        if app.get("/readyz").await.status() == 503 {
            saw_503 = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert!(
        saw_503,
        "/readyz not 503 within {:?} of the shutdown",
        GRACE / 3
    );
    kinserve_testkit::report(&format!(
        "/readyz 503 after {:?} of the shutdown",
        t.elapsed()
    ));
    fk_ok(&app, "planar_2dof", json!({"joints": [0, 0]})).await;
    let fresh = reqwest::Client::new()
        .post(format!("{}/v1/robots/planar_2dof/fk", app.http))
        .json(&json!({"joints": [0, 0]}))
        .send()
        .await
        .unwrap();
    assert_eq!(fresh.status(), 200, "a new connection during the grace");
    let status = health
        .check(HealthCheckRequest {
            service: String::new(),
        })
        .await
        .unwrap()
        .into_inner()
        .status;
    assert_eq!(status, ServingStatus::NotServing as i32);
    assert!(t.elapsed() < GRACE, "checks ran past the grace");
    let addr = addr_of(&app.http);
    let mut closed = false;
    while t.elapsed() < GRACE + EVENTUALLY {
        if TcpStream::connect(&addr).await.is_err() {
            closed = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(closed, "the listener did not close after the grace");
}

/// `--max-connections` bounds the open connections of both listeners
/// together: with every slot held by idle clients, a new REST or gRPC client
/// is not accepted (it waits in the kernel's backlog, nothing is refused) and
/// is served as soon as one of them leaves. The slots are filled with kept-alive
/// HTTP/1.1 connections until one is not answered: that one is the client past
/// the limit (the test client's own pooled connection may hold a slot too).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn connections_past_the_limit_wait_until_one_closes() {
    const MAX: usize = 4;
    let app = spawn_app_with(|c| {
        c.max_connections = MAX;
        c.header_timeout = Duration::from_secs(120);
    })
    .await;
    let addr = app.http.trim_start_matches("http://").to_string();
    let mut held = Vec::new();
    let mut waiting = loop {
        let mut s = TcpStream::connect(&addr).await.unwrap();
        s.write_all(b"GET /healthz HTTP/1.1\r\nhost: t\r\n\r\n")
            .await
            .unwrap();
        match read_status(&mut s, Duration::from_secs(3)).await {
            Some(200) => held.push(s),
            None => break s,
            other => panic!("unexpected answer {other:?}"),
        }
        assert!(held.len() <= MAX, "more connections served than slots");
    };
    assert!(held.len() + 2 >= MAX, "{} held", held.len());
    drop(held.pop());
    let status = read_status(&mut waiting, Duration::from_secs(20)).await;
    assert_eq!(status, Some(200), "served once a slot is free");
    held.push(waiting);

    // Every slot is taken again: a new gRPC client waits too.
    let grpc = app.grpc.clone();
    let call = tokio::spawn(async move {
        let mut client =
            kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient::connect(
                grpc,
            )
            .await?;
        let reply = client
            .forward_kinematics(kinserve::api::grpc::pb::ForwardKinematicsRequest {
                robot: "puma560".into(),
                joints: vec![0.0; 6],
                ..Default::default()
            })
            .await?;
        Ok::<_, Box<dyn std::error::Error + Send + Sync>>(reply.into_inner().robot)
    });
    tokio::time::sleep(Duration::from_millis(1500)).await;
    assert!(
        !call.is_finished(),
        "a gRPC client past the limit waits too"
    );
    drop(held.pop());
    let robot = tokio::time::timeout(Duration::from_secs(20), call)
        .await
        .expect("served once a slot is free")
        .unwrap()
        .unwrap();
    assert_eq!(robot, "puma560");
}

/// The response byte budget refuses an answer that does not fit with 503
/// `overloaded` + `Retry-After` (never a partial answer), while answers that
/// fit are served as usual.
#[tokio::test]
async fn an_answer_over_the_response_budget_is_a_503_not_a_partial_answer() {
    let app = spawn_app_with(|c| c.max_buffered_response_bytes = 768 << 10).await;
    let batch = |n: usize| {
        let configs: Vec<Vec<f64>> = (0..n).map(|i| vec![i as f64 * 1e-4; 6]).collect();
        app.client
            .post(format!("{}/v1/robots/puma560/fk/batch", app.http))
            .json(&json!({ "configurations": configs }))
            .send()
    };
    // Produced a frame at a time, it still holds its 10,000 computed poses
    // (960 kB) and what hyper may buffer (~480 kB): more than the whole
    // 768 KiB budget.
    let r = batch(10_000).await.unwrap();
    assert_eq!(r.status(), 503);
    assert_eq!(r.headers()["retry-after"], "1");
    let p: serde_json::Value = r.json().await.unwrap();
    assert_eq!(p["type"], "urn:kinserve:problem:overloaded", "{p}");
    // About 60 KB (counted as 100 poses and hyper's buffer, ~490 kB): fits,
    // answered in full.
    let r = batch(100).await.unwrap();
    assert_eq!(r.status(), 200);
    let body: serde_json::Value = r.json().await.unwrap();
    assert_eq!(body["poses"].as_array().unwrap().len(), 100);
}
