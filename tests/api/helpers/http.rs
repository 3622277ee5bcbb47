//! REST/HTTP: problem+json checks, JSON comparison and request shortcuts.

use serde_json::Value;

use crate::helpers::*;

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

/// `POST /v1/robots/{robot}/fk`, expecting 200; the response body.
pub(crate) async fn fk_ok(app: &TestApp, robot: &str, body: Value) -> Value {
    let r = app.post(&format!("/v1/robots/{robot}/fk"), &body).await;
    let status = r.status();
    let text = r.text().await.unwrap();
    assert_eq!(status, 200, "fk {robot} {body}: {text}");
    serde_json::from_str(&text).unwrap()
}

pub(crate) fn addr_of(url: &str) -> String {
    url.trim_start_matches("http://").to_owned()
}
