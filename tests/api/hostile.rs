//! Hostile input: the bad-input corpus in `tests/corpus/` run over REST, the
//! WebSocket stream and gRPC (typed messages and raw frames), while a parallel
//! client keeps asking for correct FK and checks every answer; plus WebSocket
//! frame abuse, slowloris, floods, slow readers, panics and the token rule.
//!
//! Every case must get its documented status (HTTP 4xx problem+json or gRPC
//! code) with the field at fault, and the server must keep answering.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use kinserve::model::{AngleUnit, FkOptions};
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_stream::wrappers::ReceiverStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::protocol::frame::Frame;
use tokio_tungstenite::tungstenite::protocol::frame::coding::{CloseCode, Data, OpCode};
use tonic::Code;

use crate::grpc::{rpc_status_fields, status_fields};
use crate::helpers::*;
use crate::rest::check_problem;

type Ws = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<TcpStream>>;

/// Generous bound for "eventually" (liveness, not performance).
const EVENTUALLY: Duration = Duration::from_secs(10);

// ---------------------------------------------------------------- corpus

fn corpus(name: &str) -> Vec<Value> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/corpus")
        .join(name);
    let doc: Value = serde_json::from_slice(&std::fs::read(&path).expect("corpus file"))
        .expect("corpus is JSON");
    doc["cases"].as_array().expect("cases").clone()
}

fn corpus_bytes(name: &str) -> Vec<u8> {
    std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/corpus")
            .join(name),
    )
    .expect("corpus data file")
}

fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

fn join(n: usize, item: &str) -> String {
    vec![item; n].join(",")
}

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

