//! TLS on both listeners with a test CA (certificates made here, rcgen):
//! REST over HTTP/1.1 and HTTP/2 (ALPN), WebSockets over both, gRPC;
//! client certificates required, optional and refused; a certificate
//! rotated while clients keep calling; a stalled handshake bounded by the
//! header timeout, and handshakes held to the connection limit.

use std::path::Path;
use std::time::{Duration, Instant};

use bytes::Bytes;
use futures_util::{SinkExt, StreamExt};
use kinserve::config::ServeConfig;
use kinserve::tls::ClientAuth;
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_tungstenite::tungstenite::Message;

use crate::helpers::tls::*;
use crate::helpers::*;

/// Planar 2-DoF arm (a1 = 0.4 m, a2 = 0.3 m) at θ = (0, π/2) rad: the tip
/// at x = a1 + a2·cos(π/2) = 0.4, y = a2·sin(π/2) = 0.3 (metres).
const JOINTS: [f64; 2] = [0.0, std::f64::consts::FRAC_PI_2];
const TIP: [f64; 3] = [0.4, 0.3, 0.0];
const TOL: f64 = 1e-12;

/// A TLS server's files and how to reach it.
struct TlsApp {
    /// Keeps the server running.
    _app: TestApp,
    ca: TestCa,
    dir: tempfile::TempDir,
    http: String,
    grpc: String,
}

/// Serves TLS with a server certificate of `ca` (common name `cn`);
/// `configure` may set the client CA and the rest.
async fn spawn_tls(cn: &str, configure: impl FnOnce(&mut ServeConfig, &Path, &TestCa)) -> TlsApp {
    let ca = TestCa::new("kinserve test CA");
    let dir = tempfile::tempdir().unwrap();
    let (cert, key) = write_pem(dir.path(), "server", &ca.server(cn));
    let path = dir.path().to_path_buf();
    let app = spawn_tls_app(|c| {
        c.tls.tls_cert = Some(cert);
        c.tls.tls_key = Some(key);
        configure(c, &path, &ca);
    })
    .await;
    let (http, grpc) = (host_port(&app.http), host_port(&app.grpc));
    TlsApp {
        _app: app,
        ca,
        dir,
        http,
        grpc,
    }
}

/// The server with a client CA (`ca.pem` in `dir`) and `auth`.
fn with_client_ca(c: &mut ServeConfig, dir: &Path, ca: &TestCa, auth: ClientAuth) {
    let path = dir.join("clients-ca.pem");
    std::fs::write(&path, ca.pem()).unwrap();
    c.tls.tls_client_ca = Some(path);
    c.tls.tls_client_auth = auth;
}

fn fk_body() -> String {
    json!({ "joints": JOINTS }).to_string()
}

fn assert_tip(out: &Value, what: &str) {
    let p = position(&out["pose"]);
    for i in 0..3 {
        assert_close(p[i], TIP[i], TOL, &format!("{what}: position[{i}]"));
    }
}

