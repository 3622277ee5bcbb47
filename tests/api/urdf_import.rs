//! Robots from URDF on every front door: `POST /v1/robots` and `PUT
//! /v1/robots/{name}` with an XML body (and the JSON import media type), gRPC
//! `ImportUrdf` and `kinserve import-urdf` give the same model; an arm brought
//! back from the server's own URDF export works downstream like the built-in
//! it came from (FK, frames, Jacobian, IK, closed form, export, both
//! conventions); the refusals name their field on every front door; the
//! token and origin rules hold; the README's worked example answers as shown.
//!
//! The conversion itself (exactness, real makers' files against Pinocchio) is
//! tested in `crates/kinserve-model/tests/model/urdf_import.rs`.

use std::process::{Command, Output};

use kinserve::api::grpc::pb;
use serde_json::{Value, json};
use tonic::Code;

use crate::helpers::pose::assert_pose_eq;
use crate::helpers::*;

/// The server's API token: imports are registry writes.
const TOKEN: &str = "urdf-import-token";
/// The JSON import media type.
const IMPORT_JSON: &str = "application/vnd.kinserve.urdf-import+json";
/// Agreement required with the built-in the URDF came from (relative, per entry).
const TOL: f64 = 1e-12;

async fn guarded_app() -> TestApp {
    spawn_app_with(|c| c.api_token = Some(TOKEN.into())).await
}

/// `GET /v1/robots/{robot}/urdf`.
async fn exported(app: &TestApp, robot: &str) -> String {
    let r = app.get(&format!("/v1/robots/{robot}/urdf")).await;
    assert_eq!(r.status(), 200);
    r.text().await.unwrap()
}

/// `METHOD {path}` with `body` as `content_type`, with the token.
async fn send(
    app: &TestApp,
    method: reqwest::Method,
    path: &str,
    content_type: &str,
    body: String,
) -> reqwest::Response {
    app.client
        .request(method, format!("{}{path}", app.http))
        .header("content-type", content_type)
        .bearer_auth(TOKEN)
        .body(body)
        .send()
        .await
        .unwrap()
}

/// `POST /v1/robots{query}` with a URDF body.
async fn post_xml(app: &TestApp, query: &str, urdf: &str) -> reqwest::Response {
    let path = format!("/v1/robots{query}");
    send(
        app,
        reqwest::Method::POST,
        &path,
        "application/xml",
        urdf.into(),
    )
    .await
}

/// `POST /v1/robots` with a JSON import body.
async fn post_import_json(app: &TestApp, body: &Value) -> reqwest::Response {
    let body = body.to_string();
    send(app, reqwest::Method::POST, "/v1/robots", IMPORT_JSON, body).await
}

fn import_pb(name: &str, urdf: &str) -> pb::ImportUrdfRequest {
    pb::ImportUrdfRequest {
        name: name.into(),
        urdf: urdf.into(),
        ..Default::default()
    }
}

fn bearer() -> String {
    format!("Bearer {TOKEN}")
}

/// `kinserve ARGS`.
fn cli(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kinserve"))
        .args(args)
        .output()
        .unwrap()
}

/// A robot model as JSON without its name (to compare models registered under two names).
fn unnamed(mut spec: Value) -> Value {
    spec.as_object_mut().unwrap().remove("name");
    spec
}

/// FK of `configs` on `robot` (radians, limits checked), the poses.
async fn poses(app: &TestApp, robot: &str, configs: &[Vec<f64>]) -> Vec<Value> {
    let r = app
        .post(
            &format!("/v1/robots/{robot}/fk/batch"),
            &json!({"configurations": configs}),
        )
        .await;
    assert_eq!(r.status(), 200, "{robot}");
    let body: Value = r.json().await.unwrap();
    body["poses"].as_array().unwrap().clone()
}

/// Asserts `robot` has the poses of `original` at 25 configurations.
async fn assert_same_fk(app: &TestApp, robot: &str, original: &str, dof: usize) {
    let configs = configs(25, dof);
    let (got, want) = (
        poses(app, robot, &configs).await,
        poses(app, original, &configs).await,
    );
    assert_eq!(got.len(), configs.len());
    for (i, (a, b)) in got.iter().zip(&want).enumerate() {
        assert_pose_eq(
            a,
            b,
            TOL,
            &format!("{robot} vs {original}, configuration {i}"),
        );
    }
}