fn addr_of(url: &str) -> String {
    url.trim_start_matches("http://").to_owned()
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

// ---------------------------------------------------------------- parallel FK client

/// Joint configurations (degrees) the parallel client cycles through.
const CHECK_CONFIGS: [[f64; 6]; 4] = [
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [10.0, -20.0, 30.0, -40.0, 50.0, -60.0],
    [-90.0, 45.0, 12.5, 100.0, -30.0, 170.0],
    [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
];

fn reference_matrices() -> Vec<Vec<f64>> {
    let robot = kinserve::model::load_robot_file(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/puma560.json"),
    )
    .unwrap();
    let opts = FkOptions {
        angle_unit: AngleUnit::Deg,
        check_limits: true,
    };
    CHECK_CONFIGS
        .iter()
        .map(|q| {
            let t = robot.fk_checked(q, &opts).unwrap();
            t.matrix().iter().flatten().copied().collect()
        })
        .collect()
}

fn same_matrix(got: &[f64], want: &[f64]) -> bool {
    got.len() == 16
        && got
            .iter()
            .zip(want)
            .all(|(a, b)| (a - b).abs() <= 1e-12 * b.abs().max(1.0))
}

/// What the parallel client saw.
#[derive(Debug, Default)]
pub struct CheckReport {
    pub rest: usize,
    pub grpc: usize,
    pub ws: usize,
    pub failures: Vec<String>,
}

/// A client computing correct FK over REST, gRPC and a WebSocket in a loop,
/// checking every pose against the library, until stopped.
pub struct Checker {
    stop: Arc<AtomicBool>,
    task: tokio::task::JoinHandle<CheckReport>,
}

impl Checker {
    pub async fn start(http: &str, grpc: &str, ws: &str) -> Checker {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let (http, grpc, ws) = (http.to_owned(), grpc.to_owned(), ws.to_owned());
        let task = tokio::spawn(async move {
            let want = reference_matrices();
            let client = reqwest::Client::new();
            let mut g = KinematicsServiceClient::connect(grpc).await.unwrap();
            let url = format!("{ws}/v1/robots/puma560/fk/stream");
            let (mut sock, _) = tokio_tungstenite::connect_async(url.as_str())
                .await
                .unwrap();
            let mut r = CheckReport::default();
            let mut i = 0usize;
            // At least one full round, then until told to stop.
            while i < CHECK_CONFIGS.len() || !flag.load(Ordering::Acquire) {
                let k = i % CHECK_CONFIGS.len();
                let q = CHECK_CONFIGS[k];
                i += 1;
                // REST
                let body = json!({"joints": q, "angle_unit": "deg"});
                match client
                    .post(format!("{http}/v1/robots/puma560/fk"))
                    .json(&body)
                    .send()
                    .await
                {
                    Ok(resp) if resp.status() == 200 => {
                        let v: Value = resp.json().await.unwrap_or(Value::Null);
                        if same_matrix(&matrix16(&v["pose"]), &want[k]) {
                            r.rest += 1;
                        } else {
                            r.failures.push(format!("REST wrong pose for {q:?}: {v}"));
                        }
                    }
                    Ok(resp) => r.failures.push(format!("REST status {}", resp.status())),
                    Err(e) => r.failures.push(format!("REST error {e}")),
                }
                // gRPC
                let req = pb::ForwardKinematicsRequest {
                    robot: "puma560".into(),
                    joints: q.to_vec(),
                    options: Some(pb::FkOptions {
                        angle_unit: pb::AngleUnit::Deg as i32,
                        ..Default::default()
                    }),
                };
                match g.forward_kinematics(req).await {
                    Ok(resp) => {
                        let m = resp.into_inner().pose.map(|p| p.matrix).unwrap_or_default();
                        if same_matrix(&m, &want[k]) {
                            r.grpc += 1;
                        } else {
                            r.failures.push(format!("gRPC wrong pose for {q:?}"));
                        }
                    }
                    Err(e) => r.failures.push(format!("gRPC error {e:?}")),
                }
                // WebSocket
                let msg = json!({"id": i, "joints": q, "angle_unit": "deg"}).to_string();
                if let Err(e) = sock.send(Message::Text(msg.into())).await {
                    r.failures.push(format!("WS send error {e}"));
                    break;
                }
                match tokio::time::timeout(EVENTUALLY, next_text(&mut sock)).await {
                    Ok(Some(v)) if v["id"] == json!(i) => {
                        if same_matrix(&matrix16(&v["pose"]), &want[k]) {
                            r.ws += 1;
                        } else {
                            r.failures.push(format!("WS wrong reply {v}"));
                        }
                    }
                    other => {
                        r.failures.push(format!("WS no reply: {other:?}"));
                        break;
                    }
                }
            }
            r
        });
        Checker { stop, task }
    }

    /// Stops the client and asserts every answer it got was correct.
    pub async fn finish(self) -> CheckReport {
        self.stop.store(true, Ordering::Release);
        let r = self.task.await.expect("checker task");
        assert!(
            r.failures.is_empty(),
            "the parallel FK client saw failures: {:#?}",
            r.failures
        );
        assert!(r.rest > 0 && r.grpc > 0 && r.ws > 0, "{r:?}");
        r
    }
}

/// The next text message of a WebSocket as JSON (None: closed or errored).
async fn next_text(sock: &mut Ws) -> Option<Value> {
    loop {
        match sock.next().await? {
            Ok(Message::Text(t)) => return serde_json::from_str(t.as_str()).ok(),
            Ok(Message::Ping(_) | Message::Pong(_)) => continue,
            _ => return None,
        }
    }
}

async fn open_ws(app: &TestApp, robot: &str) -> Ws {
    let url = format!("{}/v1/robots/{robot}/fk/stream", app.ws);
    tokio_tungstenite::connect_async(url.as_str())
        .await
        .expect("websocket opens")
        .0
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
        return Ok(());
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
        if reply["pose"]["matrix"].is_array() && reply.get("error").is_none() {
            return Ok(());
        }
        return Err(format!("expected a pose: {reply}"));
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

// ---------------------------------------------------------------- gRPC corpus

fn num(v: &Value) -> f64 {
    match v {
        Value::Number(n) => n.as_f64().unwrap(),
        Value::String(s) => match s.as_str() {
            "NaN" => f64::NAN,
            "Infinity" => f64::INFINITY,
            "-Infinity" => f64::NEG_INFINITY,
            "-0" => -0.0,
            other => panic!("unknown number {other}"),
        },
        other => panic!("not a number: {other}"),
    }
}

fn nums(v: &Value) -> Vec<f64> {
    v.as_array()
        .map(|a| a.iter().map(num).collect())
        .unwrap_or_default()
}

fn enum_of(v: &Value, names: &[(&str, i32)], default: i32) -> i32 {
    match v {
        Value::Number(n) => n.as_i64().unwrap() as i32,
        Value::String(s) => names.iter().find(|(n, _)| n == s).unwrap().1,
        _ => default,
    }
}

fn transform_pb(t: &Value) -> Option<pb::FixedTransform> {
    if t.is_null() {
        return None;
    }
    use pb::fixed_transform::Rotation;
    let rotation = if !t["matrix"].is_null() {
        Some(Rotation::Matrix(pb::Matrix4 {
            values: nums(&t["matrix"]),
        }))
    } else if !t["quaternion"].is_null() {
        let q = nums(&t["quaternion"]);
        Some(Rotation::Quaternion(pb::Quaternion {
            w: q[0],
            x: q[1],
            y: q[2],
            z: q[3],
        }))
    } else {
        None
    };
    Some(pb::FixedTransform {
        translation: None,
        rotation,
    })
}

fn model_pb(m: &Value) -> pb::Robot {
    let joints = [
        ("revolute", pb::JointType::Revolute as i32),
        ("prismatic", pb::JointType::Prismatic as i32),
        ("fixed", pb::JointType::Fixed as i32),
    ];
    pb::Robot {
        name: m["name"].as_str().unwrap_or("").to_owned(),
        description: m["description"].as_str().map(str::to_owned),
        source: None,
        convention: enum_of(
            &m["convention"],
            &[
                ("standard", pb::Convention::Standard as i32),
                ("modified", pb::Convention::Modified as i32),
            ],
            0,
        ),
        angle_unit: enum_of(
            &m["angle_unit"],
            &[
                ("rad", pb::AngleUnit::Rad as i32),
                ("deg", pb::AngleUnit::Deg as i32),
            ],
            0,
        ),
        length_unit: enum_of(
            &m["length_unit"],
            &[
                ("m", pb::LengthUnit::M as i32),
                ("mm", pb::LengthUnit::Mm as i32),
            ],
            0,
        ),
        base: transform_pb(&m["base"]),
        tool: transform_pb(&m["tool"]),
        links: m["links"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| pb::Link {
                name: None,
                joint: enum_of(&l["joint"], &joints, 0),
                a: num(&l["a"]),
                alpha: num(&l["alpha"]),
                d: num(&l["d"]),
                theta: num(&l["theta"]),
                limits: l["limits"].as_array().map(|x| pb::Limits {
                    lo: num(&x[0]),
                    hi: num(&x[1]),
                }),
            })
            .collect(),
    }
}

fn gen_n(case: &Value) -> usize {
    case["gen"]["n"].as_u64().unwrap_or(0) as usize
}

fn case_joints(case: &Value) -> Vec<f64> {
    match case["gen"]["kind"].as_str() {
        Some("joints") => vec![0.0; gen_n(case)],
        _ => nums(&case["joints"]),
    }
}

fn case_options(case: &Value) -> Option<pb::FkOptions> {
    case["angle_unit"].as_i64().map(|u| pb::FkOptions {
        angle_unit: u as i32,
        ..Default::default()
    })
}

fn code_named(name: &str) -> Code {
    match name {
        "Ok" => Code::Ok,
        "InvalidArgument" => Code::InvalidArgument,
        "NotFound" => Code::NotFound,
        "ResourceExhausted" => Code::ResourceExhausted,
        "Unimplemented" => Code::Unimplemented,
        other => panic!("code {other}"),
    }
}

fn check_status(case: &Value, r: Result<(), tonic::Status>) -> Result<(), String> {
    let want = code_named(case["code"].as_str().unwrap());
    let status = match r {
        Ok(()) if want == Code::Ok => return Ok(()),
        Ok(()) => return Err(format!("OK instead of {want:?}")),
        Err(s) => s,
    };
    if status.code() != want {
        return Err(format!(
            "{:?} instead of {want:?}: {status:?}",
            status.code()
        ));
    }
    if status.message().is_empty() {
        return Err("empty status message".into());
    }
    let got = status_fields(&status).into_iter().next();
    let want_field = case["field"].as_str().map(str::to_owned);
    if got != want_field {
        return Err(format!(
            "field {got:?} instead of {want_field:?}: {status:?}"
        ));
    }
    Ok(())
}

async fn run_grpc_case(
    c: &mut KinematicsServiceClient<tonic::transport::Channel>,
    raw: &reqwest::Client,
    grpc: &str,
    case: &Value,
) -> Result<(), String> {
    let r = match case["rpc"].as_str().unwrap() {
        "fk" => c
            .forward_kinematics(pb::ForwardKinematicsRequest {
                robot: case["robot"].as_str().unwrap().to_owned(),
                joints: case_joints(case),
                options: case_options(case),
            })
            .await
            .map(drop),
        "batch" => {
            let configurations = match case["gen"]["kind"].as_str() {
                Some("configs") => vec![
                    pb::JointConfiguration {
                        joints: vec![0.0, 0.0]
                    };
                    gen_n(case)
                ],
                _ => case["configurations"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|q| pb::JointConfiguration { joints: nums(q) })
                    .collect(),
            };
            c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
                robot: case["robot"].as_str().unwrap().to_owned(),
                configurations,
                options: None,
            })
            .await
            .map(drop)
        }
        "register" => {
            let robot = match case["gen"]["kind"].as_str() {
                Some("links") => {
                    let joint = case["gen"]["joint"].as_str().unwrap_or("fixed");
                    let row = json!({"joint": joint, "a": 0, "alpha": 0, "d": 0, "theta": 0});
                    Some(model_pb(&json!({
                        "name": "hostile_links", "convention": "standard",
                        "links": vec![row; gen_n(case)],
                    })))
                }
                _ if case["model"].is_null() => None,
                _ => Some(model_pb(&case["model"])),
            };
            c.register_robot(pb::RegisterRobotRequest {
                robot,
                replace: false,
            })
            .await
            .map(drop)
        }
        "get" => c
            .get_robot(pb::GetRobotRequest {
                name: case["name"].as_str().unwrap().to_owned(),
            })
            .await
            .map(drop),
        "delete" => c
            .delete_robot(pb::DeleteRobotRequest {
                name: case["name"].as_str().unwrap().to_owned(),
            })
            .await
            .map(drop),
        "raw" => return run_raw_grpc_case(raw, grpc, case).await,
        other => panic!("rpc {other}"),
    };
    check_status(case, r)
}

/// POSTs raw gRPC frames over h2c and reads the status from the (trailers-only) response.
async fn run_raw_grpc_case(raw: &reqwest::Client, grpc: &str, case: &Value) -> Result<(), String> {
    let method = case["method"].as_str().unwrap();
    let mut req = raw
        .post(format!("{grpc}/kinematics.v1.KinematicsService/{method}"))
        .header("content-type", "application/grpc")
        .header("te", "trailers")
        .body(hex(case["frame_hex"].as_str().unwrap()));
    if let Some(h) = case["headers"].as_object() {
        for (k, v) in h {
            req = req.header(k.as_str(), v.as_str().unwrap());
        }
    }
    let resp = req.send().await.map_err(|e| format!("send: {e}"))?;
    if resp.status() != 200 {
        return Err(format!("HTTP status {}", resp.status()));
    }
    let code = resp
        .headers()
        .get("grpc-status")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<i32>().ok())
        .ok_or_else(|| format!("no grpc-status in the headers: {:?}", resp.headers()))?;
    let message = resp
        .headers()
        .get("grpc-message")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_owned();
    let want = code_named(case["code"].as_str().unwrap());
    if Code::from_i32(code) != want {
        return Err(format!(
            "{:?} instead of {want:?}: {message}",
            Code::from_i32(code)
        ));
    }
    if message.is_empty() {
        return Err("empty grpc-message".into());
    }
    Ok(())
}

