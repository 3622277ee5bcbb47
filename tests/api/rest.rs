//! REST contract tests: every endpoint and status code of the REST API, FK of
//! built-ins against their closed forms, the token rule, persistence across a
//! restart and start-up with a corrupt data directory.

use std::path::Path;

use kinserve::App;
use kinserve::config::ServeConfig;
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use crate::helpers::*;

/// Tolerance for closed forms (absolute, scaled by max(1, |expected|)).
const CLOSED_FORM_TOL: f64 = 1e-9;
/// Tolerance for comparing two results of the same library.
const SAME_LIB_TOL: f64 = 1e-12;

// ---------------------------------------------------------------- helpers

/// Asserts `r` is an RFC 9457 problem with HTTP status `status` and returns its body.
pub(crate) async fn problem(r: reqwest::Response, status: u16) -> Value {
    let got = r.status().as_u16();
    let ct = r
        .headers()
        .get("content-type")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_owned();
    let text = r.text().await.expect("body");
    assert_eq!(got, status, "status (body: {text})");
    assert_eq!(
        ct, "application/problem+json",
        "content type (body: {text})"
    );
    let body: Value = serde_json::from_str(&text).expect("problem is JSON");
    check_problem(&body, status);
    body
}

/// Asserts `body` has the problem shape with `status`.
pub(crate) fn check_problem(body: &Value, status: u16) {
    let ty = body["type"].as_str().expect("type");
    assert!(ty.starts_with("urn:kinserve:problem:"), "type {ty}");
    assert!(
        !body["title"].as_str().expect("title").is_empty(),
        "title in {body}"
    );
    assert_eq!(body["status"], status, "status field in {body}");
    assert!(body["detail"].is_string(), "detail in {body}");
    if let Some(errors) = body.get("errors") {
        for e in errors.as_array().expect("errors array") {
            assert!(e["field"].is_string() && e["message"].is_string(), "{e}");
        }
    }
}

/// The `field`s of a problem's `errors`.
pub(crate) fn fields(problem: &Value) -> Vec<String> {
    problem["errors"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|e| e["field"].as_str().unwrap_or("").to_owned())
                .collect()
        })
        .unwrap_or_default()
}

/// JSON equality with numbers compared as f64 (`0` equals `0.0`).
pub(crate) fn json_eq(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => x.as_f64() == y.as_f64(),
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(p, q)| json_eq(p, q))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| json_eq(v, w)))
        }
        _ => a == b,
    }
}

/// Asserts two JSON poses agree entry by entry (matrix, position, quaternion, rpy).
pub(crate) fn assert_pose_eq(a: &Value, b: &Value, tol: f64, what: &str) {
    let (ma, mb) = (matrix16(a), matrix16(b));
    for (i, (x, y)) in ma.iter().zip(&mb).enumerate() {
        assert_close(
            *x,
            *y,
            tol,
            &format!("{what}: matrix[{}][{}]", i / 4, i % 4),
        );
    }
    let (pa, pb) = (position(a), position(b));
    for i in 0..3 {
        assert_close(pa[i], pb[i], tol, &format!("{what}: position[{i}]"));
        let (ra, rb) = (a["rpy"][i].as_f64().unwrap(), b["rpy"][i].as_f64().unwrap());
        assert_close(ra, rb, tol, &format!("{what}: rpy[{i}]"));
    }
    for k in ["w", "x", "y", "z"] {
        let (qa, qb) = (
            a["quaternion"][k].as_f64().unwrap(),
            b["quaternion"][k].as_f64().unwrap(),
        );
        assert_close(qa, qb, tol, &format!("{what}: quaternion.{k}"));
    }
}

/// Asserts the 3×4 upper part of a JSON pose's matrix equals `expect` (row-major).
fn assert_matrix(pose: &Value, expect: [[f64; 4]; 3], what: &str) {
    let m = matrix16(pose);
    for (r, row) in expect.iter().enumerate() {
        for (c, x) in row.iter().enumerate() {
            assert_close(
                m[r * 4 + c],
                *x,
                CLOSED_FORM_TOL,
                &format!("{what}[{r}][{c}]"),
            );
        }
    }
    assert_eq!(&m[12..], &[0.0, 0.0, 0.0, 1.0], "{what}: last row");
    let p = position(pose);
    for i in 0..3 {
        assert_close(
            p[i],
            m[i * 4 + 3],
            0.0,
            &format!("{what}: position[{i}] vs matrix"),
        );
    }
}

/// `POST /v1/robots/{robot}/fk`, expecting 200; the response body.
async fn fk_ok(app: &TestApp, robot: &str, body: Value) -> Value {
    let r = app.post(&format!("/v1/robots/{robot}/fk"), &body).await;
    let status = r.status();
    let text = r.text().await.unwrap();
    assert_eq!(status, 200, "fk {robot} {body}: {text}");
    serde_json::from_str(&text).unwrap()
}

fn builtin_file(name: &str) -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("robots")
        .join(format!("{name}.json"));
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
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

// ---------------------------------------------------------------- health, ops

#[tokio::test]
async fn healthz_and_readyz_answer_200_once_loaded() {
    let app = spawn_app().await;
    let r = app.get("/healthz").await;
    assert_eq!(r.status(), 200);
    let r = app.get("/readyz").await;
    assert_eq!(r.status(), 200);
}

