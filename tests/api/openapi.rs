//! The OpenAPI document is valid OpenAPI 3.1 for a real validator
//! (`openapi-spec-validator`, installed by `.ci/run`), describes and gives an
//! example for every request and response, and its examples are true.

use serde_json::Value;

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

/// Whether two JSON documents are the same: the same keys, arrays of the
/// same length, equal strings and booleans, numbers within `tol`; the first
/// difference (as a path) when not.
fn same_document(got: &Value, want: &Value, tol: f64, at: &str) -> Result<(), String> {
    match (got, want) {
        (Value::Object(g), Value::Object(w)) => {
            let (mut gk, mut wk): (Vec<_>, Vec<_>) = (g.keys().collect(), w.keys().collect());
            gk.sort();
            wk.sort();
            if gk != wk {
                return Err(format!("{at}: keys {gk:?}, documented {wk:?}"));
            }
            w.iter()
                .try_for_each(|(k, v)| same_document(&g[k], v, tol, &format!("{at}.{k}")))
        }
        (Value::Array(g), Value::Array(w)) => {
            if g.len() != w.len() {
                return Err(format!("{at}: {} items, documented {}", g.len(), w.len()));
            }
            g.iter()
                .zip(w)
                .enumerate()
                .try_for_each(|(i, (a, b))| same_document(a, b, tol, &format!("{at}[{i}]")))
        }
        (Value::Number(a), Value::Number(b)) => {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            ((a - b).abs() <= tol)
                .then_some(())
                .ok_or_else(|| format!("{at}: {a}, documented {b}"))
        }
        (a, b) if a == b => Ok(()),
        (a, b) => Err(format!("{at}: {a}, documented {b}")),
    }
}

/// The FK request examples get exactly the documented answers, whole (every
/// field, every pose of the batch), and the documented batch answer has one
/// pose per configuration of the documented batch request.
#[tokio::test]
async fn the_fk_examples_are_what_the_server_answers() {
    let app = spawn_app().await;
    let doc = document(&app).await;
    let schemas = &doc["components"]["schemas"];
    let batch_request = &schemas["FkBatchRequest"]["example"];
    let batch_answer = &schemas["FkBatchResponse"]["example"];
    let configurations = batch_request["configurations"].as_array().unwrap().len();
    assert_eq!(
        batch_answer["poses"].as_array().map(Vec::len),
        Some(configurations),
        "the documented batch answer has one pose per configuration of its request"
    );
    for (path, request, answer) in [
        ("fk", "FkRequest", "FkOutput"),
        ("fk/batch", "FkBatchRequest", "FkBatchResponse"),
    ] {
        let r = app
            .post(
                &format!("/v1/robots/planar_2dof/{path}"),
                &schemas[request]["example"],
            )
            .await;
        assert_eq!(r.status(), 200, "{request} example");
        let got: Value = r.json().await.unwrap();
        let expected = &schemas[answer]["example"];
        assert!(expected.is_object(), "{answer} has an example");
        if let Err(e) = same_document(&got, expected, 1e-12, answer) {
            panic!("{answer} example: {e}\nthe server answers {got}");
        }
    }
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