async fn run_stream_cases(
    c: &mut KinematicsServiceClient<tonic::transport::Channel>,
    cases: &[&Value],
) -> Vec<String> {
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let mut inbound = c
        .stream_forward_kinematics(ReceiverStream::new(rx))
        .await
        .expect("stream opens")
        .into_inner();
    let mut failures = Vec::new();
    for (i, case) in cases.iter().enumerate() {
        let name = case["name"].as_str().unwrap();
        let id = i as u64 + 1;
        tx.send(pb::StreamForwardKinematicsRequest {
            id,
            robot: case["robot"].as_str().unwrap().to_owned(),
            joints: case_joints(case),
            options: case_options(case),
        })
        .await
        .unwrap();
        let resp = match inbound.message().await {
            Ok(Some(m)) => m,
            other => {
                failures.push(format!("stream {name}: {other:?}"));
                return failures;
            }
        };
        if resp.id != id {
            failures.push(format!("stream {name}: id {} instead of {id}", resp.id));
        }
        let want = code_named(case["code"].as_str().unwrap());
        match (&resp.result, want) {
            (Some(StreamResult::Pose(_)), Code::Ok) => {}
            (Some(StreamResult::Error(s)), w) if s.code == w as i32 => {
                let got = rpc_status_fields(s).into_iter().next();
                let want_field = case["field"].as_str().map(str::to_owned);
                if got != want_field || s.message.is_empty() {
                    failures.push(format!(
                        "stream {name}: field {got:?} instead of {want_field:?} ({s:?})"
                    ));
                }
            }
            (other, w) => failures.push(format!("stream {name}: {other:?} instead of {w:?}")),
        }
    }
    drop(tx);
    failures
}

