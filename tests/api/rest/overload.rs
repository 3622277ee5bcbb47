//! REST overload: the concurrency limit (503 with Retry-After) and the request
//! timeout, driven by slow IK solves and request bodies held back over raw
//! connections.

use serde_json::json;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use crate::helpers::*;

// ---------------------------------------------------------------- overload

/// An IK solve that cannot converge: it runs until the IK time limit.
fn slow_ik() -> serde_json::Value {
    json!({"target": {"position": [5.0, 0.0, 0.5], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}},
        "restarts": 1000, "max_iterations": 10000})
}

/// With one permit, a request being computed holds it: every other admitted
/// request gets 503 + Retry-After at once, health endpoints still answer, and
/// the permit comes back when the slow request completes. A request whose
/// body is still arriving holds no permit (bodies are read first).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn overloaded_is_503_with_retry_after() {
    let app = spawn_app_with(|c| {
        c.max_concurrent_requests = 1;
        c.ik_time_limit = std::time::Duration::from_secs(2);
    })
    .await;
    let body = br#"{"joints": [0, 0]}"#;
    let partial = partial_request(&app, "/v1/robots/planar_2dof/fk", body, 3).await;
    assert_eq!(
        app.get("/v1/robots").await.status(),
        200,
        "a body on its way holds no permit"
    );
    let client = app.client.clone();
    let url = format!("{}/v1/robots/ur5e/ik", app.http);
    // The polls below take the only permit for a moment too: a slow request
    // that arrives during one is refused, so it is sent again until admitted.
    let computing = tokio::spawn(async move {
        loop {
            let r = client.post(&url).json(&slow_ik()).send().await;
            if !matches!(&r, Ok(r) if r.status() == 503) {
                return r;
            }
            tokio::time::sleep(std::time::Duration::from_millis(2)).await;
        }
    });
    // Poll until the server has admitted the slow request (it then holds the only permit).
    let mut rejected = None;
    for _ in 0..500 {
        let r = app.get("/v1/robots").await;
        if r.status() == 503 {
            rejected = Some(r);
            break;
        }
        assert_eq!(r.status(), 200);
        tokio::time::sleep(std::time::Duration::from_millis(5)).await;
    }
    let r = rejected.expect("a request beyond the limit is rejected");
    assert_eq!(r.headers()["retry-after"], "1");
    let p = problem(r, 503).await;
    assert_eq!(p["type"], "urn:kinserve:problem:overloaded");
    // Health endpoints are not subject to admission control.
    assert_eq!(app.get("/healthz").await.status(), 200);
    assert_eq!(app.get("/readyz").await.status(), 200);

    let done = computing.await.unwrap().unwrap();
    assert_eq!(
        done.status(),
        422,
        "the unreachable target is not converged"
    );
    let mut partial = partial;
    partial.write_all(&body[3..]).await.unwrap();
    let resp = read_response(partial).await;
    assert!(resp.starts_with("HTTP/1.1 200"), "{resp}");
    assert!(resp.contains("\"planar_2dof\""), "{resp}");
    assert_eq!(app.get("/v1/robots").await.status(), 200, "permit released");
}

/// A request still computing at the request timeout gets 503 + Retry-After.
#[tokio::test]
async fn a_request_over_the_timeout_is_503() {
    let app = spawn_app_with(|c| {
        c.request_timeout = std::time::Duration::from_millis(300);
        c.ik_time_limit = std::time::Duration::from_secs(3);
    })
    .await;
    let r = app.post("/v1/robots/ur5e/ik", &slow_ik()).await;
    assert_eq!(r.headers()["retry-after"], "1");
    let p = problem(r, 503).await;
    assert!(p["detail"].as_str().unwrap().contains("timed out"), "{p}");
}

/// A request whose body is unfinished at the request timeout gets 408
/// problem+json and the connection is closed.
#[tokio::test]
async fn a_body_unfinished_at_the_request_timeout_is_408() {
    let app = spawn_app_with(|c| c.request_timeout = std::time::Duration::from_millis(200)).await;
    let slow = partial_request(
        &app,
        "/v1/robots/planar_2dof/fk",
        br#"{"joints": [0, 0]}"#,
        1,
    )
    .await;
    let resp = read_response(slow).await;
    assert!(resp.starts_with("HTTP/1.1 408"), "{resp}");
    let lower = resp.to_ascii_lowercase();
    assert!(
        lower.contains("content-type: application/problem+json"),
        "{resp}"
    );
    assert!(lower.contains("connection: close"), "{resp}");
    assert!(resp.contains("did not arrive in time"), "{resp}");
}

fn host_port(app: &TestApp) -> String {
    app.http.trim_start_matches("http://").to_owned()
}

/// Sends `method path` with `Content-Length: content_length` and only the first
/// `sent` bytes of `body` over a raw connection: the request stays in flight
/// (its handler waits for the rest of the body) until the caller writes more.
async fn partial_request(app: &TestApp, path: &str, body: &[u8], sent: usize) -> TcpStream {
    let mut s = TcpStream::connect(host_port(app)).await.expect("connect");
    let head = format!(
        "POST {path} HTTP/1.1\r\nHost: {}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        host_port(app),
        body.len()
    );
    s.write_all(head.as_bytes()).await.unwrap();
    s.write_all(&body[..sent]).await.unwrap();
    s.flush().await.unwrap();
    s
}

/// Reads a whole HTTP/1.1 response (the request said `Connection: close`).
async fn read_response(mut s: TcpStream) -> String {
    let mut buf = Vec::new();
    s.read_to_end(&mut buf).await.expect("read response");
    String::from_utf8_lossy(&buf).into_owned()
}
