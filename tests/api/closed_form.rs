//! Closed forms and URDF over REST and gRPC: the served answers are the
//! library's (`ClosedForm::of`, `to_urdf`) for every built-in, the OpenAPI
//! examples are the real answers for the planar arm, the two protocols agree,
//! and unknown robots and closed forms too long to print are refused with the
//! documented statuses. (The numbers themselves are checked against FK in
//! `crates/kinserve-model/tests/model/closed_form.rs` and `urdf.rs`.)

use std::path::Path;

use kinserve::api::grpc::pb;
use kinserve::api::rest::{PLANAR_CLOSED_FORM_EXAMPLE, PLANAR_URDF_EXAMPLE};
use kinserve::model::{ClosedForm, load_robot_file, to_urdf};
use serde_json::{Value, json};

use crate::helpers::*;

fn builtin_names() -> Vec<String> {
    let mut names: Vec<String> =
        std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("robots"))
            .unwrap()
            .filter_map(|e| {
                let p = e.unwrap().path();
                (p.extension()? == "json")
                    .then(|| p.file_stem().unwrap().to_string_lossy().into_owned())
            })
            .collect();
    names.sort();
    names
}

fn load(name: &str) -> kinserve::model::Robot {
    load_robot_file(&Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("robots/{name}.json")))
        .unwrap()
}

/// A registered model whose closed form is too long to print: 40 rows with alternating twists.
fn snake() -> Value {
    let links: Vec<Value> = (0..40)
        .map(|i| json!({"joint": "revolute", "a": 0.1, "alpha": if i % 2 == 0 { 90 } else { -90 }, "d": 0.1, "theta": 0}))
        .collect();
    json!({"name": "snake", "convention": "standard", "angle_unit": "deg", "links": links})
}

#[tokio::test]
async fn rest_closed_form_of_every_builtin_is_the_librarys() {
    let app = spawn_app().await;
    for name in builtin_names() {
        let r = app.get(&format!("/v1/robots/{name}/closed-form")).await;
        assert_eq!(r.status(), 200, "{name}");
        assert_eq!(r.headers()["content-type"], "application/json", "{name}");
        let body: Value = r.json().await.unwrap();
        let want = serde_json::to_value(ClosedForm::of(&load(&name)).unwrap()).unwrap();
        assert!(
            json_eq(&body, &want),
            "{name}: served closed form differs from the library's"
        );
    }
}

#[tokio::test]
async fn rest_planar_closed_form_is_the_openapi_example() {
    let app = spawn_app().await;
    let body: Value = app
        .get("/v1/robots/planar_2dof/closed-form")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(body["transform"]["text"][0][3], "a1*c1 + a2*c12");
    assert_eq!(body["robot"], "planar_2dof");
    assert_eq!(body["convention"], "standard");
    assert_eq!(body["length_unit"], "m");
    assert_eq!(body["symbols"], json!({"a1": 0.4, "a2": 0.3}));
    // No tool: the key is absent (not `null`), as `tool` is absent from the
    // gRPC answer; the OpenAPI schema does not list it as required.
    assert!(body.get("tool").is_none(), "no tool key: {body}");
    let example: Value = serde_json::from_str(PLANAR_CLOSED_FORM_EXAMPLE).unwrap();
    assert!(
        json_eq(&body, &example),
        "the OpenAPI example is stale: {body}"
    );
    let doc: Value = app.get("/openapi.json").await.json().await.unwrap();
    let documented = &doc["paths"]["/v1/robots/{name}/closed-form"]["get"]["responses"]["200"]["content"]
        ["application/json"]["example"];
    assert!(
        json_eq(documented, &example),
        "openapi.json carries the example: {documented}"
    );
    let urdf_doc = &doc["paths"]["/v1/robots/{name}/urdf"]["get"]["responses"]["200"]["content"]["application/xml"]
        ["example"];
    assert_eq!(urdf_doc.as_str(), Some(PLANAR_URDF_EXAMPLE));
}

#[tokio::test]
async fn rest_urdf_of_every_builtin_is_xml_from_the_library() {
    let app = spawn_app().await;
    for name in builtin_names() {
        let r = app.get(&format!("/v1/robots/{name}/urdf")).await;
        assert_eq!(r.status(), 200, "{name}");
        assert_eq!(r.headers()["content-type"], "application/xml", "{name}");
        let body = r.text().await.unwrap();
        assert_eq!(body, to_urdf(&load(&name)), "{name}");
        if name == "planar_2dof" {
            assert_eq!(body, PLANAR_URDF_EXAMPLE, "the OpenAPI example is stale");
        }
    }
}