/// `POST /v1/robots/planar_2dof/fk` over HTTP/1.1: status and JSON body.
async fn h1_fk(t: &TlsApp, client: Option<&Pem>) -> std::io::Result<(u16, Value)> {
    let config = client_config(&t.ca.pem(), client, &["http/1.1"]);
    let mut tls = tls_connect(&t.http, config).await?;
    let body = fk_body();
    let req = format!(
        "POST /v1/robots/planar_2dof/fk HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    );
    tls.write_all(req.as_bytes()).await?;
    let mut raw = Vec::new();
    let read = tls.read_to_end(&mut raw).await;
    let text = String::from_utf8_lossy(&raw).into_owned();
    let Some(status) = text.split(' ').nth(1).and_then(|s| s.parse().ok()) else {
        read?;
        return Err(std::io::Error::other(format!("no answer: {text}")));
    };
    let json = text
        .split_once("\r\n\r\n")
        .and_then(|(_, b)| serde_json::from_str(b).ok())
        .unwrap_or(Value::Null);
    Ok((status, json))
}

/// An HTTP/2 connection over TLS (ALPN h2).
async fn h2_connect(t: &TlsApp, client: Option<&Pem>) -> h2::client::SendRequest<Bytes> {
    let config = client_config(&t.ca.pem(), client, &["h2"]);
    let tls = tls_connect(&t.http, config).await.unwrap();
    assert_eq!(tls.get_ref().1.alpn_protocol(), Some(&b"h2"[..]));
    let (send, conn) = h2::client::handshake(tls).await.unwrap();
    tokio::spawn(async move {
        let _ = conn.await;
    });
    send
}

/// FK over an HTTP/2 connection: status and JSON body.
async fn h2_fk(send: &mut h2::client::SendRequest<Bytes>) -> Result<(u16, Value), h2::Error> {
    let req = ::http::Request::builder()
        .method("POST")
        .uri("https://localhost/v1/robots/planar_2dof/fk")
        .header("content-type", "application/json")
        .body(())
        .unwrap();
    let mut ready = send.clone().ready().await?;
    let (resp, mut body) = ready.send_request(req, false)?;
    body.send_data(Bytes::from(fk_body()), true)?;
    let resp = resp.await?;
    let status = resp.status().as_u16();
    let mut body = resp.into_body();
    let mut raw = Vec::new();
    while let Some(chunk) = body.data().await {
        let chunk = chunk?;
        let _ = body.flow_control().release_capacity(chunk.len());
        raw.extend_from_slice(&chunk);
    }
    Ok((status, serde_json::from_slice(&raw).unwrap_or(Value::Null)))
}

#[tokio::test]
async fn rest_answers_over_tls_on_http1_and_http2() {
    let t = spawn_tls("kinserve-a", |_, _, _| {}).await;
    // HTTP/1.1 (ALPN http/1.1).
    let (status, out) = h1_fk(&t, None).await.unwrap();
    assert_eq!(status, 200, "{out}");
    assert_tip(&out, "HTTP/1.1 over TLS");
    let config = client_config(&t.ca.pem(), None, &["http/1.1"]);
    let tls = tls_connect(&t.http, config).await.unwrap();
    assert_eq!(tls.get_ref().1.alpn_protocol(), Some(&b"http/1.1"[..]));
    assert_eq!(server_cn(&tls), "CN=kinserve-a, O=kinserve tests");
    assert_eq!(h1_get(tls, "/readyz").await.0, 200);
    // HTTP/2 (ALPN h2), two requests on one connection.
    let mut send = h2_connect(&t, None).await;
    for _ in 0..2 {
        let (status, out) = h2_fk(&mut send).await.unwrap();
        assert_eq!(status, 200, "{out}");
        assert_tip(&out, "HTTP/2 over TLS");
    }
    // No ALPN at all: still served (HTTP/1.1).
    let config = client_config(&t.ca.pem(), None, &[]);
    let tls = tls_connect(&t.http, config).await.unwrap();
    assert_eq!(h1_get(tls, "/healthz").await.0, 200);
    // Plain HTTP to the TLS listener gets no answer.
    let plain = reqwest::Client::new()
        .get(format!("http://{}/readyz", t.http))
        .send()
        .await;
    assert!(plain.is_err(), "plain HTTP answered: {plain:?}");
}

#[tokio::test]
async fn websockets_work_over_tls_on_http1_and_http2() {
    let t = spawn_tls("kinserve-ws", |_, _, _| {}).await;
    // HTTP/1.1 upgrade.
    let config = client_config(&t.ca.pem(), None, &["http/1.1"]);
    let tls = tls_connect(&t.http, config).await.unwrap();
    let (mut ws, _) =
        tokio_tungstenite::client_async("wss://localhost/v1/robots/planar_2dof/fk/stream", tls)
            .await
            .expect("the WebSocket opens over TLS");
    let msg = json!({"id": 7, "joints": JOINTS}).to_string();
    ws.send(Message::text(msg)).await.unwrap();
    let reply = loop {
        match ws.next().await.expect("a reply").unwrap() {
            Message::Text(t) => break serde_json::from_str::<Value>(t.as_str()).unwrap(),
            _ => continue,
        }
    };
    assert_eq!(reply["id"], 7, "{reply}");
    assert_tip(&reply, "WebSocket over HTTP/1.1 + TLS");
    // HTTP/2 extended CONNECT (RFC 8441).
    let mut send = h2_connect(&t, None).await;
    for _ in 0..100 {
        if send.is_extended_connect_protocol_enabled() {
            break;
        }
        send = send.ready().await.unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert!(send.is_extended_connect_protocol_enabled());
    let mut req = ::http::Request::builder()
        .method("CONNECT")
        .uri("https://localhost/v1/robots/planar_2dof/fk/stream")
        .header("sec-websocket-version", "13")
        .body(())
        .unwrap();
    req.extensions_mut()
        .insert(h2::ext::Protocol::from_static("websocket"));
    let (resp, mut body_out) = send
        .ready()
        .await
        .unwrap()
        .send_request(req, false)
        .unwrap();
    let resp = resp.await.unwrap();
    assert_eq!(resp.status(), 200);
    // One text frame, masked with zeros; one reply frame (16-bit length).
    let msg = json!({"id": 8, "joints": JOINTS}).to_string();
    let mut frame = vec![0x81, 0x80 | msg.len() as u8, 0, 0, 0, 0];
    frame.extend_from_slice(msg.as_bytes());
    body_out.send_data(Bytes::from(frame), false).unwrap();
    let mut body = resp.into_body();
    let mut got = Vec::new();
    let reply = loop {
        let chunk = body.data().await.expect("a reply").unwrap();
        let _ = body.flow_control().release_capacity(chunk.len());
        got.extend_from_slice(&chunk);
        if got.len() >= 4 {
            assert_eq!(got[..2], [0x81, 126], "{got:?}");
            let len = u16::from_be_bytes([got[2], got[3]]) as usize;
            if got.len() >= 4 + len {
                break serde_json::from_slice::<Value>(&got[4..4 + len]).unwrap();
            }
        }
    };
    assert_eq!(reply["id"], 8, "{reply}");
    assert_tip(&reply, "WebSocket over HTTP/2 + TLS");
}

#[tokio::test]
async fn grpc_answers_over_tls() {
    let t = spawn_tls("kinserve-grpc", |_, _, _| {}).await;
    let config = client_config(&t.ca.pem(), None, &["h2"]);
    let mut client = grpc_tls_client(&t.grpc, config).await;
    let out = client
        .forward_kinematics(fk_request("planar_2dof", &JOINTS, None))
        .await
        .unwrap()
        .into_inner();
    let p = out.pose.unwrap().position.unwrap();
    for (i, got) in [p.x, p.y, p.z].into_iter().enumerate() {
        assert_close(got, TIP[i], TOL, &format!("gRPC over TLS: position[{i}]"));
    }
    // gRPC offers h2 only: a client that wants HTTP/1.1 alone is refused.
    let h1_only = client_config(&t.ca.pem(), None, &["http/1.1"]);
    assert!(tls_connect(&t.grpc, h1_only).await.is_err());
    // A plain gRPC client gets no answer.
    let plain =
        kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient::connect(
            format!("http://{}", t.grpc),
        )
        .await;
    if let Ok(mut plain) = plain {
        let r = plain
            .forward_kinematics(fk_request("planar_2dof", &JOINTS, None))
            .await;
        assert!(r.is_err(), "plain gRPC answered: {r:?}");
    }
}

/// A call that must fail at the TLS layer: the handshake, or the first
/// request on the connection (TLS 1.3 clients learn of a refused
/// certificate only then).
async fn refused(t: &TlsApp, client: Option<&Pem>) -> bool {
    let rest = h1_fk(t, client).await.is_err();
    let config = client_config(&t.ca.pem(), client, &["h2"]);
    let grpc = match grpc_tls_channel(&t.grpc, config).await {
        Err(_) => true,
        Ok(ch) => {
            kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient::new(ch)
                .forward_kinematics(fk_request("planar_2dof", &JOINTS, None))
                .await
                .is_err()
        }
    };
    assert_eq!(rest, grpc, "REST and gRPC agree");
    rest
}

#[tokio::test]
async fn client_certificates_are_required_with_a_client_ca() {
    let t = spawn_tls("kinserve-mtls", |c, dir, ca| {
        with_client_ca(c, dir, ca, ClientAuth::Require)
    })
    .await;
    let good = t.ca.client("planner");
    let stranger = TestCa::new("another CA").client("planner");
    assert!(
        !refused(&t, Some(&good)).await,
        "a certificate of the client CA is accepted"
    );
    assert!(refused(&t, None).await, "no certificate is refused");
    assert!(
        refused(&t, Some(&stranger)).await,
        "another CA's certificate is refused"
    );
    // A server certificate (no clientAuth usage) is not a client certificate.
    let server_cert = t.ca.server("not-a-client");
    assert!(refused(&t, Some(&server_cert)).await);
}

#[tokio::test]
async fn client_certificates_are_optional_with_tls_client_auth_optional() {
    let t = spawn_tls("kinserve-optional", |c, dir, ca| {
        with_client_ca(c, dir, ca, ClientAuth::Optional)
    })
    .await;
    let good = t.ca.client("planner");
    let stranger = TestCa::new("another CA").client("planner");
    assert!(!refused(&t, None).await, "no certificate is fine");
    assert!(!refused(&t, Some(&good)).await, "a good one is fine");
    assert!(
        refused(&t, Some(&stranger)).await,
        "a bad one is still refused"
    );
}

/// Rotation: new files are picked up (contents polled every 100 ms) while
/// one HTTP/2 connection and a stream of new connections keep calling; not
/// one call fails, the open connection keeps its session, new ones see the
/// new certificate; a broken replacement keeps the last good one.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rotated_certificate_is_served_without_a_failed_request() {
    let t = spawn_tls("generation-1", |c, _, _| {
        c.tls.tls_reload_interval = Duration::from_millis(100);
    })
    .await;
    let mut kept = h2_connect(&t, None).await;
    let config = client_config(&t.ca.pem(), None, &["http/1.1"]);
    let cn = |tls: &tokio_rustls::client::TlsStream<tokio::net::TcpStream>| server_cn(tls);
    let first = tls_connect(&t.http, config.clone()).await.unwrap();
    assert_eq!(cn(&first), "CN=generation-1, O=kinserve tests");
    let (mut calls, mut rotated_at) = (0, None);
    write_pem(t.dir.path(), "server", &t.ca.server("generation-2"));
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        let (status, out) = h2_fk(&mut kept).await.expect("the kept connection works");
        assert_eq!(status, 200, "{out}");
        let (status, out) = h1_fk(&t, None).await.expect("a new connection works");
        assert_eq!(status, 200, "{out}");
        calls += 2;
        let tls = tls_connect(&t.http, config.clone()).await.unwrap();
        if cn(&tls) == "CN=generation-2, O=kinserve tests" {
            rotated_at.get_or_insert(calls);
            if calls >= rotated_at.unwrap() + 10 {
                break;
            }
        }
    }
    assert!(
        rotated_at.is_some(),
        "the new certificate was never served ({calls} calls)"
    );
    // A broken replacement (a key of another certificate): the last good one stays.
    let other = t.ca.server("generation-3");
    std::fs::write(t.dir.path().join("server.key"), other.key).unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let tls = tls_connect(&t.http, config.clone()).await.unwrap();
    assert_eq!(cn(&tls), "CN=generation-2, O=kinserve tests");
    assert_eq!(h1_get(tls, "/readyz").await.0, 200);
    let (status, _) = h2_fk(&mut kept).await.unwrap();
    assert_eq!(status, 200);
}

