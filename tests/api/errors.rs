//! Errors that say how to fix the mistake, on every front door: joint values
//! that look like degrees, limits in readable units, unknown robot names with
//! suggestions, empty names, JSON syntax errors with their position — and the
//! README's error examples exactly as the server prints them.

use kinserve::api::grpc::pb;
use serde_json::{Value, json};
use tonic::Code;

use crate::helpers::*;

/// POSTs a raw body to `path` and returns (status, JSON body).
async fn post_raw(app: &TestApp, path: &str, body: &str) -> (u16, Value) {
    let r = app
        .client
        .post(format!("{}{path}", app.http))
        .header("content-type", "application/json")
        .body(body.to_string())
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    (status, r.json().await.unwrap())
}

#[tokio::test]
async fn joint_values_that_look_like_degrees_say_so_over_rest_and_grpc() {
    let app = spawn_app().await;
    let q = [0.0, 90.0, -90.0, 0.0, 0.0, 0.0];
    let (status, p) = post_raw(
        &app,
        "/v1/robots/puma560/fk",
        &json!({"joints": q}).to_string(),
    )
    .await;
    assert_eq!(status, 422, "{p}");
    let message = p["errors"][0]["message"].as_str().unwrap();
    assert_eq!(p["errors"][0]["field"], "joints[1]");
    assert!(message.contains("send angle_unit \"deg\""), "{message}");
    // Limits in the request's unit to 6 significant digits, and in the model's own unit.
    assert!(message.contains("[-1.91986, 1.91986] rad"), "{message}");
    assert!(
        message.contains("([-110, 110] deg in the model)"),
        "{message}"
    );
    // The same message over gRPC.
    let mut client = app.grpc_client().await;
    let e = client
        .forward_kinematics(fk_request("puma560", &q, None))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert!(e.message().contains(message), "{}", e.message());
    // Values that are wrong but not degrees-like get no such hint.
    let (status, p) = post_raw(
        &app,
        "/v1/robots/puma560/fk",
        r#"{"joints": [0, 3, 0, 0, 0, 0]}"#,
    )
    .await;
    assert_eq!(status, 422, "{p}");
    assert!(!p["detail"].as_str().unwrap().contains("degrees"), "{p}");
}

#[tokio::test]
async fn unknown_robot_names_suggest_the_nearest_ones() {
    let app = spawn_app().await;
    for (asked, expect) in [
        ("Puma-560", "puma560"),
        ("ur5E", "ur5e"),
        ("stanfrd", "stanford"),
    ] {
        let path = format!("/v1/robots/{asked}/fk");
        let (status, p) = post_raw(&app, &path, r#"{"joints": [0]}"#).await;
        assert_eq!(status, 404, "{p}");
        let detail = p["detail"].as_str().unwrap();
        assert!(detail.contains(&format!("'{expect}'")), "{asked}: {detail}");
        assert!(detail.contains("did you mean"), "{detail}");
    }
    // Nothing close: no suggestion.
    let (_, p) = post_raw(&app, "/v1/robots/zzzzzzzzzz/fk", r#"{"joints": [0]}"#).await;
    assert!(
        !p["detail"].as_str().unwrap().contains("did you mean"),
        "{p}"
    );
    let mut client = app.grpc_client().await;
    let e = client
        .forward_kinematics(fk_request("Puma-560", &[0.0; 6], None))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::NotFound);
    assert!(
        e.message().contains("did you mean 'puma560'"),
        "{}",
        e.message()
    );
}

#[tokio::test]
async fn an_empty_robot_name_is_invalid_argument_naming_the_field() {
    let app = spawn_app().await;
    let mut client = app.grpc_client().await;
    let e = client
        .forward_kinematics(fk_request("", &[0.0], None))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&e), ["robot"]);
    let e = client
        .get_robot(pb::GetRobotRequest {
            name: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&e), ["name"]);
}