#[tokio::test]
async fn rest_unknown_robot_bad_name_and_too_long_closed_form_are_problems() {
    let app = spawn_app().await;
    for path in ["/v1/robots/nope/closed-form", "/v1/robots/nope/urdf"] {
        let r = app.get(path).await;
        assert_eq!(r.status(), 404, "{path}");
        assert_eq!(r.headers()["content-type"], "application/problem+json");
    }
    // A path segment that is not UTF-8 is malformed.
    let r = app.get("/v1/robots/%FF/closed-form").await;
    assert_eq!(r.status(), 400);
    assert_eq!(app.post("/v1/robots", &snake()).await.status(), 201);
    let r = app.get("/v1/robots/snake/closed-form").await;
    assert_eq!(r.status(), 413, "past the closed-form work limit");
    let p: Value = r.json().await.unwrap();
    assert_eq!(p["errors"][0]["field"], "links", "{p}");
    assert!(p["detail"].as_str().unwrap().contains("too large"), "{p}");
    // Its URDF has no such limit: 40 rows, 42 joints.
    let xml = app.get("/v1/robots/snake/urdf").await.text().await.unwrap();
    assert_eq!(xml.matches("<joint ").count(), 42);
}

#[tokio::test]
async fn rest_closed_form_of_a_registered_robot_with_a_tool() {
    let app = spawn_app().await;
    let mut model = planar_model("tooled");
    model["tool"] = json!({"translation": [0.05, 0, 0], "rpy": [0, 0, 0]});
    assert_eq!(app.post("/v1/robots", &model).await.status(), 201);
    let body: Value = app
        .get("/v1/robots/tooled/closed-form")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(body["transform"]["text"][0][3], "a1*c1 + a2*c12");
    assert_eq!(body["symbols"], json!({"a1": 0.5, "a2": 0.3}));
    assert_eq!(
        body["tool"][0][3], 0.05,
        "the tool is given as numbers: {}",
        body["tool"]
    );
    assert_eq!(
        body["base"],
        json!([
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0]
        ])
    );
    let variables: Vec<&str> = body["variables"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["name"].as_str().unwrap())
        .collect();
    assert_eq!(variables, ["theta1", "theta2"]);
}

#[tokio::test]
async fn grpc_closed_form_and_urdf_agree_with_rest() {
    let app = spawn_app().await;
    let mut client = app.grpc_client().await;
    for name in ["puma560", "alpha_ii", "panda", "stanford"] {
        let rest: Value = app
            .get(&format!("/v1/robots/{name}/closed-form"))
            .await
            .json()
            .await
            .unwrap();
        let r = client
            .get_closed_form(pb::GetClosedFormRequest { robot: name.into() })
            .await
            .unwrap()
            .into_inner();
        assert_eq!(r.robot, name);
        let text = r.transform.as_ref().unwrap().text.clone();
        let rest_text: Vec<String> = rest["transform"]["text"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|row| {
                row.as_array()
                    .unwrap()
                    .iter()
                    .map(|e| e.as_str().unwrap().to_string())
            })
            .collect();
        assert_eq!(text, rest_text, "{name}: 16 entries, row-major");
        assert_eq!(
            r.transform.as_ref().unwrap().latex,
            rest["transform"]["latex"],
            "{name}"
        );
        assert_eq!(
            r.transform.as_ref().unwrap().mathml,
            rest["transform"]["mathml"],
            "{name}"
        );
        assert_eq!(
            r.link_transforms.len(),
            rest["link_transforms"].as_array().unwrap().len(),
            "{name}"
        );
        assert_eq!(
            r.symbols.len(),
            rest["symbols"].as_object().unwrap().len(),
            "{name}"
        );
        for (k, v) in &r.symbols {
            assert_eq!(rest["symbols"][k].as_f64(), Some(*v), "{name}: symbol {k}");
        }
        assert_eq!(
            r.variables.len(),
            rest["variables"].as_array().unwrap().len()
        );
        assert_eq!(r.base.as_ref().unwrap().values.len(), 16);
        assert!(r.tool.is_none(), "{name} has no tool");
        assert!(
            rest.get("tool").is_none(),
            "{name}: REST leaves the key out as gRPC does"
        );
        let urdf = client
            .get_urdf(pb::GetUrdfRequest { robot: name.into() })
            .await
            .unwrap()
            .into_inner();
        assert_eq!(
            urdf.urdf,
            app.get(&format!("/v1/robots/{name}/urdf"))
                .await
                .text()
                .await
                .unwrap()
        );
    }
    let stanford = client
        .get_closed_form(pb::GetClosedFormRequest {
            robot: "stanford".into(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(stanford.variables[2].kind, pb::JointType::Prismatic as i32);
    assert_eq!(stanford.variables[2].name, "d3");
}

#[tokio::test]
async fn grpc_closed_form_errors_are_statuses() {
    let app = spawn_app().await;
    let mut client = app.grpc_client().await;
    let e = client
        .get_closed_form(pb::GetClosedFormRequest {
            robot: "nope".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), tonic::Code::NotFound);
    let e = client
        .get_urdf(pb::GetUrdfRequest {
            robot: "nope".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), tonic::Code::NotFound);
    assert_eq!(app.post("/v1/robots", &snake()).await.status(), 201);
    let e = client
        .get_closed_form(pb::GetClosedFormRequest {
            robot: "snake".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(
        e.code(),
        tonic::Code::ResourceExhausted,
        "past the work limit"
    );
    assert_eq!(status_fields(&e), ["links"]);
}