/// The gRPC corpus: typed messages on every RPC, the FK ones again on the
/// bidirectional stream, and raw frames (garbage, truncated, oversized,
/// compressed) over h2c; a parallel client checks correct FK all along.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn the_grpc_corpus_gets_documented_statuses_and_the_server_keeps_answering() {
    let app = spawn_app().await;
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    let cases = corpus("grpc.json");
    let mut c = app.grpc_client().await;
    let raw = reqwest::Client::builder()
        .http2_prior_knowledge()
        .build()
        .unwrap();
    let mut failures = Vec::new();
    for case in &cases {
        let name = case["name"].as_str().unwrap();
        if let Err(e) = run_grpc_case(&mut c, &raw, &app.grpc, case).await {
            failures.push(format!("{name}: {e}"));
        }
    }
    let stream_cases: Vec<&Value> = cases.iter().filter(|c| c["stream"] == true).collect();
    failures.extend(run_stream_cases(&mut c, &stream_cases).await);
    // Nothing was registered; the server still answers on the same channel.
    let list = c.list_robots(pb::ListRobotsRequest {}).await.unwrap();
    assert!(
        list.into_inner()
            .robots
            .iter()
            .all(|r| r.source == pb::RobotSource::Builtin as i32)
    );
    let report = checker.finish().await;
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    println!(
        "hostile gRPC corpus: {} calls, {} stream messages; parallel FK ok: {} REST, {} gRPC, {} WebSocket",
        cases.len(),
        stream_cases.len(),
        report.rest,
        report.grpc,
        report.ws
    );
}

