//! REST request validation: malformed JSON and wrong types, unsupported
//! methods and media types, and bodies over the size limit.

use serde_json::json;

use crate::helpers::*;

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
    // XML is a URDF on the registry routes (tests/api/urdf_import.rs), not a computation's body.
    let r = app
        .client
        .post(format!("{}/v1/robots/planar_2dof/fk", app.http))
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

/// Every batch route (FK, Jacobian, IK) reads a body within the batch body
/// limit, and its single sibling refuses the same body (413): the larger
/// limit goes with the routes declared as batches, each of them.
#[tokio::test]
async fn every_batch_route_and_only_they_take_the_batch_body_limit() {
    let app = spawn_app_with(|c| {
        c.max_body_bytes = 2048;
        c.max_batch_body_bytes = 4096;
    })
    .await;
    // ~3 KB: over the body limit, under the batch body limit.
    let body = json!({"configurations": vec![[0.0, 0.0]; 300]});
    for op in ["fk", "jacobian", "ik"] {
        let batch = app
            .post(&format!("/v1/robots/planar_2dof/{op}/batch"), &body)
            .await;
        // The IK batch reads it and finds no targets (400/422); the others compute it.
        assert_ne!(
            batch.status(),
            413,
            "{op}/batch: {}",
            batch.text().await.unwrap()
        );
        assert!(
            batch.status().as_u16() < 500,
            "{op}/batch: {}",
            batch.status()
        );
        let single = app
            .post(&format!("/v1/robots/planar_2dof/{op}"), &body)
            .await;
        let p = problem(single, 413).await;
        assert_eq!(p["type"], "urn:kinserve:problem:too-large", "{op}");
    }
}
