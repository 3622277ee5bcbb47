//! REST batch FK: request order, a bad configuration failing the batch, the
//! batch size limit, and large answers written as the client reads them.

use serde_json::{Value, json};

use crate::helpers::pose::assert_pose_eq;
use crate::helpers::*;

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

/// A large answer (3,000 full poses, about 1.8 MB) goes out chunked, without
/// `Content-Length`, over HTTP/1.1 and HTTP/2, and is exactly the answers
/// of its parts (small answers, sent whole with `Content-Length`) joined:
/// streaming changes how the bytes are sent, not which.
#[tokio::test]
async fn a_large_answer_is_streamed_and_equals_its_parts_joined() {
    let app = spawn_app().await;
    let qs = configs(3_000, 6);
    let path = "/v1/robots/puma560/fk/batch";
    let mut parts = Vec::new();
    for chunk in qs.chunks(50) {
        let r = app.post(path, &json!({"configurations": chunk})).await;
        assert_eq!(r.status(), 200);
        assert!(
            r.headers().contains_key("content-length"),
            "small answer sent whole"
        );
        let part: Value = r.json().await.unwrap();
        parts.extend(part["poses"].as_array().unwrap().iter().cloned());
    }
    let h2 = reqwest::Client::builder()
        .http2_prior_knowledge()
        .build()
        .unwrap();
    for (client, version) in [(&app.client, "HTTP/1.1"), (&h2, "HTTP/2")] {
        let r = client
            .post(format!("{}{path}", app.http))
            .json(&json!({"configurations": qs}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200, "{version}");
        assert_eq!(r.headers()["content-type"], "application/json");
        assert!(
            !r.headers().contains_key("content-length"),
            "{version}: a large answer is streamed"
        );
        let whole: Value = r.json().await.unwrap();
        assert_eq!(whole["robot"], "puma560");
        assert_eq!(whole["length_unit"], "m");
        // Exact equality of every number (serde_json parses with float_roundtrip).
        assert!(
            whole["poses"].as_array().unwrap() == &parts,
            "{version}: streamed poses differ from the parts' poses"
        );
    }
}