// ---------------------------------------------------------------- WebSocket frames

/// Waits for the server to end a WebSocket (close frame, EOF or error); returns the close code if any.
async fn closed_by_server(sock: &mut Ws) -> Option<u16> {
    let end = tokio::time::timeout(EVENTUALLY, async {
        loop {
            match sock.next().await {
                Some(Ok(Message::Close(frame))) => return frame.map(|f| u16::from(f.code)),
                Some(Ok(_)) => continue,
                Some(Err(_)) | None => return None,
            }
        }
    })
    .await;
    end.expect("the server ends the connection")
}

/// Binary and fragmented frames, invalid UTF-8, an oversized message and a
/// ping flood: each gets an error reply or a close, never a hung or dead server.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn websocket_binary_fragmented_invalid_and_oversized_frames() {
    let app = spawn_app_with(|c| c.max_body_bytes = 64 << 10).await;
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    let mut sock = open_ws(&app, "planar_2dof").await;
    let fk = br#"{"id": 7, "joints": [0, 0]}"#;

    // A binary message: 415 error reply, the stream goes on.
    sock.send(Message::Binary(fk.to_vec().into()))
        .await
        .unwrap();
    let reply = next_text(&mut sock).await.unwrap();
    assert_eq!(reply["error"]["status"], 415, "{reply}");
    // A text message in three fragments: one message, one reply.
    for (i, part) in fk.chunks(10).enumerate() {
        let op = if i == 0 {
            OpCode::Data(Data::Text)
        } else {
            OpCode::Data(Data::Continue)
        };
        let last = (i + 1) * 10 >= fk.len();
        sock.send(Message::Frame(Frame::message(part.to_vec(), op, last)))
            .await
            .unwrap();
    }
    let reply = next_text(&mut sock).await.unwrap();
    assert_eq!(reply["id"], 7, "{reply}");
    assert!(reply["pose"].is_object(), "{reply}");
    // A fragmented binary message: still 415.
    sock.send(Message::Frame(Frame::message(
        fk[..5].to_vec(),
        OpCode::Data(Data::Binary),
        false,
    )))
    .await
    .unwrap();
    sock.send(Message::Frame(Frame::message(
        fk[5..].to_vec(),
        OpCode::Data(Data::Continue),
        true,
    )))
    .await
    .unwrap();
    let reply = next_text(&mut sock).await.unwrap();
    assert_eq!(reply["error"]["status"], 415, "{reply}");
    // A ping flood is answered and does not disturb the replies.
    for i in 0..1000u32 {
        sock.send(Message::Ping(i.to_be_bytes().to_vec().into()))
            .await
            .unwrap();
    }
    sock.send(Message::Text(r#"{"id": 8, "joints": [0, 0]}"#.into()))
        .await
        .unwrap();
    let reply = next_text(&mut sock).await.unwrap();
    assert_eq!(reply["id"], 8, "{reply}");

    // Invalid UTF-8 in a text frame: the connection is closed (1007 or a plain close).
    sock.send(Message::Frame(Frame::message(
        vec![b'{', 0xff, 0xfe, b'}'],
        OpCode::Data(Data::Text),
        true,
    )))
    .await
    .unwrap();
    let code = closed_by_server(&mut sock).await;
    assert!(
        code.is_none_or(|c| c == u16::from(CloseCode::Invalid)),
        "{code:?}"
    );

    // A message over the limit (64 KiB here), whole or in fragments: closed (1009 or plain).
    let mut sock = open_ws(&app, "planar_2dof").await;
    let big = format!(r#"{{"id": "{}", "joints": [0, 0]}}"#, "x".repeat(100 << 10));
    let _ = sock.send(Message::Text(big.clone().into())).await;
    let code = closed_by_server(&mut sock).await;
    assert!(
        code.is_none_or(|c| c == u16::from(CloseCode::Size)),
        "{code:?}"
    );
    let mut sock = open_ws(&app, "planar_2dof").await;
    for (i, part) in big.as_bytes().chunks(16 << 10).enumerate() {
        let op = if i == 0 {
            OpCode::Data(Data::Text)
        } else {
            OpCode::Data(Data::Continue)
        };
        if sock
            .send(Message::Frame(Frame::message(part.to_vec(), op, false)))
            .await
            .is_err()
        {
            break;
        }
    }
    let code = closed_by_server(&mut sock).await;
    assert!(
        code.is_none_or(|c| c == u16::from(CloseCode::Size)),
        "{code:?}"
    );

    // A fresh stream works.
    let mut sock = open_ws(&app, "planar_2dof").await;
    sock.send(Message::Text(r#"{"id": 9, "joints": [0, 0]}"#.into()))
        .await
        .unwrap();
    assert_eq!(next_text(&mut sock).await.unwrap()["id"], 9);
    checker.finish().await;
}

/// A client that sends on a WebSocket and never reads is stopped by
/// backpressure (TCP flow control): the server holds at most one reply per
/// stream and does not buffer the rest, so the client's sends block long
/// before it has pushed an unbounded amount. Other clients are unaffected.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_websocket_client_that_never_reads_is_held_back_by_backpressure() {
    let app = spawn_app().await;
    let (sock, _) =
        tokio_tungstenite::connect_async(format!("{}/v1/robots/planar_2dof/fk/stream", app.ws))
            .await
            .unwrap();
    let (mut tx, rx) = sock.split();
    // 16 KiB ids: every reply echoes one.
    let msg = format!(
        r#"{{"id": "{}", "joints": [0.1, 0.2], "frames": true}}"#,
        "y".repeat(16 << 10)
    );
    const BOUND: usize = 256 << 20; // far above any socket buffers
    let mut sent = 0usize;
    let mut stalled = false;
    while sent < BOUND {
        match tokio::time::timeout(
            Duration::from_secs(2),
            tx.send(Message::Text(msg.clone().into())),
        )
        .await
        {
            Ok(Ok(())) => sent += msg.len(),
            Ok(Err(e)) => panic!("send failed after {sent} bytes: {e}"),
            Err(_) => {
                stalled = true;
                break;
            }
        }
    }
    assert!(stalled, "sent {sent} bytes without being held back");
    // The server is fine meanwhile.
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    checker.finish().await;
    println!(
        "WebSocket slow reader: held back after {} KiB sent",
        sent >> 10
    );
    drop((tx, rx));
}

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
    let channel = crate::grpc::channel(&app).await;
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
    registry.load_builtins(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots"),
        &limits.model,
    );
    let service = Arc::new(Service::new(registry, limits, None));
    service.set_ready(true);
    let mut config = kinserve::config::ServeConfig::for_tests(std::env::temp_dir());
    config.max_concurrent_requests = 1;
    let (_tx, shutdown) = tokio::sync::watch::channel(false);
    let state = AppState::new(AppInner {
        service,
        config: Arc::new(config),
        shutdown,
        metrics: kinserve::telemetry::metrics_handle(),
        permits: Arc::new(tokio::sync::Semaphore::new(1)),
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
        let p = crate::rest::problem(r, 500).await;
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
            let p = crate::rest::problem(r, 401).await;
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
    assert_eq!(reply["error"]["status"], 422, "{reply}");
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
        let mut r = ServerReflectionClient::new(crate::grpc::channel(&app).await);
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
    let mut server = crate::crash::start_server(
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