/// A client that opens a connection and sends half a ClientHello (or
/// nothing) is closed after the header timeout; while such handshakes hold
/// every connection slot, nothing more is accepted, then service resumes.
#[tokio::test]
async fn a_stalled_handshake_is_bounded_by_the_header_timeout_and_the_connection_limit() {
    const HEADER_TIMEOUT: Duration = Duration::from_millis(400);
    let t = spawn_tls("kinserve-stall", |c, _, _| {
        c.header_timeout = HEADER_TIMEOUT;
        c.max_connections = 2;
    })
    .await;
    // Wait until the readiness probes' connections are gone.
    tokio::time::sleep(HEADER_TIMEOUT * 2).await;
    let start = Instant::now();
    let mut stalled = Vec::new();
    for addr in [&t.http, &t.grpc] {
        let mut tcp = tokio::net::TcpStream::connect(addr).await.unwrap();
        // The first bytes of a TLS record holding a ClientHello, then nothing.
        tcp.write_all(&[0x16, 0x03, 0x01, 0x02, 0x00, 0x01])
            .await
            .unwrap();
        stalled.push(tcp);
    }
    // Both slots are held: a full client is served only once they are freed.
    let config = client_config(&t.ca.pem(), None, &["http/1.1"]);
    let tls = tls_connect(&t.http, config).await.unwrap();
    let waited = start.elapsed();
    assert_eq!(h1_get(tls, "/readyz").await.0, 200);
    assert!(
        waited >= HEADER_TIMEOUT.mul_f64(0.9),
        "served after {waited:?}, while the stalled handshakes held every slot"
    );
    for mut tcp in stalled {
        let mut buf = [0u8; 64];
        let closed = tokio::time::timeout(Duration::from_secs(2), async {
            loop {
                match tcp.read(&mut buf).await {
                    Ok(0) | Err(_) => return,
                    Ok(_) => continue,
                }
            }
        })
        .await;
        assert!(closed.is_ok(), "a stalled handshake stays open");
    }
    assert!(
        start.elapsed() <= HEADER_TIMEOUT + Duration::from_secs(1),
        "stalled handshakes closed after {:?}",
        start.elapsed()
    );
}