#[tokio::test]
async fn json_syntax_errors_give_line_and_column() {
    let app = spawn_app().await;
    let body = "{\n  \"joints\": [0, 0,]\n}";
    let (status, p) = post_raw(&app, "/v1/robots/planar_2dof/fk", body).await;
    assert_eq!(status, 400, "{p}");
    let detail = p["detail"].as_str().unwrap();
    assert!(detail.contains("line 2 column"), "{detail}");
}

/// Every `<!-- error example: METHOD PATH BODY -->` in the README is followed
/// by a ```json block with the problem the server answers, word for word.
#[tokio::test]
async fn readme_error_examples_are_what_the_server_prints() {
    let app = spawn_app().await;
    let mut seen = 0;
    for (request, documented) in readme_examples("<!-- error example: ") {
        let (method, rest_req) = request.split_once(' ').unwrap();
        let (path, body) = rest_req.split_once(' ').unwrap();
        assert_eq!(method, "POST", "only POST examples are checked");
        let (status, answered) = post_raw(&app, path, body).await;
        assert_eq!(Value::from(status), documented["status"], "{path} {body}");
        assert_eq!(answered, documented, "README example for {path} {body}");
        seen += 1;
    }
    assert!(
        seen >= 3,
        "the README shows at least three error examples, found {seen}"
    );
}

/// A degree table registered without `angle_unit` (read as radians) is
/// refused on every front door, saying how to fix it, instead of being
/// stored with wrong poses; the same table with `"angle_unit": "deg"` is fine.
#[tokio::test]
async fn a_degree_table_sent_as_radians_is_refused_with_the_fix() {
    let app = spawn_app().await;
    let mut model = planar_model("deg-table");
    model.as_object_mut().unwrap().remove("angle_unit");
    model["links"][0]["alpha"] = json!(90);
    let p = problem(app.post("/v1/robots", &model).await, 422).await;
    let by_field: Vec<(String, String)> = p["errors"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["field"].as_str().unwrap().into(),
                e["message"].as_str().unwrap().into(),
            )
        })
        .collect();
    let fields: Vec<&str> = by_field.iter().map(|(f, _)| f.as_str()).collect();
    assert_eq!(fields, ["links[0].alpha", "links[0].limits"], "{p}");
    for (_, message) in &by_field {
        assert!(message.contains("add \"angle_unit\": \"deg\""), "{message}");
    }
    // gRPC: the same fields.
    let mut client = app.grpc_client().await;
    let spec: kinserve::model::RobotSpec = serde_json::from_value(model.clone()).unwrap();
    let e = client
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(pb::Robot::from(&spec)),
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert!(
        e.message().contains("links[0].alpha") && e.message().contains("angle_unit"),
        "{}",
        e.message()
    );
    // Declared as degrees, it registers.
    model["angle_unit"] = json!("deg");
    assert_eq!(app.post("/v1/robots", &model).await.status(), 201);
}

/// A misspelled field or enum value names the nearest right one first.
#[tokio::test]
async fn a_misspelled_field_suggests_the_right_one() {
    let app = spawn_app().await;
    let (status, p) = post_raw(
        &app,
        "/v1/robots/puma560/fk",
        r#"{"jionts": [0, 0, 0, 0, 0, 0]}"#,
    )
    .await;
    assert_eq!(status, 400, "{p}");
    assert_eq!(p["errors"][0]["field"], "jionts");
    let message = p["errors"][0]["message"].as_str().unwrap();
    assert!(message.contains("did you mean `joints`?"), "{message}");
    let (status, p) = post_raw(
        &app,
        "/v1/robots/puma560/fk",
        r#"{"joints": [0, 0, 0, 0, 0, 0], "angle_unit": "degs"}"#,
    )
    .await;
    assert_eq!(status, 400, "{p}");
    assert!(
        p["errors"][0]["message"]
            .as_str()
            .unwrap()
            .contains("did you mean `deg`?"),
        "{p}"
    );
}
