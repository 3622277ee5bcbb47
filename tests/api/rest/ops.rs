//! REST operations: health and readiness, request ids, CORS, the OpenAPI
//! document and docs page, and metrics.

use kinserve::App;
use kinserve::config::ServeConfig;
use serde_json::{Value, json};

use crate::helpers::*;

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
async fn cors_allows_any_origin_to_read_and_compute_by_default() {
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
    // Secure by default: reads and FK from any origin, no cross-origin
    // registry writes unless --cors-origin names the origin (secure_defaults.rs).
    assert!(
        methods.contains("GET") && methods.contains("POST"),
        "{methods}"
    );
    assert!(
        !methods.contains("PUT") && !methods.contains("DELETE"),
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
    ("/v1/robots/{name}/jacobian", &["post"]),
    ("/v1/robots/{name}/jacobian/batch", &["post"]),
    ("/v1/robots/{name}/ik", &["post"]),
    ("/v1/robots/{name}/ik/batch", &["post"]),
    ("/v1/robots/{name}/ik/path", &["post"]),
    ("/v1/robots/{name}/closed-form", &["get"]),
    ("/v1/robots/{name}/link-transforms", &["post"]),
    ("/v1/robots/{name}/urdf", &["get"]),
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
        "JacobianRequest",
        "JacobianBatchRequest",
        "JacobianOutput",
        "JacobianBatchOutput",
        "IkSpec",
        "IkBatchSpec",
        "IkTargetSpec",
        "IkOutput",
        "IkBatchOutput",
        "ClosedForm",
        "SymbolicMatrix",
        "JointVariable",
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
    assert_eq!(app.get("/no/such/route/x").await.status(), 404);

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
    // A path no route matches has the one fixed label, never its own path.
    assert!(
        metric_value(
            &text,
            requests,
            &[r#"route="unmatched""#, r#"status="404""#]
        )
        .is_some_and(|v| v >= 1.0),
        "{text}"
    );
    assert!(!text.contains("/no/such/route"), "{text}");
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
