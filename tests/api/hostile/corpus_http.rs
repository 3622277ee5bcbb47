//! The REST and WebSocket corpus: each case sent over raw HTTP/1.1 and the
//! WebSocket stream, with the parallel FK client checking the server keeps
//! answering. Error cases are checked against their documented problem;
//! 2xx cases' poses against the plain reference product (1e-12); the case
//! count has a floor (today's 123).

use futures_util::SinkExt;
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;

use crate::helpers::*;

fn links_json(n: usize, joint: &str) -> String {
    join(
        n,
        &format!(r#"{{"joint":"{joint}","a":0,"alpha":0,"d":0,"theta":0}}"#),
    )
}

/// The request body a REST corpus case describes.
fn rest_body(case: &Value) -> Vec<u8> {
    if let Some(s) = case["body"].as_str() {
        return s.as_bytes().to_vec();
    }
    if !case["body_json"].is_null() {
        return serde_json::to_vec(&case["body_json"]).unwrap();
    }
    if let Some(h) = case["body_hex"].as_str() {
        return hex(h);
    }
    if let Some(f) = case["body_file"].as_str() {
        return corpus_bytes(f);
    }
    let gen_ = &case["gen"];
    if gen_.is_null() {
        return Vec::new();
    }
    let n = gen_["n"].as_u64().unwrap_or(0) as usize;
    let depth = gen_["depth"].as_u64().unwrap_or(0) as usize;
    let s = match gen_["kind"].as_str().expect("body or gen") {
        "joints" => format!(r#"{{"joints":[{}]}}"#, join(n, "0")),
        "nested_joints" => format!(
            r#"{{"joints":[{}{}]}}"#,
            "[".repeat(depth),
            "]".repeat(depth)
        ),
        "nested_id" => format!(
            r#"{{"id":{}0{},"joints":[0,0]}}"#,
            r#"{"a":"#.repeat(depth),
            "}".repeat(depth)
        ),
        "padded" => format!(
            r#"{}{{"joints":{}[0,0]{}}}{}"#,
            " ".repeat(n / 4),
            "\n".repeat(n / 4),
            "\t".repeat(n / 4),
            "\r\n".repeat(n / 8)
        ),
        "many_keys" => {
            let keys: Vec<String> = (0..n).map(|i| format!(r#""k{i}":0"#)).collect();
            format!(r#"{{{},"joints":[0,0]}}"#, keys.join(","))
        }
        "links" => format!(
            r#"{{"name":"hostile_links","convention":"standard","links":[{}]}}"#,
            links_json(n, gen_["joint"].as_str().unwrap_or("fixed"))
        ),
        "configs" => format!(r#"{{"configurations":[{}]}}"#, join(n, "[0,0]")),
        other => panic!("unknown generator {other}"),
    };
    s.into_bytes()
}

// ---------------------------------------------------------------- raw HTTP/1.1

/// A response read off a raw connection.
struct RawResponse {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl RawResponse {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }
}

fn parse_response(buf: &[u8]) -> Result<RawResponse, String> {
    let text_end = buf
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .ok_or_else(|| format!("no complete response head in {} bytes", buf.len()))?;
    let head = String::from_utf8_lossy(&buf[..text_end]).into_owned();
    let mut lines = head.split("\r\n");
    let status_line = lines.next().unwrap_or("");
    let status = status_line
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| format!("bad status line {status_line:?}"))?;
    let headers: Vec<(String, String)> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_owned()))
        .collect();
    let mut body = buf[text_end + 4..].to_vec();
    let chunked = headers
        .iter()
        .any(|(k, v)| k == "transfer-encoding" && v.contains("chunked"));
    if chunked {
        let mut out = Vec::new();
        let mut rest = &body[..];
        while let Some(i) = rest.windows(2).position(|w| w == b"\r\n") {
            let size = usize::from_str_radix(String::from_utf8_lossy(&rest[..i]).trim(), 16)
                .map_err(|e| format!("bad chunk size: {e}"))?;
            if size == 0 {
                break;
            }
            out.extend_from_slice(&rest[i + 2..i + 2 + size]);
            rest = &rest[i + 2 + size + 2..];
        }
        body = out;
    }
    Ok(RawResponse {
        status,
        headers,
        body,
    })
}

/// One request over a fresh HTTP/1.1 connection (`Connection: close`), the
/// body written while the response is read (a server that answers early, e.g.
/// 413, is not blocked by a client still writing).
async fn raw_http(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[(String, String)],
    body: &[u8],
) -> Result<RawResponse, String> {
    let stream = TcpStream::connect(addr)
        .await
        .map_err(|e| format!("connect: {e}"))?;
    let (mut rd, mut wr) = stream.into_split();
    let mut head = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for (k, v) in headers {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    if !body.is_empty() || method == "POST" || method == "PUT" {
        head.push_str(&format!("Content-Length: {}\r\n", body.len()));
    }
    head.push_str("\r\n");
    let mut bytes = head.into_bytes();
    bytes.extend_from_slice(body);
    let writer = tokio::spawn(async move {
        let _ = wr.write_all(&bytes).await;
        let _ = wr.flush().await;
        wr
    });
    let mut buf = Vec::new();
    let read = tokio::time::timeout(EVENTUALLY, rd.read_to_end(&mut buf)).await;
    let _ = writer.await;
    match read {
        Err(_) => return Err("no response (timed out)".into()),
        Ok(Err(e)) if buf.is_empty() => return Err(format!("read: {e}")),
        _ => {}
    }
    parse_response(&buf)
}

// ---------------------------------------------------------------- checks

fn first_field(problem: &Value) -> Option<String> {
    problem["errors"]
        .as_array()
        .and_then(|a| a.first())
        .map(|e| e["field"].as_str().unwrap_or("").to_owned())
}

/// Compares a problem document with a case's expectations.
fn check_case_problem(case: &Value, p: &Value) -> Result<(), String> {
    let status = case["status"].as_u64().unwrap() as u16;
    if p["status"] != json!(status) {
        return Err(format!("status {} instead of {status}: {p}", p["status"]));
    }
    let result = std::panic::catch_unwind(|| check_problem(p, status));
    if result.is_err() {
        return Err(format!("not a problem document: {p}"));
    }
    if let Some(kind) = case["type"].as_str()
        && p["type"] != json!(format!("urn:kinserve:problem:{kind}"))
    {
        return Err(format!("type {} instead of {kind}", p["type"]));
    }
    let got = first_field(p);
    let want = case["field"].as_str().map(str::to_owned);
    if let Some(prefix) = case["field_prefix"].as_str() {
        let field = got.clone().unwrap_or_default();
        if !field.starts_with(prefix) || field.chars().count() > 201 {
            return Err(format!(
                "field {got:?} does not start with {prefix:?} or is long"
            ));
        }
    } else if got != want {
        return Err(format!("field {got:?} instead of {want:?}: {p}"));
    }
    if got.is_some() {
        let message = p["errors"][0]["message"].as_str().unwrap_or("");
        if message.is_empty() {
            return Err(format!("empty field message: {p}"));
        }
    }
    Ok(())
}

/// The robot of a case's FK path (`/v1/robots/{robot}/fk[/batch]`).
fn case_robot(case: &Value) -> Option<&str> {
    let rest = case["path"].as_str()?.strip_prefix("/v1/robots/")?;
    rest.strip_suffix("/fk")
        .or_else(|| rest.strip_suffix("/fk/batch"))
}

/// A JSON pose's matrix (nested rows) as 16 row-major values.
fn flat_matrix(pose: &Value) -> Vec<f64> {
    pose["matrix"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|row| row.as_array().cloned().unwrap_or_default())
        .filter_map(|x| x.as_f64())
        .collect()
}

/// Checks a 2xx answer (`/fk`: `pose`; `/fk/batch`: one pose per
/// configuration) against the reference product for the case's request body.
fn check_ok_body(case: &Value, answer: &Value) -> Result<(), String> {
    let robot = case_robot(case).ok_or("a 2xx case outside /v1/robots/{robot}/fk")?;
    let body = rest_body(case);
    let request: Value = serde_json::from_slice(&body).map_err(|e| format!("request: {e}"))?;
    let deg = request["angle_unit"] == "deg";
    let joints = |v: &Value| -> Vec<f64> {
        v.as_array()
            .into_iter()
            .flatten()
            .filter_map(Value::as_f64)
            .collect()
    };
    let expect = |q: &Value, pose: &Value, what: &str| {
        matrix_matches(&flat_matrix(pose), &reference_pose(robot, &joints(q), deg))
            .map_err(|e| format!("{what}: {e}: {answer}"))
    };
    if let Some(configs) = request["configurations"].as_array() {
        let poses = answer["poses"]
            .as_array()
            .ok_or(format!("no poses: {answer}"))?;
        if poses.len() != configs.len() {
            return Err(format!(
                "{} poses for {} configurations",
                poses.len(),
                configs.len()
            ));
        }
        for (i, (q, pose)) in configs.iter().zip(poses).enumerate() {
            expect(q, pose, &format!("poses[{i}]"))?;
        }
        return Ok(());
    }
    expect(&request["joints"], &answer["pose"], "pose")
}

async fn run_rest_case(app: &TestApp, case: &Value) -> Result<(), String> {
    let mut headers: Vec<(String, String)> = Vec::new();
    if let Some(ct) = case["content_type"].as_str() {
        headers.push(("Content-Type".into(), ct.into()));
    }
    if let Some(h) = case["headers"].as_object() {
        for (k, v) in h {
            headers.push((k.clone(), v.as_str().unwrap().to_owned()));
        }
    }
    let body = rest_body(case);
    let method = case["method"].as_str().unwrap();
    let path = case["path"].as_str().unwrap();
    let resp = raw_http(&addr_of(&app.http), method, path, &headers, &body).await?;
    let status = case["status"].as_u64().unwrap() as u16;
    if status < 300 {
        if resp.status != status {
            return Err(format!(
                "status {} instead of {status}: {}",
                resp.status,
                String::from_utf8_lossy(&resp.body)
            ));
        }
        let answer: Value =
            serde_json::from_slice(&resp.body).map_err(|e| format!("answer JSON: {e}"))?;
        return check_ok_body(case, &answer);
    }
    let ct = resp.header("content-type").unwrap_or("");
    if ct != "application/problem+json" {
        return Err(format!(
            "status {} content type {ct:?}: {}",
            resp.status,
            String::from_utf8_lossy(&resp.body)
        ));
    }
    let p: Value = serde_json::from_slice(&resp.body).map_err(|e| format!("problem JSON: {e}"))?;
    if resp.status != status {
        return Err(format!(
            "HTTP status {} instead of {status}: {p}",
            resp.status
        ));
    }
    check_case_problem(case, &p)
}

async fn run_ws_case(sock: &mut Ws, case: &Value) -> Result<(), String> {
    let body = String::from_utf8(rest_body(case)).map_err(|_| "not UTF-8".to_string())?;
    sock.send(Message::Text(body.into()))
        .await
        .map_err(|e| format!("send: {e}"))?;
    let reply = tokio::time::timeout(EVENTUALLY, next_text(sock))
        .await
        .map_err(|_| "no reply".to_string())?
        .ok_or_else(|| "stream closed".to_string())?;
    let status = case["status"].as_u64().unwrap();
    if status < 300 {
        if reply.get("error").is_some() {
            return Err(format!("expected a pose: {reply}"));
        }
        return check_ok_body(case, &reply);
    }
    check_case_problem(case, &reply["error"])
}

/// The REST corpus over HTTP/1.1 and (the FK messages) over the WebSocket,
/// with a parallel client checking correct FK all along.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn the_rest_and_websocket_corpus_gets_documented_errors_and_the_server_keeps_answering() {
    let app = spawn_app().await;
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    let cases = corpus("rest.json");
    let mut failures = Vec::new();
    let (mut rest_n, mut ws_n) = (0, 0);
    let mut socks: std::collections::HashMap<String, Ws> = Default::default();
    for case in &cases {
        let name = case["name"].as_str().unwrap();
        if case["path"] != "ws-only" {
            rest_n += 1;
            if let Err(e) = run_rest_case(&app, case).await {
                failures.push(format!("REST {name}: {e}"));
            }
        }
        if case["ws"] == true {
            ws_n += 1;
            // The robot of the REST path (`/v1/robots/{robot}/fk`), else planar_2dof.
            let robot = case["path"]
                .as_str()
                .and_then(|p| p.strip_prefix("/v1/robots/"))
                .and_then(|p| p.strip_suffix("/fk"))
                .unwrap_or("planar_2dof")
                .to_owned();
            if !socks.contains_key(&robot) {
                socks.insert(robot.clone(), open_ws(&app, &robot).await);
            }
            let sock = socks.get_mut(&robot).unwrap();
            if let Err(e) = run_ws_case(sock, case).await {
                failures.push(format!("WS {name}: {e}"));
                socks.remove(&robot);
            }
        }
    }
    // Nothing the corpus sent was registered.
    let list: Value = app.get("/v1/robots").await.json().await.unwrap();
    let registered: Vec<&Value> = list["robots"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["source"] == "registered")
        .collect();
    assert!(registered.is_empty(), "{registered:?}");
    let names: Vec<String> = std::fs::read_dir(app.data_dir.join("robots"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.is_empty(), "files written: {names:?}");
    let report = checker.finish().await;
    // Today's corpus: 123 cases (122 over HTTP, 58 on the WebSocket); a
    // corpus file that lost cases (or a filter that skips them) fails.
    assert!(
        cases.len() >= 123,
        "{} REST corpus cases (at least 123)",
        cases.len()
    );
    assert!(
        rest_n >= 122 && ws_n >= 58,
        "{rest_n} HTTP cases, {ws_n} WebSocket cases"
    );
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    assert_eq!(app.get("/healthz").await.status(), 200);
    println!(
        "hostile REST corpus: {rest_n} HTTP requests, {ws_n} WebSocket messages; parallel FK ok: {} REST, {} gRPC, {} WebSocket",
        report.rest, report.grpc, report.ws
    );
}