/// `/readyz` answers 503 (problem+json, Retry-After) whenever the service is not
/// ready. Shutdown flips readiness, but the HTTP listener stops accepting at the
/// same moment (axum graceful shutdown), so a 503 *during* shutdown cannot be
/// fetched over HTTP: the not-ready answer is provoked through the service
/// handle instead, and the flip on shutdown is checked on the same handle.
#[tokio::test]
async fn readyz_is_503_with_retry_after_when_not_ready_and_shutdown_flips_readiness() {
    let tmp = tempfile::tempdir().unwrap();
    let app = App::build(ServeConfig::for_tests(tmp.path().to_path_buf()))
        .await
        .unwrap();
    let service = app.service();
    assert!(!service.is_ready(), "not ready before serving");
    let base = format!("http://{}", app.http_addr());
    let shutdown = app.shutdown_handle();
    let task = tokio::spawn(app.run_until_stopped());
    let client = reqwest::Client::new();
    let mut ready = false;
    for _ in 0..500 {
        if let Ok(r) = client.get(format!("{base}/readyz")).send().await
            && r.status() == 200
        {
            ready = true;
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    assert!(ready, "server became ready");

    service.set_ready(false);
    let r = client.get(format!("{base}/readyz")).send().await.unwrap();
    assert_eq!(
        r.headers().get("retry-after").map(|v| v.to_str().unwrap()),
        Some("1")
    );
    let p = problem(r, 503).await;
    assert_eq!(p["type"], "urn:kinserve:problem:unavailable");
    // Liveness is unaffected.
    let r = client.get(format!("{base}/healthz")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    service.set_ready(true);
    let r = client.get(format!("{base}/readyz")).send().await.unwrap();
    assert_eq!(r.status(), 200);

    shutdown.shutdown();
    task.await.unwrap().unwrap();
    assert!(!service.is_ready(), "readiness flipped on shutdown");
}

#[tokio::test]
async fn unknown_route_is_404_problem() {
    let app = spawn_app().await;
    let p = problem(app.get("/v2/nothing").await, 404).await;
    assert_eq!(p["type"], "urn:kinserve:problem:no-route");
}

#[tokio::test]
async fn x_request_id_is_echoed_or_generated() {
    let app = spawn_app().await;
    let r = app
        .client
        .get(format!("{}/v1/robots", app.http))
        .header("x-request-id", "trace-me-42")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["x-request-id"], "trace-me-42");

    // Generated when absent, also on errors; different per request.
    let a = app.get("/v1/robots/nope").await;
    assert_eq!(a.status(), 404);
    let b = app.get("/healthz").await;
    let ida = a.headers()["x-request-id"].to_str().unwrap().to_owned();
    let idb = b.headers()["x-request-id"].to_str().unwrap().to_owned();
    assert!(!ida.is_empty() && !idb.is_empty());
    assert_ne!(ida, idb);
}

#[tokio::test]
async fn cors_allows_any_origin_by_default() {
    let app = spawn_app().await;
    let r = app
        .client
        .get(format!("{}/v1/robots", app.http))
        .header("origin", "https://anywhere.example")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["access-control-allow-origin"], "*");

    // Preflight of a mutating request.
    let r = app
        .client
        .request(
            reqwest::Method::OPTIONS,
            format!("{}/v1/robots/x", app.http),
        )
        .header("origin", "https://anywhere.example")
        .header("access-control-request-method", "PUT")
        .header(
            "access-control-request-headers",
            "authorization, content-type",
        )
        .send()
        .await
        .unwrap();
    assert!(r.status().is_success(), "preflight {}", r.status());
    assert_eq!(r.headers()["access-control-allow-origin"], "*");
    let methods = r.headers()["access-control-allow-methods"]
        .to_str()
        .unwrap()
        .to_ascii_uppercase();
    assert!(
        methods.contains("PUT") && methods.contains("DELETE"),
        "{methods}"
    );
}

#[tokio::test]
async fn cors_is_restricted_by_cors_origins() {
    let app = spawn_app_with(|c| c.cors_origins = vec!["https://ok.example".into()]).await;
    let get = |origin: &'static str| {
        app.client
            .get(format!("{}/v1/robots", app.http))
            .header("origin", origin)
            .send()
    };
    let r = get("https://ok.example").await.unwrap();
    assert_eq!(
        r.headers()["access-control-allow-origin"],
        "https://ok.example"
    );
    let r = get("https://evil.example").await.unwrap();
    assert!(
        r.headers().get("access-control-allow-origin").is_none(),
        "no CORS grant for an unlisted origin"
    );
}

/// Every route the router serves, with its methods.
const ROUTES: &[(&str, &[&str])] = &[
    ("/healthz", &["get"]),
    ("/readyz", &["get"]),
    ("/metrics", &["get"]),
    ("/v1/robots", &["get", "post"]),
    ("/v1/robots/{name}", &["get", "put", "delete"]),
    ("/v1/robots/{name}/fk", &["post"]),
    ("/v1/robots/{name}/fk/batch", &["post"]),
    ("/v1/robots/{name}/fk/stream", &["get"]),
];

fn collect_refs(v: &Value, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                if k == "$ref"
                    && let Some(s) = x.as_str()
                {
                    out.push(s.to_owned());
                }
                collect_refs(x, out);
            }
        }
        Value::Array(a) => a.iter().for_each(|x| collect_refs(x, out)),
        _ => {}
    }
}

#[tokio::test]
async fn openapi_covers_every_route_and_schema() {
    let app = spawn_app().await;
    let r = app.get("/openapi.json").await;
    assert_eq!(r.status(), 200);
    let doc: Value = r.json().await.unwrap();
    assert!(doc["openapi"].as_str().unwrap().starts_with("3."));
    let paths = doc["paths"].as_object().expect("paths");
    for (path, methods) in ROUTES {
        let item = paths
            .get(*path)
            .unwrap_or_else(|| panic!("{path} missing from /openapi.json"));
        for m in *methods {
            assert!(
                item.get(*m).is_some(),
                "{m} {path} missing from /openapi.json"
            );
        }
    }
    let mut documented: Vec<_> = paths.keys().map(String::as_str).collect();
    documented.sort();
    let mut served: Vec<_> = ROUTES.iter().map(|(p, _)| *p).collect();
    served.sort();
    assert_eq!(
        documented, served,
        "documented paths are exactly the routes"
    );

    let schemas = doc["components"]["schemas"].as_object().expect("schemas");
    for s in [
        "RobotSpec",
        "LinkSpec",
        "TransformSpec",
        "RobotList",
        "RobotSummaryDto",
        "FkRequest",
        "FkBatchRequest",
        "FkBatchResponse",
        "FkOutput",
        "Pose",
        "Problem",
        "ProblemField",
        "WsRequest",
        "WsReply",
    ] {
        assert!(schemas.contains_key(s), "schema {s} missing");
    }
    let mut refs = Vec::new();
    collect_refs(&doc, &mut refs);
    assert!(!refs.is_empty());
    for r in refs {
        let name = r
            .strip_prefix("#/components/schemas/")
            .unwrap_or_else(|| panic!("unexpected $ref {r}"));
        assert!(schemas.contains_key(name), "dangling $ref {r}");
    }
    assert!(doc["components"]["securitySchemes"]["bearer"].is_object());

    // Every documented path is really routed (no `no-route` 404).
    for (path, methods) in ROUTES {
        let concrete = path.replace("{name}", "planar_2dof");
        let url = format!("{}{concrete}", app.http);
        let m = reqwest::Method::from_bytes(methods[0].to_ascii_uppercase().as_bytes()).unwrap();
        let r = app
            .client
            .request(m, url)
            .header("content-type", "application/json")
            .body("{}")
            .send()
            .await
            .unwrap();
        if r.status() == 404 {
            let p: Value = r.json().await.unwrap();
            assert_ne!(p["type"], "urn:kinserve:problem:no-route", "{path}");
        }
    }
}

#[tokio::test]
async fn docs_page_is_served() {
    let app = spawn_app().await;
    let r = app.get("/docs").await; // follows the redirect to /docs/
    assert_eq!(r.status(), 200);
    assert!(
        r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/html")
    );
    let html = r.text().await.unwrap().to_ascii_lowercase();
    assert!(html.contains("swagger"), "interactive docs page");
}

fn metric_value(text: &str, name: &str, labels: &[&str]) -> Option<f64> {
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .filter(|l| l.starts_with(name) && l[name.len()..].starts_with(['{', ' ']))
        .filter(|l| labels.iter().all(|x| l.contains(x)))
        .map(|l| l.rsplit(' ').next().unwrap().parse::<f64>().unwrap())
        .reduce(f64::max)
}

