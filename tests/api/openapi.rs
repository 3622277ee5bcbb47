//! The OpenAPI document is valid OpenAPI 3.1 for a real validator
//! (`openapi-spec-validator`, installed by `.ci/run`), describes and gives an
//! example for every request and response, and its examples are true.

use serde_json::Value;

use crate::helpers::pose::assert_pose_eq;
use crate::helpers::*;

async fn document(app: &TestApp) -> Value {
    app.get("/openapi.json").await.json().await.unwrap()
}

/// Runs `python3 -m openapi_spec_validator` on `doc`. `None` when the validator
/// is not installed outside CI (the test then says SKIPPED); under CI a
/// missing validator fails the test (`kinserve_testkit::skip_unless_ci`).
fn run_validator(doc: &Value) -> Option<std::process::Output> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("openapi.json");
    std::fs::write(&path, serde_json::to_vec_pretty(doc).unwrap()).unwrap();
    let have = std::process::Command::new("python3")
        .args(["-c", "import openapi_spec_validator"])
        .status()
        .is_ok_and(|s| s.success());
    if !have {
        kinserve_testkit::skip_unless_ci(
            "OpenAPI validator test",
            "openapi-spec-validator is not installed",
            "pip install openapi-spec-validator; .ci/run installs it",
        );
        return None;
    }
    let out = std::process::Command::new("python3")
        .args(["-m", "openapi_spec_validator"])
        .arg(&path)
        .output()
        .unwrap();
    Some(out)
}

#[tokio::test]
async fn the_document_passes_a_real_openapi_3_1_validator() {
    let app = spawn_app().await;
    let doc = document(&app).await;
    assert_eq!(doc["openapi"], "3.1.0");
    if let Some(out) = run_validator(&doc) {
        assert!(
            out.status.success(),
            "openapi-spec-validator:\n{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

/// Whether a media type object carries an example, itself or through its schema.
fn has_example(doc: &Value, media: &Value) -> bool {
    if media.get("example").is_some() || media.get("examples").is_some() {
        return true;
    }
    let schema = &media["schema"];
    if schema.get("example").is_some() || schema.get("examples").is_some() {
        return true;
    }
    let Some(r) = schema["$ref"].as_str() else {
        return false;
    };
    let name = r.trim_start_matches("#/components/schemas/");
    let target = &doc["components"]["schemas"][name];
    target.get("example").is_some() || target.get("examples").is_some()
}

#[tokio::test]
async fn every_route_has_tags_descriptions_and_examples() {
    let app = spawn_app().await;
    let doc = document(&app).await;
    assert!(
        doc["servers"].as_array().is_some_and(|s| !s.is_empty()),
        "servers"
    );
    let tags: Vec<&str> = doc["tags"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["name"].as_str().unwrap())
        .collect();
    let mut missing = Vec::new();
    for (path, item) in doc["paths"].as_object().unwrap() {
        for (method, op) in item.as_object().unwrap() {
            let at = format!("{method} {path}");
            let op_tags = op["tags"].as_array().cloned().unwrap_or_default();
            if op_tags.is_empty() || op_tags.iter().any(|t| !tags.contains(&t.as_str().unwrap())) {
                missing.push(format!("{at}: tags {op_tags:?} not among {tags:?}"));
            }
            for media in op["requestBody"]["content"]
                .as_object()
                .into_iter()
                .flat_map(|m| m.values())
            {
                if !has_example(&doc, media) {
                    missing.push(format!("{at}: request body has no example"));
                }
            }
            for (code, resp) in op["responses"].as_object().unwrap() {
                if resp["description"].as_str().is_none_or(str::is_empty) {
                    missing.push(format!("{at} {code}: no description"));
                }
                for (ct, media) in resp["content"].as_object().into_iter().flatten() {
                    if !has_example(&doc, media) {
                        missing.push(format!("{at} {code} {ct}: no example"));
                    }
                }
            }
        }
    }
    assert!(missing.is_empty(), "{}", missing.join("\n"));
}

#[tokio::test]
async fn the_fk_examples_are_what_the_server_answers() {
    let app = spawn_app().await;
    let doc = document(&app).await;
    let schemas = &doc["components"]["schemas"];
    let request = &schemas["FkRequest"]["example"];
    let expected = &schemas["FkOutput"]["example"];
    let got: Value = app
        .post("/v1/robots/planar_2dof/fk", request)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(got["robot"], expected["robot"]);
    assert_pose_eq(&got["pose"], &expected["pose"], 1e-12, "FkOutput example");
    let batch = &schemas["FkBatchRequest"]["example"];
    let expected = &schemas["FkBatchResponse"]["example"];
    let got: Value = app
        .post("/v1/robots/planar_2dof/fk/batch", batch)
        .await
        .json()
        .await
        .unwrap();
    assert_pose_eq(
        &got["poses"][0],
        &expected["poses"][0],
        1e-12,
        "FkBatchResponse example",
    );
}

/// Whether two JSON arrays of numbers (possibly nested) are equal to `tol`.
fn numbers_close(a: &Value, b: &Value, tol: f64) -> bool {
    match (a, b) {
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(a, b)| numbers_close(a, b, tol))
        }
        (Value::Number(x), Value::Number(y)) => match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => (x - y).abs() <= tol,
            _ => false,
        },
        _ => false,
    }
}

/// The compact pose schemas' examples are the server's answers to the FK
/// request examples in that format, in the format's own field.
#[tokio::test]
async fn the_compact_pose_examples_are_what_the_server_answers() {
    let app = spawn_app().await;
    let doc = document(&app).await;
    let schemas = &doc["components"]["schemas"];
    let cases = [
        ("fk", "FkRequest", "matrix", "matrix", "PoseMatrix"),
        ("fk", "FkRequest", "position", "position", "PosePosition"),
        (
            "fk/batch",
            "FkBatchRequest",
            "matrix",
            "matrices",
            "PoseMatrices",
        ),
        (
            "fk/batch",
            "FkBatchRequest",
            "position",
            "positions",
            "PosePositions",
        ),
    ];
    for (path, request, format, field, schema) in cases {
        let mut body = schemas[request]["example"].clone();
        body["pose_format"] = format.into();
        let r = app
            .post(&format!("/v1/robots/planar_2dof/{path}"), &body)
            .await;
        assert_eq!(r.status(), 200, "{schema}");
        let got: Value = r.json().await.unwrap();
        let example = &schemas[schema]["example"];
        assert!(example.is_array(), "{schema} has an example");
        assert!(
            numbers_close(&got[field], example, 1e-12),
            "{schema} example: the server answers {}",
            got[field]
        );
    }
}

#[tokio::test]
async fn swagger_ui_never_calls_the_public_validator() {
    let app = spawn_app().await;
    let js = app
        .get("/docs/swagger-initializer.js")
        .await
        .text()
        .await
        .unwrap();
    assert!(js.contains("\"validatorUrl\": \"none\""), "{js}");
}