#[tokio::test]
async fn an_exported_arm_imported_over_rest_grpc_and_the_cli_is_the_same_model() {
    let app = guarded_app().await;
    let urdf = exported(&app, "ur5e").await;
    // REST, XML body.
    let r = post_xml(&app, "?name=imported-arm", &urdf).await;
    assert_eq!(r.status(), 201);
    assert_eq!(r.headers()["location"], "/v1/robots/imported-arm");
    assert!(r.headers().contains_key("etag"));
    let rest: Value = r.json().await.unwrap();
    assert_eq!(rest["name"], "imported-arm");
    assert_eq!(rest["links"].as_array().unwrap().len(), 6, "{rest}");
    assert_eq!(
        (rest["angle_unit"].as_str(), rest["length_unit"].as_str()),
        (Some("rad"), Some("m"))
    );
    let names: Vec<&str> = rest["links"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "shoulder_pan",
            "shoulder_lift",
            "elbow",
            "wrist_1",
            "wrist_2",
            "wrist_3"
        ],
        "joint names carried over"
    );
    let limits = &rest["links"][0]["limits"];
    assert_close(
        limits[1].as_f64().unwrap(),
        std::f64::consts::TAU,
        1e-15,
        "limits in rad",
    );
    // The stored model is the answer.
    let stored: Value = app
        .get("/v1/robots/imported-arm")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(stored, rest);
    // gRPC, replacing it: the same model.
    let mut c = app.grpc_client().await;
    let mut msg = import_pb("imported-arm", &urdf);
    msg.replace = true;
    let got = c
        .import_urdf(with_token(msg, &bearer()))
        .await
        .unwrap()
        .into_inner();
    assert!(!got.created);
    assert!(!got.etag.is_empty());
    let grpc = kinserve_api::robot_from_pb(got.robot.unwrap()).unwrap();
    let grpc = serde_json::to_value(grpc).unwrap();
    assert!(json_eq(&grpc, &rest), "gRPC {grpc}\nREST {rest}");
    // The JSON import media type.
    let r = post_import_json(&app, &json!({"name": "imported-json", "urdf": urdf})).await;
    assert_eq!(r.status(), 201);
    let body: Value = r.json().await.unwrap();
    assert_eq!(unnamed(body), unnamed(rest.clone()));
    // The CLI prints the same model, as a robot file that loads.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ur5e.urdf");
    std::fs::write(&file, &urdf).unwrap();
    let out = cli(&[
        "import-urdf",
        file.to_str().unwrap(),
        "--name",
        "imported-arm",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(json_eq(&printed, &rest), "CLI {printed}\nREST {rest}");
    let robot_file = dir.path().join("imported-arm.json");
    std::fs::write(&robot_file, &out.stdout).unwrap();
    let checked = cli(&["validate", robot_file.to_str().unwrap()]);
    assert!(
        checked.status.success(),
        "{}",
        String::from_utf8_lossy(&checked.stderr)
    );
}

#[tokio::test]
async fn an_imported_arm_works_downstream_like_the_built_in_it_came_from() {
    let app = guarded_app().await;
    let urdf = exported(&app, "ur5e").await;
    assert_eq!(
        post_xml(&app, "?name=imported-arm", &urdf).await.status(),
        201
    );
    let mdh = post_xml(
        &app,
        "?name=imported-mdh&convention=modified&tip_link=tool",
        &urdf,
    )
    .await;
    assert_eq!(mdh.status(), 201);
    let mdh: Value = mdh.json().await.unwrap();
    assert_eq!(mdh["convention"], "modified");
    // FK, both conventions.
    assert_same_fk(&app, "imported-arm", "ur5e", 6).await;
    assert_same_fk(&app, "imported-mdh", "ur5e", 6).await;
    // Frames: the import's own DH frames, one per row and the base; the last
    // one times the tool is the pose.
    let q = [0.3, -0.7, 1.1, -0.4, 0.9, 0.2];
    let fk = fk_ok(&app, "imported-arm", json!({"joints": q, "frames": true})).await;
    assert_eq!(fk["frames"].as_array().unwrap().len(), 7, "{fk}");
    // Jacobian (base frame) and its figures.
    for q in configs(5, 6) {
        let body = json!({"joints": q});
        let a: Value = app
            .post("/v1/robots/imported-arm/jacobian", &body)
            .await
            .json()
            .await
            .unwrap();
        let b: Value = app
            .post("/v1/robots/ur5e/jacobian", &body)
            .await
            .json()
            .await
            .unwrap();
        let (ja, jb) = (&a["jacobian"], &b["jacobian"]);
        for (r, (ra, rb)) in ja
            .as_array()
            .unwrap()
            .iter()
            .zip(jb.as_array().unwrap())
            .enumerate()
        {
            for (k, (x, y)) in ra
                .as_array()
                .unwrap()
                .iter()
                .zip(rb.as_array().unwrap())
                .enumerate()
            {
                assert_close(
                    x.as_f64().unwrap(),
                    y.as_f64().unwrap(),
                    TOL,
                    &format!("J[{r}][{k}]"),
                );
            }
        }
        let (ma, mb) = (
            a["manipulability"].as_f64().unwrap(),
            b["manipulability"].as_f64().unwrap(),
        );
        assert_close(ma, mb, 1e-10, "manipulability");
    }
    // IK: the target of a built-in pose, solved on the import, is reached.
    let target = &fk_ok(&app, "ur5e", json!({"joints": q})).await["pose"];
    let r = app
        .post(
            "/v1/robots/imported-arm/ik",
            &json!({"target": {"matrix": target["matrix"]}}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let ik: Value = r.json().await.unwrap();
    assert_eq!(ik["converged"], true, "{ik}");
    let back = fk_ok(&app, "imported-arm", json!({"joints": ik["joints"]})).await;
    assert_pose_eq(&back["pose"], target, 1e-9, "IK answer by FK");
    // Closed form: one link matrix per row, ⁰Tₙ 4×4.
    let r = app.get("/v1/robots/imported-arm/closed-form").await;
    assert_eq!(r.status(), 200);
    let cf: Value = r.json().await.unwrap();
    assert_eq!(cf["link_transforms"].as_array().unwrap().len(), 6);
    assert_eq!(cf["transform"]["text"].as_array().unwrap().len(), 4);
    // URDF export of the import, imported again: the same arm, the same table.
    let again = exported(&app, "imported-arm").await;
    let r = post_xml(&app, "?name=imported-again", &again).await;
    assert_eq!(r.status(), 201);
    let twice: Value = r.json().await.unwrap();
    assert_same_fk(&app, "imported-again", "ur5e", 6).await;
    let once: Value = app
        .get("/v1/robots/imported-arm")
        .await
        .json()
        .await
        .unwrap();
    for (i, (a, b)) in once["links"]
        .as_array()
        .unwrap()
        .iter()
        .zip(twice["links"].as_array().unwrap())
        .enumerate()
    {
        for k in ["a", "alpha", "d", "theta"] {
            assert_close(
                a[k].as_f64().unwrap(),
                b[k].as_f64().unwrap(),
                1e-12,
                &format!("links[{i}].{k}"),
            );
        }
    }
}

#[tokio::test]
async fn put_imports_create_then_replace_under_their_etags() {
    let app = guarded_app().await;
    let urdf = exported(&app, "planar_2dof").await;
    let put = |query: &'static str, etag: Option<String>| {
        let (app, urdf) = (&app, urdf.clone());
        async move {
            let mut req = app
                .client
                .put(format!("{}/v1/robots/imported-planar{query}", app.http))
                .header("content-type", "text/xml; charset=utf-8")
                .bearer_auth(TOKEN)
                .body(urdf);
            if let Some(tag) = etag {
                req = req.header("if-match", tag);
            }
            req.send().await.unwrap()
        }
    };
    let r = put("", None).await;
    assert_eq!(r.status(), 201);
    assert_eq!(r.headers()["location"], "/v1/robots/imported-planar");
    let first = r.headers()["etag"].to_str().unwrap().to_string();
    let r = put("?convention=modified", Some(first.clone())).await;
    assert_eq!(r.status(), 200);
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["convention"], "modified");
    assert_same_fk(&app, "imported-planar", "planar_2dof", 2).await;
    // The first version is gone: its tag no longer matches.
    let p = problem(put("", Some(first)).await, 412).await;
    assert_eq!(p["status"], 412);
    // PUT takes the name from its path only.
    let p = problem(put("?name=other", None).await, 400).await;
    assert_eq!(fields(&p), ["query"], "{p}");
}

/// A two-joint URDF whose second joint is `second` (the XML of `<joint …>`
/// from `type` on, to `</joint>`), plus `extra` elements.
fn two_joints(second: &str, extra: &str) -> String {
    format!(
        r#"<robot name="r"><link name="base"/><link name="l1"/><link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit lower="-2" upper="2"/></joint>
  <joint name="j2" {second}
  {extra}
</robot>"#
    )
}

/// The documents each front door must refuse: what, the document, the field
/// and a fragment of the message.
fn refused() -> Vec<(&'static str, String, &'static str, &'static str)> {
    let child = r#"<parent link="l1"/><child link="tip"/><origin xyz="0.4 0 0"/><axis xyz="0 0 1"/></joint>"#;
    vec![
        (
            "mimic",
            two_joints(
                &format!(r#"type="revolute"><mimic joint="j1"/>{child}"#),
                "",
            ),
            "urdf",
            "joint 'j2' mimics 'j1'",
        ),
        (
            "floating",
            two_joints(&format!(r#"type="floating">{child}"#), ""),
            "urdf",
            "joint 'j2' is floating",
        ),
        (
            "not URDF",
            "<html><body/></html>".to_string(),
            "urdf",
            "not URDF",
        ),
        (
            "an entity",
            format!(
                "<?xml version=\"1.0\"?><!DOCTYPE robot [<!ENTITY x \"base\">]>{}",
                two_joints(&format!(r#"type="revolute">{child}"#), "")
            ),
            "urdf",
            "entities are not accepted",
        ),
        (
            "two leaves",
            two_joints(
                &format!(r#"type="revolute">{child}"#),
                r#"<link name="finger"/><joint name="jf" type="fixed"><parent link="l1"/><child link="finger"/></joint>"#,
            ),
            "tip_link",
            "one of 'finger', 'tip'",
        ),
    ]
}

#[tokio::test]
async fn refusals_name_their_field_on_every_front_door() {
    let app = guarded_app().await;
    let mut c = app.grpc_client().await;
    let dir = tempfile::tempdir().unwrap();
    for (what, urdf, field, says) in refused() {
        // REST, XML.
        let p = problem(post_xml(&app, "?name=refused", &urdf).await, 422).await;
        assert_eq!(fields(&p), [field], "{what}: {p}");
        assert!(
            p["errors"][0]["message"].as_str().unwrap().contains(says),
            "{what}: {p}"
        );
        // REST, JSON import.
        let body = json!({"name": "refused", "urdf": urdf});
        let p = problem(post_import_json(&app, &body).await, 422).await;
        assert_eq!(fields(&p), [field], "{what} (JSON): {p}");
        // gRPC.
        let err = c
            .import_urdf(with_token(import_pb("refused", &urdf), &bearer()))
            .await
            .unwrap_err();
        assert_eq!(err.code(), Code::InvalidArgument, "{what}: {err:?}");
        assert_eq!(status_fields(&err), [field], "{what}: {err:?}");
        assert!(err.message().contains(says), "{what}: {err:?}");
        // CLI.
        let file = dir.path().join("refused.urdf");
        std::fs::write(&file, &urdf).unwrap();
        let out = cli(&["import-urdf", file.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{what}: the CLI exits 1");
        assert!(out.stdout.is_empty(), "{what}: nothing printed");
        assert!(
            stderr.contains(&format!("{field}: ")) && stderr.contains(says),
            "{what}: {stderr}"
        );
    }
    assert_eq!(
        app.get("/v1/robots/refused").await.status(),
        404,
        "nothing was stored"
    );
    // Naming the tip resolves the two leaves on every front door.
    let (_, two_leaves, _, _) = refused().pop().unwrap();
    let r = post_xml(&app, "?name=refused&tip_link=tip", &two_leaves).await;
    assert_eq!(r.status(), 201);
    let mut msg = import_pb("refused-grpc", &two_leaves);
    msg.tip_link = "tip".into();
    assert!(
        c.import_urdf(with_token(msg, &bearer()))
            .await
            .unwrap()
            .into_inner()
            .created
    );
    let file = dir.path().join("two.urdf");
    std::fs::write(&file, &two_leaves).unwrap();
    assert!(
        cli(&["import-urdf", file.to_str().unwrap(), "--tip", "tip"])
            .status
            .success()
    );
}

#[tokio::test]
async fn the_query_and_the_body_are_checked_before_any_import() {
    let app = guarded_app().await;
    let urdf = exported(&app, "planar_2dof").await;
    // A URDF body needs a name; a convention is standard or modified.
    let p = problem(post_xml(&app, "", &urdf).await, 422).await;
    assert_eq!(fields(&p), ["name"], "{p}");
    let p = problem(
        post_xml(&app, "?name=x1&convention=craig", &urdf).await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["convention"], "{p}");
    let p = problem(post_xml(&app, "?name=x1&tip=tool", &urdf).await, 400).await;
    assert_eq!(fields(&p), ["query"], "an unknown parameter: {p}");
    let p = problem(
        post_xml(&app, "?name=x1&base_link=nowhere&tip_link=tool", &urdf).await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["base_link"], "{p}");
    // The URDF parameters do not go with a JSON model.
    let r = app
        .client
        .post(format!("{}/v1/robots?tip_link=tool", app.http))
        .bearer_auth(TOKEN)
        .json(&planar_model("json-model"))
        .send()
        .await
        .unwrap();
    let p = problem(r, 400).await;
    assert_eq!(fields(&p), ["tip_link"], "{p}");
    // Not UTF-8, or declared in another charset.
    let r = app
        .client
        .post(format!("{}/v1/robots?name=x1", app.http))
        .header("content-type", "application/xml")
        .bearer_auth(TOKEN)
        .body(b"<robot name=\"\xff\"/>".to_vec())
        .send()
        .await
        .unwrap();
    let p = problem(r, 400).await;
    assert_eq!(fields(&p), ["urdf"], "{p}");
    let r = send(
        &app,
        reqwest::Method::POST,
        "/v1/robots?name=x1",
        "text/xml; charset=iso-8859-1",
        urdf.clone(),
    )
    .await;
    problem(r, 415).await;
    // gRPC: an unknown convention.
    let mut c = app.grpc_client().await;
    let mut msg = import_pb("x1", &urdf);
    msg.convention = 7;
    let err = c.import_urdf(with_token(msg, &bearer())).await.unwrap_err();
    assert_eq!(
        (err.code(), status_fields(&err)),
        (Code::InvalidArgument, vec!["convention".to_string()])
    );
    assert_eq!(app.get("/v1/robots/x1").await.status(), 404);
}

#[tokio::test]
async fn a_urdf_over_the_body_limit_is_413_and_over_the_message_limit_resource_exhausted() {
    let app = spawn_app_with(|c| {
        c.api_token = Some(TOKEN.into());
        c.max_body_bytes = 2048;
        c.max_batch_body_bytes = 2048;
    })
    .await;
    let urdf = exported(&app, "ur5e").await;
    assert!(urdf.len() > 2048, "the export is {} bytes", urdf.len());
    problem(post_xml(&app, "?name=too-big", &urdf).await, 413).await;
    let body = json!({"name": "too-big", "urdf": urdf});
    problem(post_import_json(&app, &body).await, 413).await;
    let mut c = app.grpc_client().await;
    let err = c
        .import_urdf(with_token(import_pb("too-big", &urdf), &bearer()))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::ResourceExhausted, "{err:?}");
    assert_eq!(app.get("/v1/robots/too-big").await.status(), 404);
}

/// gRPC messages may be larger than REST bodies (the batch limit), but a
/// URDF document is bounded by the body limit on both front doors.
#[tokio::test]
async fn a_grpc_import_is_bounded_by_the_body_limit_not_the_message_limit() {
    let app = spawn_app_with(|c| {
        c.api_token = Some(TOKEN.into());
        c.max_body_bytes = 4096;
    })
    .await;
    let urdf = exported(&app, "ur5e").await;
    let mut c = app.grpc_client().await;
    let err = c
        .import_urdf(with_token(import_pb("too-big", &urdf), &bearer()))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::ResourceExhausted, "{err:?}");
    assert!(err.message().contains("--max-body-bytes"), "{err:?}");
    let small = exported(&app, "planar_2dof").await;
    assert!(
        small.len() <= 4096 && urdf.len() > 4096,
        "{} bytes",
        small.len()
    );
    let ok = c
        .import_urdf(with_token(import_pb("small", &small), &bearer()))
        .await;
    assert!(ok.unwrap().into_inner().created);
}

#[tokio::test]
async fn imports_need_the_token_and_a_trusted_origin() {
    let app = guarded_app().await;
    let urdf = exported(&app, "planar_2dof").await;
    let post = |token: Option<&'static str>, origin: Option<&'static str>| {
        let (app, urdf) = (&app, urdf.clone());
        async move {
            let mut req = app
                .client
                .post(format!("{}/v1/robots?name=guarded", app.http))
                .header("content-type", "application/xml")
                .body(urdf);
            if let Some(t) = token {
                req = req.bearer_auth(t);
            }
            if let Some(o) = origin {
                req = req.header("origin", o);
            }
            req.send().await.unwrap()
        }
    };
    problem(post(None, None).await, 401).await;
    problem(post(Some("wrong"), None).await, 401).await;
    let p = problem(
        post(Some(TOKEN), Some("https://stranger.example")).await,
        403,
    )
    .await;
    assert_eq!(p["type"], "urn:kinserve:problem:forbidden");
    let mut c = app.grpc_client().await;
    let err = c
        .import_urdf(import_pb("guarded", &urdf))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::Unauthenticated);
    let err = c
        .import_urdf(with_token(import_pb("guarded", &urdf), "Bearer wrong"))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::Unauthenticated);
    assert_eq!(
        app.get("/v1/robots/guarded").await.status(),
        404,
        "nothing was written"
    );
    assert_eq!(post(Some(TOKEN), None).await.status(), 201);
}

#[test]
fn the_cli_names_the_robot_after_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("My Arm.v2.urdf");
    std::fs::write(&file, two_joints(r#"type="continuous"><parent link="l1"/><child link="tip"/><origin xyz="0.4 0 0"/><axis xyz="0 0 1"/></joint>"#, "")).unwrap();
    let out = cli(&[
        "import-urdf",
        file.to_str().unwrap(),
        "--convention",
        "modified",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let spec: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (spec["name"].as_str(), spec["convention"].as_str()),
        (Some("my-arm"), Some("modified"))
    );
    assert_eq!(spec["links"].as_array().unwrap().len(), 2);
}

/// The README's worked example: the document, posted as its curl line posts
/// it, answers the JSON shown.
#[tokio::test]
async fn the_readme_import_example_answers_as_shown() {
    let app = spawn_app().await;
    let marker = "<!-- urdf import example: ";
    let examples = readme_examples(marker);
    assert_eq!(examples.len(), 1, "one worked example");
    let (request, documented) = &examples[0];
    let path = request.strip_prefix("POST ").expect("POST PATH");
    let urdf = readme_block_after(marker, "```xml");
    let r = app
        .client
        .post(format!("{}{path}", app.http))
        .header("content-type", "application/xml")
        .body(urdf)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let answered: Value = r.json().await.unwrap();
    assert!(
        json_eq(&answered, documented),
        "the server answers {answered}"
    );
}