#[tokio::test]
async fn metrics_expose_requests_latency_poses_and_robots() {
    let app = spawn_app().await;
    fk_ok(&app, "planar_2dof", json!({"joints": [0.1, 0.2]})).await;
    let r = app
        .post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": [[0, 0], [1, 1], [2, 2]]}),
        )
        .await;
    assert_eq!(r.status(), 200);
    assert_eq!(app.get("/v1/robots/nope").await.status(), 404);

    let r = app.get("/metrics").await;
    assert_eq!(r.status(), 200);
    assert!(
        r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/plain")
    );
    let text = r.text().await.unwrap();
    let requests = "kinserve_http_requests_total";
    assert!(
        metric_value(
            &text,
            requests,
            &[
                r#"route="/v1/robots/{name}/fk""#,
                r#"status="200""#,
                r#"method="POST""#
            ]
        )
        .is_some_and(|v| v >= 1.0),
        "{text}"
    );
    assert!(
        metric_value(
            &text,
            requests,
            &[r#"route="/v1/robots/{name}""#, r#"status="404""#]
        )
        .is_some_and(|v| v >= 1.0),
        "{text}"
    );
    assert!(
        metric_value(
            &text,
            "kinserve_http_request_duration_seconds_bucket",
            &[r#"route="/v1/robots/{name}/fk/batch""#, "le="]
        )
        .is_some_and(|v| v >= 1.0),
        "latency histogram: {text}"
    );
    assert!(
        metric_value(
            &text,
            "kinserve_http_request_duration_seconds_count",
            &[r#"route="/v1/robots/{name}/fk""#]
        )
        .is_some_and(|v| v >= 1.0),
        "{text}"
    );
    // One single + three batched poses at least (the recorder is process-wide).
    assert!(
        metric_value(&text, "kinserve_poses_computed_total", &[]).is_some_and(|v| v >= 4.0),
        "{text}"
    );
    assert!(
        metric_value(&text, "kinserve_robots", &[r#"source="builtin""#]).is_some_and(|v| v >= 1.0),
        "{text}"
    );
    assert!(
        metric_value(&text, "kinserve_robots", &[r#"source="registered""#]).is_some(),
        "{text}"
    );
}

// ---------------------------------------------------------------- robots CRUD

#[tokio::test]
async fn list_robots_is_sorted_with_summaries_and_sources() {
    let app = spawn_app().await;
    let r = app.post("/v1/robots", &planar_model("aaa_first")).await;
    assert_eq!(r.status(), 201);
    let r = app.get("/v1/robots").await;
    assert_eq!(r.status(), 200);
    let body: Value = r.json().await.unwrap();
    let robots = body["robots"].as_array().expect("robots");
    let names: Vec<&str> = robots.iter().map(|r| r["name"].as_str().unwrap()).collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(names, sorted, "sorted by name");
    let builtin_count = std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("robots"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "json")
        })
        .count();
    assert_eq!(robots.len(), builtin_count + 1);
    let find = |n: &str| robots.iter().find(|r| r["name"] == n).cloned().unwrap();
    let a = find("aaa_first");
    assert!(
        json_eq(
            &a,
            &json!({"name": "aaa_first", "dof": 2, "convention": "standard", "length_unit": "m", "source": "registered"})
        ),
        "{a}"
    );
    let p = find("puma560");
    assert_eq!(p["dof"], 6);
    assert_eq!(p["source"], "builtin");
    assert_eq!(p["length_unit"], "m");
    let alpha = find("alpha_ii");
    assert_eq!(alpha["length_unit"], "mm");
    assert_eq!(alpha["dof"], 5);
    let s = find("scara_4dof");
    assert_eq!(s["dof"], 4);
    assert_eq!(s["convention"], "standard");
    for r in robots {
        for k in ["name", "dof", "convention", "length_unit", "source"] {
            assert!(r.get(k).is_some(), "{k} in {r}");
        }
        assert!(r["source"] == "builtin" || r["source"] == "registered");
    }
}

#[tokio::test]
async fn get_robot_returns_the_model_in_its_registered_schema() {
    let app = spawn_app().await;
    // Built-in: the robot file as written.
    let r = app.get("/v1/robots/scara_4dof").await;
    assert_eq!(r.status(), 200);
    let got: Value = r.json().await.unwrap();
    let file = builtin_file("scara_4dof");
    assert!(json_eq(&got, &file), "got {got}\nfile {file}");

    // Registered: what was posted, including optional parts.
    let mut model = planar_model("with_extras");
    model["description"] = json!("two links");
    model["base"] = json!({"translation": [1, 2, 3], "rpy": [0, 0, 90]});
    model["tool"] = json!({"translation": [0.1, 0, 0]});
    model["links"][0]["name"] = json!("shoulder");
    assert_eq!(app.post("/v1/robots", &model).await.status(), 201);
    let got: Value = app
        .get("/v1/robots/with_extras")
        .await
        .json()
        .await
        .unwrap();
    assert!(json_eq(&got, &model), "got {got}\nposted {model}");
}

#[tokio::test]
async fn unknown_robot_is_404_on_every_robot_route() {
    let app = spawn_app().await;
    let p = problem(app.get("/v1/robots/no_such_robot").await, 404).await;
    assert_eq!(p["type"], "urn:kinserve:problem:not-found");
    assert!(p["detail"].as_str().unwrap().contains("no_such_robot"));
    problem(
        app.post("/v1/robots/no_such_robot/fk", &json!({"joints": [0]}))
            .await,
        404,
    )
    .await;
    problem(
        app.post(
            "/v1/robots/no_such_robot/fk/batch",
            &json!({"configurations": [[0]]}),
        )
        .await,
        404,
    )
    .await;
    let r = app
        .client
        .delete(format!("{}/v1/robots/no_such_robot", app.http))
        .send()
        .await
        .unwrap();
    problem(r, 404).await;
}

#[tokio::test]
async fn post_creates_with_201_and_location_and_409_when_the_name_is_taken() {
    let app = spawn_app().await;
    let r = app.post("/v1/robots", &planar_model("arm1")).await;
    assert_eq!(r.status(), 201);
    let location = r.headers()["location"].to_str().unwrap().to_owned();
    assert_eq!(location, "/v1/robots/arm1");
    let created: Value = r.json().await.unwrap();
    assert!(json_eq(&created, &planar_model("arm1")));
    // The Location resolves to the model.
    let r = app.get(&location).await;
    assert_eq!(r.status(), 200);

    // Taken by a registered robot.
    let mut other = planar_model("arm1");
    other["links"][0]["a"] = json!(0.9);
    let p = problem(app.post("/v1/robots", &other).await, 409).await;
    assert_eq!(p["type"], "urn:kinserve:problem:already-exists");
    // Unchanged.
    let got: Value = app.get("/v1/robots/arm1").await.json().await.unwrap();
    assert!(json_eq(&got, &planar_model("arm1")));
    // Taken by a built-in.
    problem(app.post("/v1/robots", &planar_model("puma560")).await, 409).await;
}

#[tokio::test]
async fn put_creates_with_201_then_replaces_with_200() {
    let app = spawn_app().await;
    let put = |name: &str, body: Value| {
        app.client
            .put(format!("{}/v1/robots/{name}", app.http))
            .json(&body)
            .send()
    };
    let r = put("arm2", planar_model("arm2")).await.unwrap();
    assert_eq!(r.status(), 201);
    assert_eq!(r.headers()["location"], "/v1/robots/arm2");

    let mut replaced = planar_model("arm2");
    replaced["links"][0]["a"] = json!(0.7);
    let r = put("arm2", replaced.clone()).await.unwrap();
    assert_eq!(r.status(), 200);
    let body: Value = r.json().await.unwrap();
    assert!(json_eq(&body, &replaced));
    let got: Value = app.get("/v1/robots/arm2").await.json().await.unwrap();
    assert!(json_eq(&got, &replaced));
    // The replacement is what FK uses: x = 0.7 + 0.3 at q = 0.
    let out = fk_ok(&app, "arm2", json!({"joints": [0, 0]})).await;
    assert_close(position(&out["pose"])[0], 1.0, CLOSED_FORM_TOL, "x");
}

#[tokio::test]
async fn put_with_a_name_that_does_not_match_the_path_is_422() {
    let app = spawn_app().await;
    let r = app
        .client
        .put(format!("{}/v1/robots/arm3", app.http))
        .json(&planar_model("other_name"))
        .send()
        .await
        .unwrap();
    let p = problem(r, 422).await;
    assert_eq!(fields(&p), ["name"]);
    assert_eq!(app.get("/v1/robots/arm3").await.status(), 404);
    assert_eq!(app.get("/v1/robots/other_name").await.status(), 404);
}

/// The model schema requires `name` in a PUT body too (see the report: the issue's
/// "a name in the body must match" could also be read as "if present").
#[tokio::test]
async fn put_without_a_name_in_the_body_is_422_naming_it() {
    let app = spawn_app().await;
    let mut model = planar_model("ignored");
    model.as_object_mut().unwrap().remove("name");
    let r = app
        .client
        .put(format!("{}/v1/robots/nameless", app.http))
        .json(&model)
        .send()
        .await
        .unwrap();
    let p = problem(r, 422).await;
    assert_eq!(fields(&p), ["name"]);
    assert_eq!(app.get("/v1/robots/nameless").await.status(), 404);
}

#[tokio::test]
async fn delete_answers_204_then_404() {
    let app = spawn_app().await;
    assert_eq!(
        app.post("/v1/robots", &planar_model("gone")).await.status(),
        201
    );
    let del = || {
        app.client
            .delete(format!("{}/v1/robots/gone", app.http))
            .send()
    };
    let r = del().await.unwrap();
    assert_eq!(r.status(), 204);
    assert!(r.bytes().await.unwrap().is_empty());
    problem(app.get("/v1/robots/gone").await, 404).await;
    problem(del().await.unwrap(), 404).await;
    // The name is free again.
    assert_eq!(
        app.post("/v1/robots", &planar_model("gone")).await.status(),
        201
    );
}

#[tokio::test]
async fn builtins_are_read_only() {
    let app = spawn_app().await;
    let r = app
        .client
        .put(format!("{}/v1/robots/planar_2dof", app.http))
        .json(&planar_model("planar_2dof"))
        .send()
        .await
        .unwrap();
    let p = problem(r, 409).await;
    assert_eq!(p["type"], "urn:kinserve:problem:read-only");
    assert!(p["detail"].as_str().unwrap().contains("read-only"), "{p}");
    let r = app
        .client
        .delete(format!("{}/v1/robots/planar_2dof", app.http))
        .send()
        .await
        .unwrap();
    let p = problem(r, 409).await;
    assert_eq!(p["type"], "urn:kinserve:problem:read-only");
    assert!(p["detail"].as_str().unwrap().contains("read-only"), "{p}");
    // Still the built-in.
    let got: Value = app
        .get("/v1/robots/planar_2dof")
        .await
        .json()
        .await
        .unwrap();
    assert!(json_eq(&got, &builtin_file("planar_2dof")));
}

#[tokio::test]
async fn an_invalid_model_is_422_naming_every_field() {
    let app = spawn_app().await;
    let mut model = planar_model("Bad Name");
    model["links"][0]["limits"] = json!([10, -10]);
    model["links"]
        .as_array_mut()
        .unwrap()
        .push(json!({"joint": "fixed", "a": 0, "alpha": 0, "d": 0, "theta": 0, "limits": [0, 1]}));
    let p = problem(app.post("/v1/robots", &model).await, 422).await;
    assert_eq!(p["type"], "urn:kinserve:problem:invalid-input");
    let f = fields(&p);
    for expect in ["name", "links[0].limits", "links[2].limits"] {
        assert!(f.iter().any(|x| x == expect), "{expect} in {f:?}");
    }
    // Well-formed JSON breaking the schema (missing / unknown field) is 422 too.
    let mut missing = planar_model("m1");
    missing.as_object_mut().unwrap().remove("links");
    let p = problem(app.post("/v1/robots", &missing).await, 422).await;
    assert_eq!(fields(&p), ["links"]);
    let mut unknown = planar_model("m2");
    unknown["links"][1]["colour"] = json!("red");
    let p = problem(app.post("/v1/robots", &unknown).await, 422).await;
    assert!(fields(&p)[0].starts_with("links[1]"), "{p}");
}

#[tokio::test]
async fn malformed_json_or_wrong_types_are_400() {
    let app = spawn_app().await;
    let raw = |path: &str, body: &'static str| {
        app.client
            .post(format!("{}{path}", app.http))
            .header("content-type", "application/json")
            .body(body)
            .send()
    };
    let p = problem(raw("/v1/robots", "{\"name\": \"x\",").await.unwrap(), 400).await;
    assert_eq!(p["type"], "urn:kinserve:problem:malformed-request");
    problem(
        raw("/v1/robots/planar_2dof/fk", "not json").await.unwrap(),
        400,
    )
    .await;
    problem(
        raw("/v1/robots/planar_2dof/fk", "{\"joints\": [0, 0]} trailing")
            .await
            .unwrap(),
        400,
    )
    .await;
    // Wrong types name the field.
    let p = problem(
        app.post("/v1/robots/planar_2dof/fk", &json!({"joints": "zero"}))
            .await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["joints"]);
    let p = problem(
        app.post("/v1/robots/planar_2dof/fk", &json!({"joints": [0, "x"]}))
            .await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["joints[1]"]);
    let p = problem(
        app.post(
            "/v1/robots/planar_2dof/fk",
            &json!({"joints": [0, 0], "angle_unit": "grad"}),
        )
        .await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["angle_unit"]);
    let mut model = planar_model("typed");
    model["links"][1]["a"] = json!("long");
    let p = problem(app.post("/v1/robots", &model).await, 400).await;
    assert_eq!(fields(&p), ["links[1].a"]);
    let p = problem(
        app.post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": [[0, 0], [0, true]]}),
        )
        .await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["configurations[1][1]"]);
}

/// serde reads a struct from an array of its fields; the API must not: a
/// top-level array is a wrong type (400), not `{"joints": ...}`.
#[tokio::test]
async fn a_top_level_array_is_a_wrong_type_400() {
    let app = spawn_app().await;
    let raw = |path: &str, body: &'static str| {
        app.client
            .post(format!("{}{path}", app.http))
            .header("content-type", "application/json")
            .body(body)
            .send()
    };
    let p = problem(
        raw("/v1/robots/planar_2dof/fk", " [[0.5, 0]]")
            .await
            .unwrap(),
        400,
    )
    .await;
    assert_eq!(p["type"], "urn:kinserve:problem:malformed-request");
    problem(
        raw("/v1/robots/planar_2dof/fk/batch", "[[[0, 0]]]")
            .await
            .unwrap(),
        400,
    )
    .await;
    problem(
        raw(
            "/v1/robots",
            r#"["arr", null, null, "standard", "rad", "m", null, null, [{"joint": "revolute", "a": 1, "alpha": 0, "d": 0, "theta": 0}]]"#,
        )
        .await
        .unwrap(),
        400,
    )
    .await;
    assert_eq!(app.get("/v1/robots/arr").await.status(), 404);
}

/// Errors are problem+json everywhere, 405 included (with its `Allow` header).
#[tokio::test]
async fn an_unsupported_method_is_405_problem_with_allow() {
    let app = spawn_app().await;
    for (method, path, allow) in [
        ("GET", "/v1/robots/planar_2dof/fk", "POST"),
        ("DELETE", "/v1/robots/planar_2dof/fk/batch", "POST"),
        ("POST", "/readyz", "GET"),
        ("PATCH", "/v1/robots/planar_2dof", "PUT"),
        ("DELETE", "/v1/robots", "POST"),
        ("POST", "/openapi.json", "GET"),
    ] {
        let r = app
            .client
            .request(
                reqwest::Method::from_bytes(method.as_bytes()).unwrap(),
                format!("{}{path}", app.http),
            )
            .send()
            .await
            .unwrap();
        let allowed = r
            .headers()
            .get("allow")
            .map(|v| v.to_str().unwrap().to_owned())
            .unwrap_or_default();
        assert!(
            allowed.contains(allow),
            "{method} {path}: allow {allowed:?}"
        );
        let p = problem(r, 405).await;
        assert_eq!(p["type"], "urn:kinserve:problem:method-not-allowed");
    }
}

#[tokio::test]
async fn a_body_that_is_not_json_is_415() {
    let app = spawn_app().await;
    for path in [
        "/v1/robots",
        "/v1/robots/planar_2dof/fk",
        "/v1/robots/planar_2dof/fk/batch",
    ] {
        let r = app
            .client
            .post(format!("{}{path}", app.http))
            .header("content-type", "text/plain")
            .body(r#"{"joints": [0, 0]}"#)
            .send()
            .await
            .unwrap();
        let p = problem(r, 415).await;
        assert_eq!(p["type"], "urn:kinserve:problem:unsupported-media-type");
        // No content type at all.
        let r = app
            .client
            .post(format!("{}{path}", app.http))
            .body(r#"{"joints": [0, 0]}"#)
            .send()
            .await
            .unwrap();
        problem(r, 415).await;
    }
    let r = app
        .client
        .put(format!("{}/v1/robots/x", app.http))
        .header("content-type", "application/xml")
        .body("<robot/>")
        .send()
        .await
        .unwrap();
    problem(r, 415).await;
    // `application/json; charset=utf-8` is JSON.
    let r = app
        .client
        .post(format!("{}/v1/robots/planar_2dof/fk", app.http))
        .header("content-type", "application/json; charset=utf-8")
        .body(r#"{"joints": [0, 0]}"#)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
}

#[tokio::test]
async fn a_body_over_the_limit_is_413() {
    let app = spawn_app_with(|c| {
        c.max_body_bytes = 2048;
        c.max_batch_body_bytes = 4096;
    })
    .await;
    let mut model = planar_model("big");
    model["description"] = json!("x".repeat(3000));
    let p = problem(app.post("/v1/robots", &model).await, 413).await;
    assert_eq!(p["type"], "urn:kinserve:problem:too-large");
    let joints: Vec<f64> = vec![0.0; 1000];
    problem(
        app.post("/v1/robots/planar_2dof/fk", &json!({"joints": joints}))
            .await,
        413,
    )
    .await;
    // The batch route has its own (larger) body limit.
    let configs = vec![[0.0, 0.0]; 300]; // ~3 KB: over the body limit, under the batch body limit
    let r = app
        .post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": configs}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let configs = vec![[0.0, 0.0]; 600];
    problem(
        app.post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": configs}),
        )
        .await,
        413,
    )
    .await;
}

// ---------------------------------------------------------------- security

#[tokio::test]
async fn the_token_guards_mutations_and_fk_stays_open() {
    let app = spawn_app_with(|c| c.api_token = Some("s3cret".into())).await;
    let url = format!("{}/v1/robots", app.http);
    // Missing token.
    let r = app.post("/v1/robots", &planar_model("guarded")).await;
    assert_eq!(r.headers()["www-authenticate"], "Bearer");
    let p = problem(r, 401).await;
    assert_eq!(p["type"], "urn:kinserve:problem:unauthenticated");
    // Wrong token, wrong scheme.
    for auth in ["Bearer wrong", "Bearer s3cret-", "Basic s3cret", "s3cret"] {
        let r = app
            .client
            .post(&url)
            .header("authorization", auth)
            .json(&planar_model("guarded"))
            .send()
            .await
            .unwrap();
        problem(r, 401).await;
    }
    let put = |auth: Option<&str>| {
        let mut b = app
            .client
            .put(format!("{url}/guarded"))
            .json(&planar_model("guarded"));
        if let Some(a) = auth {
            b = b.header("authorization", a);
        }
        b.send()
    };
    let del = |auth: Option<&str>| {
        let mut b = app.client.delete(format!("{url}/guarded"));
        if let Some(a) = auth {
            b = b.header("authorization", a);
        }
        b.send()
    };
    problem(put(None).await.unwrap(), 401).await;
    problem(del(None).await.unwrap(), 401).await;
    // Nothing was created by the rejected calls.
    assert_eq!(app.get("/v1/robots/guarded").await.status(), 404);

    // The right token.
    let r = app
        .client
        .post(&url)
        .bearer_auth("s3cret")
        .json(&planar_model("guarded"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    assert_eq!(put(Some("Bearer s3cret")).await.unwrap().status(), 200);
    problem(del(Some("Bearer nope")).await.unwrap(), 401).await;

    // Reads and FK need no token.
    assert_eq!(app.get("/v1/robots").await.status(), 200);
    assert_eq!(app.get("/v1/robots/guarded").await.status(), 200);
    fk_ok(&app, "guarded", json!({"joints": [0, 0]})).await;
    let r = app
        .post(
            "/v1/robots/guarded/fk/batch",
            &json!({"configurations": [[0, 0]]}),
        )
        .await;
    assert_eq!(r.status(), 200);

    assert_eq!(del(Some("Bearer s3cret")).await.unwrap().status(), 204);
}

// ---------------------------------------------------------------- forward kinematics

#[tokio::test]
async fn planar_2dof_matches_its_closed_form() {
    let app = spawn_app().await;
    let (a1, a2) = (0.4, 0.3);
    for (t1, t2) in [(0.0, 0.0), (30.0, 45.0), (-120.0, 75.0), (179.0, -179.0)] {
        let out = fk_ok(
            &app,
            "planar_2dof",
            json!({"joints": [t1, t2], "angle_unit": "deg"}),
        )
        .await;
        assert_eq!(out["robot"], "planar_2dof");
        assert_eq!(out["length_unit"], "m");
        assert!(out.get("frames").is_none(), "no frames unless asked");
        let (r1, r12) = (f64::to_radians(t1), f64::to_radians(t1 + t2));
        let (c1, s1, c12, s12) = (r1.cos(), r1.sin(), r12.cos(), r12.sin());
        assert_matrix(
            &out["pose"],
            [
                [c12, -s12, 0.0, a1 * c1 + a2 * c12],
                [s12, c12, 0.0, a1 * s1 + a2 * s12],
                [0.0, 0.0, 1.0, 0.0],
            ],
            "planar",
        );
        assert_close(
            out["pose"]["rpy"][2].as_f64().unwrap(),
            wrap(r12),
            CLOSED_FORM_TOL,
            "yaw",
        );
        // The same configuration in rad (the default unit) gives the same pose.
        let rad = fk_ok(
            &app,
            "planar_2dof",
            json!({"joints": [r1, t2.to_radians()]}),
        )
        .await;
        assert_pose_eq(&rad["pose"], &out["pose"], SAME_LIB_TOL, "deg vs rad");
    }
}

/// An angle wrapped into (-π, π].
fn wrap(a: f64) -> f64 {
    let t = a.sin().atan2(a.cos());
    if t <= -std::f64::consts::PI {
        t + 2.0 * std::f64::consts::PI
    } else {
        t
    }
}

#[tokio::test]
async fn scara_4dof_matches_its_closed_form() {
    let app = spawn_app().await;
    let (a1, a2, d1, d4) = (0.35, 0.25, 0.4, 0.05);
    for (t1, t2, d3, t4) in [
        (0.0, 0.0, 0.0, 0.0),
        (30.0, -60.0, 0.1, 45.0),
        (-150.0, 120.0, 0.2, -90.0),
    ] {
        let out = fk_ok(
            &app,
            "scara_4dof",
            json!({"joints": [t1, t2, d3, t4], "angle_unit": "deg"}),
        )
        .await;
        let (r1, r12) = (f64::to_radians(t1), f64::to_radians(t1 + t2));
        let p = position(&out["pose"]);
        assert_close(p[0], a1 * r1.cos() + a2 * r12.cos(), CLOSED_FORM_TOL, "x");
        assert_close(p[1], a1 * r1.sin() + a2 * r12.sin(), CLOSED_FORM_TOL, "y");
        assert_close(p[2], d1 - d3 - d4, CLOSED_FORM_TOL, "z = d1 - d3 - d4");
        // Approach vector (third column) points down.
        let m = matrix16(&out["pose"]);
        for (i, want) in [0.0, 0.0, -1.0].into_iter().enumerate() {
            assert_close(m[i * 4 + 2], want, CLOSED_FORM_TOL, "approach");
        }
        // Normal vector: x4 = (cos φ, sin φ, 0) with φ = θ1 + θ2 − θ4.
        let phi = f64::to_radians(t1 + t2 - t4);
        assert_close(m[0], phi.cos(), CLOSED_FORM_TOL, "n.x");
        assert_close(m[4], phi.sin(), CLOSED_FORM_TOL, "n.y");
    }
}

#[tokio::test]
async fn cylindrical_3dof_matches_its_closed_form() {
    let app = spawn_app().await;
    let d1 = 0.5;
    for (t1, d2, d3) in [(0.0, 0.0, 0.2), (40.0, 0.3, 0.5), (-135.0, 0.6, 0.7)] {
        let out = fk_ok(
            &app,
            "cylindrical_3dof",
            json!({"joints": [t1, d2, d3], "angle_unit": "deg"}),
        )
        .await;
        let (s1, c1) = f64::to_radians(t1).sin_cos();
        assert_matrix(
            &out["pose"],
            [
                [c1, 0.0, -s1, -d3 * s1],
                [s1, 0.0, c1, d3 * c1],
                [0.0, -1.0, 0.0, d1 + d2],
            ],
            "cylindrical",
        );
    }
}

#[tokio::test]
async fn alpha_ii_in_mm_matches_its_closed_form() {
    let app = spawn_app().await;
    for q in [
        [0.0, 0.0, 0.0, 0.0, 0.0],
        [30.0, -45.0, 60.0, 20.0, 10.0],
        [-100.0, 80.0, -30.0, -70.0, 170.0],
    ] {
        let out = fk_ok(&app, "alpha_ii", json!({"joints": q, "angle_unit": "deg"})).await;
        assert_eq!(out["length_unit"], "mm");
        let r = q.map(f64::to_radians);
        let (c1, s1) = (r[0].cos(), r[0].sin());
        let (c2, s2) = (r[1].cos(), r[1].sin());
        let (c23, s23) = ((r[1] + r[2]).cos(), (r[1] + r[2]).sin());
        let (c234, s234) = ((r[1] + r[2] + r[3]).cos(), (r[1] + r[2] + r[3]).sin());
        let reach = 177.8 * c2 + 177.8 * c23 - 129.5 * s234;
        let p = position(&out["pose"]);
        assert_close(p[0], c1 * reach, CLOSED_FORM_TOL, "x");
        assert_close(p[1], s1 * reach, CLOSED_FORM_TOL, "y");
        assert_close(
            p[2],
            215.0 - 177.8 * s2 - 177.8 * s23 - 129.5 * c234,
            CLOSED_FORM_TOL,
            "z",
        );
        let m = matrix16(&out["pose"]);
        for (i, want) in [-c1 * s234, -s1 * s234, -c234].into_iter().enumerate() {
            assert_close(m[i * 4 + 2], want, CLOSED_FORM_TOL, "approach");
        }
    }
}

#[tokio::test]
async fn fk_returns_every_frame_when_asked() {
    let app = spawn_app().await;
    let out = fk_ok(
        &app,
        "planar_2dof",
        json!({"joints": [30, 45], "angle_unit": "deg", "frames": true}),
    )
    .await;
    let frames = out["frames"].as_array().expect("frames");
    assert_eq!(frames.len(), 3, "base frame plus one per DH row");
    let p0 = position(&frames[0]);
    assert_eq!(p0, [0.0, 0.0, 0.0], "base frame");
    let p1 = position(&frames[1]);
    let r1 = 30f64.to_radians();
    assert_close(p1[0], 0.4 * r1.cos(), CLOSED_FORM_TOL, "frame 1 x");
    assert_close(p1[1], 0.4 * r1.sin(), CLOSED_FORM_TOL, "frame 1 y");
    // No tool: the last frame (flange) is the pose.
    assert_pose_eq(&frames[2], &out["pose"], SAME_LIB_TOL, "flange");
    // frames: false gives the same pose and no frames.
    let plain = fk_ok(
        &app,
        "planar_2dof",
        json!({"joints": [30, 45], "angle_unit": "deg", "frames": false}),
    )
    .await;
    assert!(plain.get("frames").is_none());
    assert_pose_eq(
        &plain["pose"],
        &out["pose"],
        SAME_LIB_TOL,
        "frames vs plain",
    );
}

#[tokio::test]
async fn fk_checks_joint_count_and_limits() {
    let app = spawn_app().await;
    // Quill stroke d3 ∈ [0, 0.2] m.
    let p = problem(
        app.post(
            "/v1/robots/scara_4dof/fk",
            &json!({"joints": [0, 0, 0.3, 0]}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["joints[2]"]);
    assert!(
        p["errors"][0]["message"]
            .as_str()
            .unwrap()
            .contains("quill"),
        "{p}"
    );
    // check_limits: false computes it anyway: z = d1 - d3 - d4.
    let out = fk_ok(
        &app,
        "scara_4dof",
        json!({"joints": [0, 0, 0.3, 0], "check_limits": false}),
    )
    .await;
    assert_close(
        position(&out["pose"])[2],
        0.4 - 0.3 - 0.05,
        CLOSED_FORM_TOL,
        "z",
    );
    // Limits in degrees are checked in the request's unit: puma560 waist ±160°.
    let p = problem(
        app.post(
            "/v1/robots/puma560/fk",
            &json!({"joints": [161, 0, 0, 0, 0, 0], "angle_unit": "deg"}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["joints[0]"]);
    fk_ok(
        &app,
        "puma560",
        json!({"joints": [159, 0, 0, 0, 0, 0], "angle_unit": "deg"}),
    )
    .await;
    // Wrong joint count.
    for joints in [json!([0]), json!([0, 0, 0]), json!([])] {
        let p = problem(
            app.post("/v1/robots/planar_2dof/fk", &json!({"joints": joints}))
                .await,
            422,
        )
        .await;
        assert_eq!(fields(&p), ["joints"], "{p}");
    }
}

/// Deterministic pseudo-random joint values in [-1.5, 1.5] rad (inside every puma560 limit).
fn configs(n: usize, dof: usize) -> Vec<Vec<f64>> {
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    (0..n)
        .map(|_| {
            (0..dof)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    (x % 30_001) as f64 / 10_000.0 - 1.5
                })
                .collect()
        })
        .collect()
}

#[tokio::test]
async fn batch_equals_single_in_request_order() {
    let app = spawn_app().await;
    for (robot, dof) in [("puma560", 6), ("scara_4dof", 4), ("alpha_ii", 5)] {
        let mut qs = configs(40, dof);
        if robot == "scara_4dof" {
            for q in &mut qs {
                q[2] = (q[2] + 1.5) / 15.0; // quill in [0, 0.2]
            }
        }
        let r = app
            .post(
                &format!("/v1/robots/{robot}/fk/batch"),
                &json!({"configurations": qs}),
            )
            .await;
        assert_eq!(r.status(), 200);
        assert_eq!(r.headers()["content-type"], "application/json");
        let batch: Value = r.json().await.unwrap();
        assert_eq!(batch["robot"], robot);
        let poses = batch["poses"].as_array().expect("poses");
        assert_eq!(poses.len(), qs.len());
        for (i, q) in qs.iter().enumerate() {
            let single = fk_ok(&app, robot, json!({"joints": q})).await;
            assert_eq!(batch["length_unit"], single["length_unit"]);
            assert_pose_eq(
                &poses[i],
                &single["pose"],
                SAME_LIB_TOL,
                &format!("{robot} #{i}"),
            );
        }
    }
    // Degrees too.
    let r = app
        .post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": [[30, 45], [0, 90]], "angle_unit": "deg"}),
        )
        .await;
    let batch: Value = r.json().await.unwrap();
    let single = fk_ok(
        &app,
        "planar_2dof",
        json!({"joints": [0, 90], "angle_unit": "deg"}),
    )
    .await;
    assert_pose_eq(
        &batch["poses"][1],
        &single["pose"],
        SAME_LIB_TOL,
        "deg batch",
    );
    // An empty batch is an empty answer.
    let r = app
        .post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": []}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let batch: Value = r.json().await.unwrap();
    assert_eq!(batch["poses"], json!([]));
}

#[tokio::test]
async fn one_bad_configuration_fails_the_batch_naming_it() {
    let app = spawn_app().await;
    let mut qs: Vec<Vec<f64>> = vec![vec![0.0, 0.0, 0.1, 0.0]; 30];
    qs[17][2] = 0.5; // quill over its 0.2 m limit
    let p = problem(
        app.post(
            "/v1/robots/scara_4dof/fk/batch",
            &json!({"configurations": qs}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["configurations[17][2]"]);
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("configurations[17][2]")
    );
    // With limits off the same batch is computed.
    let r = app
        .post(
            "/v1/robots/scara_4dof/fk/batch",
            &json!({"configurations": qs, "check_limits": false}),
        )
        .await;
    assert_eq!(r.status(), 200);
    // Wrong joint count in one configuration.
    let mut qs = vec![vec![0.0, 0.0]; 30];
    qs[17] = vec![0.0, 0.0, 0.0];
    let p = problem(
        app.post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": qs}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["configurations[17]"]);
}

#[tokio::test]
async fn the_batch_limit_defaults_to_10000_and_is_413_above() {
    let app = spawn_app().await;
    let at_limit = vec![[0.0, 0.0]; 10_000];
    let r = app
        .post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": at_limit}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["poses"].as_array().unwrap().len(), 10_000);
    let over = vec![[0.0, 0.0]; 10_001];
    let p = problem(
        app.post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": over}),
        )
        .await,
        413,
    )
    .await;
    assert_eq!(p["type"], "urn:kinserve:problem:too-large");
    assert_eq!(fields(&p), ["configurations"]);
    assert!(p["detail"].as_str().unwrap().contains("10000"), "{p}");

    // Configurable.
    let app = spawn_app_with(|c| c.max_batch = 3).await;
    let r = app
        .post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": [[0, 0], [0, 0], [0, 0]]}),
        )
        .await;
    assert_eq!(r.status(), 200);
    problem(
        app.post(
            "/v1/robots/planar_2dof/fk/batch",
            &json!({"configurations": [[0, 0], [0, 0], [0, 0], [0, 0]]}),
        )
        .await,
        413,
    )
    .await;
}

// ---------------------------------------------------------------- overload

/// With one permit, a request whose body is still arriving holds it: every other
/// admitted request gets 503 + Retry-After at once, health endpoints still answer,
/// and the permit comes back when the slow request completes.
#[tokio::test]
async fn overloaded_is_503_with_retry_after() {
    let app = spawn_app_with(|c| c.max_concurrent_requests = 1).await;
    let body = br#"{"joints": [0, 0]}"#;
    let slow = partial_request(&app, "/v1/robots/planar_2dof/fk", body, 3).await;
    // Poll until the server has admitted the slow request (it then holds the only permit).
    let mut rejected = None;
    for _ in 0..500 {
        let r = app.get("/v1/robots").await;
        if r.status() == 503 {
            rejected = Some(r);
            break;
        }
        assert_eq!(r.status(), 200);
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    let r = rejected.expect("a request beyond the limit is rejected");
    assert_eq!(r.headers()["retry-after"], "1");
    let p = problem(r, 503).await;
    assert_eq!(p["type"], "urn:kinserve:problem:overloaded");
    problem(
        app.post("/v1/robots/planar_2dof/fk", &json!({"joints": [0, 0]}))
            .await,
        503,
    )
    .await;
    // Health endpoints are not subject to admission control.
    assert_eq!(app.get("/healthz").await.status(), 200);
    assert_eq!(app.get("/readyz").await.status(), 200);

    let mut slow = slow;
    slow.write_all(&body[3..]).await.unwrap();
    let resp = read_response(slow).await;
    assert!(resp.starts_with("HTTP/1.1 200"), "{resp}");
    assert!(resp.contains("\"planar_2dof\""), "{resp}");
    assert_eq!(app.get("/v1/robots").await.status(), 200, "permit released");
}

/// A request still unfinished at the request timeout gets 503 + Retry-After.
#[tokio::test]
async fn a_request_over_the_timeout_is_503() {
    let app = spawn_app_with(|c| c.request_timeout = std::time::Duration::from_millis(200)).await;
    let slow = partial_request(
        &app,
        "/v1/robots/planar_2dof/fk",
        br#"{"joints": [0, 0]}"#,
        1,
    )
    .await;
    let resp = read_response(slow).await;
    assert!(resp.starts_with("HTTP/1.1 503"), "{resp}");
    let lower = resp.to_ascii_lowercase();
    assert!(lower.contains("retry-after: 1"), "{resp}");
    assert!(
        lower.contains("content-type: application/problem+json"),
        "{resp}"
    );
    assert!(resp.contains("timed out"), "{resp}");
}

// ---------------------------------------------------------------- persistence

#[tokio::test]
async fn registered_robots_survive_a_restart() {
    let tmp = tempfile::tempdir().unwrap();
    let app = spawn_in(tmp.path(), |_| {}).await;
    assert_eq!(
        app.post("/v1/robots", &planar_model("kept")).await.status(),
        201
    );
    assert_eq!(
        app.post("/v1/robots", &planar_model("replaced"))
            .await
            .status(),
        201
    );
    assert_eq!(
        app.post("/v1/robots", &planar_model("deleted"))
            .await
            .status(),
        201
    );
    let mut replacement = planar_model("replaced");
    replacement["links"][1]["a"] = json!(0.25);
    replacement["description"] = json!("second version");
    let r = app
        .client
        .put(format!("{}/v1/robots/replaced", app.http))
        .json(&replacement)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let r = app
        .client
        .delete(format!("{}/v1/robots/deleted", app.http))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204);
    // Written before the answer: the files are there already.
    let dir = tmp.path().join("robots");
    assert!(dir.join("kept.json").is_file());
    assert!(dir.join("replaced.json").is_file());
    assert!(!dir.join("deleted.json").exists());
    let on_disk: Value =
        serde_json::from_slice(&std::fs::read(dir.join("replaced.json")).unwrap()).unwrap();
    assert!(json_eq(&on_disk, &replacement), "{on_disk}");
    // Atomic writes leave no temporary files behind.
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["kept.json", "replaced.json"]);
    let before = fk_ok(&app, "replaced", json!({"joints": [0.3, -0.2]})).await;
    app.stop().await.unwrap();

    let app = spawn_in(tmp.path(), |_| {}).await;
    let got: Value = app.get("/v1/robots/kept").await.json().await.unwrap();
    assert!(json_eq(&got, &planar_model("kept")), "{got}");
    let got: Value = app.get("/v1/robots/replaced").await.json().await.unwrap();
    assert!(json_eq(&got, &replacement), "{got}");
    problem(app.get("/v1/robots/deleted").await, 404).await;
    let list: Value = app.get("/v1/robots").await.json().await.unwrap();
    let kept = list["robots"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["name"] == "kept")
        .unwrap();
    assert_eq!(kept["source"], "registered");
    let after = fk_ok(&app, "replaced", json!({"joints": [0.3, -0.2]})).await;
    assert_pose_eq(
        &after["pose"],
        &before["pose"],
        SAME_LIB_TOL,
        "same model after restart",
    );
    // Still registered, not built in: it can be deleted, and stays deleted.
    let r = app
        .client
        .delete(format!("{}/v1/robots/kept", app.http))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204);
    app.stop().await.unwrap();
    let app = spawn_in(tmp.path(), |_| {}).await;
    assert_eq!(app.get("/v1/robots/kept").await.status(), 404);
    assert_eq!(app.get("/v1/robots/replaced").await.status(), 200);
}

#[tokio::test]
async fn corrupt_or_unreadable_files_are_skipped_at_start_up_and_left_in_place() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("robots");
    std::fs::create_dir_all(&dir).unwrap();
    let good = serde_json::to_vec_pretty(&planar_model("good")).unwrap();
    std::fs::write(dir.join("good.json"), &good).unwrap();
    let corrupt = b"{\"name\": \"corrupt\", \"convention\": ".to_vec();
    std::fs::write(dir.join("corrupt.json"), &corrupt).unwrap();
    let mut bad = planar_model("invalid");
    bad["links"] = json!([]);
    let invalid = serde_json::to_vec(&bad).unwrap();
    std::fs::write(dir.join("invalid.json"), &invalid).unwrap();
    let mismatch = serde_json::to_vec(&planar_model("someone_else")).unwrap();
    std::fs::write(dir.join("mismatch.json"), &mismatch).unwrap();
    let clash = serde_json::to_vec(&planar_model("puma560")).unwrap();
    std::fs::write(dir.join("puma560.json"), &clash).unwrap();
    // Unreadable (a directory where a file should be; works even as root).
    std::fs::create_dir(dir.join("unreadable.json")).unwrap();

    let app = spawn_in(tmp.path(), |_| {}).await;
    assert_eq!(app.get("/readyz").await.status(), 200);
    assert_eq!(app.get("/v1/robots/good").await.status(), 200);
    for name in [
        "corrupt",
        "invalid",
        "mismatch",
        "someone_else",
        "unreadable",
    ] {
        problem(app.get(&format!("/v1/robots/{name}")).await, 404).await;
    }
    // The built-in wins over a stored file of the same name.
    let got: Value = app.get("/v1/robots/puma560").await.json().await.unwrap();
    assert!(json_eq(&got, &builtin_file("puma560")));
    let list: Value = app.get("/v1/robots").await.json().await.unwrap();
    let registered: Vec<&str> = list["robots"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["source"] == "registered")
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(registered, ["good"]);
    // The server works normally beside them.
    assert_eq!(
        app.post("/v1/robots", &planar_model("fresh"))
            .await
            .status(),
        201
    );
    app.stop().await.unwrap();

    // Left in place, untouched.
    assert_eq!(std::fs::read(dir.join("corrupt.json")).unwrap(), corrupt);
    assert_eq!(std::fs::read(dir.join("invalid.json")).unwrap(), invalid);
    assert_eq!(std::fs::read(dir.join("mismatch.json")).unwrap(), mismatch);
    assert_eq!(std::fs::read(dir.join("puma560.json")).unwrap(), clash);
    assert!(dir.join("unreadable.json").is_dir());
    assert_eq!(std::fs::read(dir.join("good.json")).unwrap(), good);
}

/// When the store cannot write, the API answers 507 and changes nothing.
#[tokio::test]
async fn a_failed_write_is_507_and_changes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let app = spawn_in(tmp.path(), |_| {}).await;
    assert_eq!(
        app.post("/v1/robots", &planar_model("before"))
            .await
            .status(),
        201
    );
    // Replace the robots directory by a plain file: every write fails (even as root).
    let dir = tmp.path().join("robots");
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::write(&dir, b"not a directory").unwrap();
    let p = problem(app.post("/v1/robots", &planar_model("after")).await, 507).await;
    assert_eq!(p["type"], "urn:kinserve:problem:storage");
    problem(app.get("/v1/robots/after").await, 404).await;
    let mut replacement = planar_model("before");
    replacement["links"][0]["a"] = json!(0.9);
    let r = app
        .client
        .put(format!("{}/v1/robots/before", app.http))
        .json(&replacement)
        .send()
        .await
        .unwrap();
    problem(r, 507).await;
    let got: Value = app.get("/v1/robots/before").await.json().await.unwrap();
    assert!(json_eq(&got, &planar_model("before")), "unchanged: {got}");
}
