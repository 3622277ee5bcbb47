//! Velocity and inverse kinematics over REST and the WebSocket stream:
//! `POST /v1/robots/{name}/jacobian`, `/jacobian/batch`, `/ik`, `/ik/batch`,
//! and `"jacobian": true` / `"ik": {...}` messages — closed forms, round
//! trips through FK, limits, field paths, the `ik-not-converged` problem with
//! its best attempt, and the same answers on REST and WebSocket.

use futures_util::SinkExt;
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;

use crate::helpers::pose::assert_pose_eq;
use crate::helpers::*;

/// `POST {path}` expecting 200; the body.
async fn ok(app: &TestApp, path: &str, body: &Value) -> Value {
    let r = app.post(path, body).await;
    let status = r.status();
    let text = r.text().await.unwrap();
    assert_eq!(status, 200, "{path} {body}: {text}");
    serde_json::from_str(&text).unwrap()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

fn rows(v: &Value) -> Vec<Vec<f64>> {
    v.as_array().expect("rows").iter().map(floats).collect()
}

/// A target of the form `{"matrix": …}` from a JSON pose.
fn matrix_target(pose: &Value) -> Value {
    json!({"matrix": pose["matrix"].clone()})
}

// ---------------------------------------------------------------- Jacobian

#[tokio::test]
async fn the_planar_jacobian_matches_its_closed_form_per_radian() {
    let app = spawn_app().await;
    let (a1, a2) = (0.4, 0.3);
    for (t1, t2) in [(30.0, 45.0), (-120.0, 75.0), (10.0, 0.0)] {
        let out = ok(
            &app,
            "/v1/robots/planar_2dof/jacobian",
            &json!({"joints": [t1, t2], "angle_unit": "deg"}),
        )
        .await;
        assert_eq!(out["robot"], "planar_2dof");
        assert_eq!(out["length_unit"], "m");
        assert_eq!(out["frame"], "base", "base is the default");
        let (r1, r12) = (f64::to_radians(t1), f64::to_radians(t1 + t2));
        let expected = [
            [-a1 * r1.sin() - a2 * r12.sin(), -a2 * r12.sin()],
            [a1 * r1.cos() + a2 * r12.cos(), a2 * r12.cos()],
            [0.0, 0.0],
            [0.0, 0.0],
            [0.0, 0.0],
            [1.0, 1.0],
        ];
        let j = rows(&out["jacobian"]);
        assert_eq!(j.len(), 6);
        for (r, row) in expected.iter().enumerate() {
            for (c, x) in row.iter().enumerate() {
                assert_close(j[r][c], *x, CLOSED_FORM_TOL, &format!("J[{r}][{c}]"));
            }
        }
        // Up to 3 joints: the linear rows; for the planar 2R arm a1·a2·|sin θ2|.
        let m = out["manipulability"].as_f64().unwrap();
        assert_close(
            m,
            a1 * a2 * f64::to_radians(t2).sin().abs(),
            CLOSED_FORM_TOL,
            "w",
        );
        assert_eq!(out["singular"], t2 == 0.0, "θ2 = {t2}");
        if t2 == 0.0 {
            let c = &out["condition_number"];
            assert!(c.is_null() || c.as_f64().unwrap() > 1e12, "{c}");
        }
        let fk = fk_ok(
            &app,
            "planar_2dof",
            json!({"joints": [t1, t2], "angle_unit": "deg"}),
        )
        .await;
        assert_pose_eq(&out["pose"], &fk["pose"], SAME_LIB_TOL, "pose");
    }
}

/// `Rᵀ` applied to the linear and the angular half of every column.
fn rotate_to_tool(j: &[Vec<f64>], pose: &Value) -> Vec<Vec<f64>> {
    let m = matrix16(pose);
    let r = |i: usize, k: usize| m[i * 4 + k];
    let mut out = vec![vec![0.0; j[0].len()]; 6];
    for c in 0..j[0].len() {
        for half in [0, 3] {
            for i in 0..3 {
                out[half + i][c] = (0..3).map(|k| r(k, i) * j[half + k][c]).sum();
            }
        }
    }
    out
}

#[tokio::test]
async fn the_tool_frame_jacobian_is_the_base_one_rotated_into_the_tool() {
    let app = spawn_app().await;
    for (robot, q) in [
        ("puma560", json!([0.3, -0.5, 0.4, 0.2, 0.6, -0.1])),
        ("panda", json!([0.1, -0.4, 0.2, -2.0, 0.3, 1.8, 0.5])),
        ("stanford", json!([0.2, -0.4, 0.5, 0.5, -0.6, 0.7])),
    ] {
        let path = format!("/v1/robots/{robot}/jacobian");
        let base = ok(&app, &path, &json!({"joints": q, "frame": "base"})).await;
        let tool = ok(&app, &path, &json!({"joints": q, "frame": "tool"})).await;
        assert_eq!(tool["frame"], "tool");
        let expected = rotate_to_tool(&rows(&base["jacobian"]), &base["pose"]);
        for (r, (a, b)) in rows(&tool["jacobian"]).iter().zip(&expected).enumerate() {
            for (c, (x, y)) in a.iter().zip(b).enumerate() {
                assert_close(*x, *y, SAME_LIB_TOL, &format!("{robot} J[{r}][{c}]"));
            }
        }
        // Rotating the rows keeps the singular values.
        let (mb, mt) = (&base["manipulability"], &tool["manipulability"]);
        assert_close(
            mt.as_f64().unwrap(),
            mb.as_f64().unwrap(),
            1e-9,
            "manipulability",
        );
    }
}

#[tokio::test]
async fn bad_jacobian_requests_are_problems_with_field_paths() {
    let app = spawn_app().await;
    let path = "/v1/robots/puma560/jacobian";
    let p = problem(
        app.post(
            path,
            &json!({"joints": [0, 0, 0, 0, 0, 0], "frame": "world"}),
        )
        .await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["frame"]);
    let p = problem(app.post(path, &json!({"joints": [0, 0, 0]})).await, 422).await;
    assert_eq!(fields(&p), ["joints"]);
    let p = problem(
        app.post(path, &json!({"joints": [0, 0, 0, 0, 9, 0]})).await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["joints[4]"]);
    // ... unless the limit check is off.
    ok(
        &app,
        path,
        &json!({"joints": [0, 0, 0, 0, 9, 0], "check_limits": false}),
    )
    .await;
    let p = problem(
        app.post("/v1/robots/nope/jacobian", &json!({"joints": [0]}))
            .await,
        404,
    )
    .await;
    assert_eq!(p["type"], "urn:kinserve:problem:not-found");
    let body = json!({"configurations": [[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 9, 0]]});
    let p = problem(
        app.post("/v1/robots/puma560/jacobian/batch", &body).await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["configurations[1][4]"]);
}

#[tokio::test]
async fn a_jacobian_batch_answers_in_request_order_like_single_requests() {
    let app = spawn_app().await;
    let cfgs = configs(5, 6);
    let out = ok(
        &app,
        "/v1/robots/puma560/jacobian/batch",
        &json!({"configurations": cfgs, "frame": "tool"}),
    )
    .await;
    let results = out["results"].as_array().unwrap();
    assert_eq!(results.len(), 5);
    for (q, r) in cfgs.iter().zip(results) {
        let single = ok(
            &app,
            "/v1/robots/puma560/jacobian",
            &json!({"joints": q, "frame": "tool"}),
        )
        .await;
        assert_eq!(r["jacobian"], single["jacobian"]);
        assert_eq!(r["manipulability"], single["manipulability"]);
        assert_eq!(r["singular"], single["singular"]);
        assert_eq!(r["pose"], single["pose"]);
    }
}

// ---------------------------------------------------------------- IK

#[tokio::test]
async fn ik_of_an_fk_pose_reaches_it_within_the_limits_in_either_unit() {
    let app = spawn_app().await;
    let cases = [
        ("puma560", json!([20.0, -30.0, 45.0, 10.0, 50.0, -20.0])),
        ("ur5e", json!([30.0, -80.0, 70.0, -40.0, 80.0, 10.0])),
        (
            "panda",
            json!([10.0, -20.0, 15.0, -110.0, 20.0, 100.0, 30.0]),
        ),
    ];
    for (robot, q) in cases {
        let fk = fk_ok(&app, robot, json!({"joints": q, "angle_unit": "deg"})).await;
        let pose = &fk["pose"];
        let quaternion_target =
            json!({"position": pose["position"], "quaternion": pose["quaternion"]});
        for (target, unit) in [(matrix_target(pose), "deg"), (quaternion_target, "rad")] {
            let out = ok(
                &app,
                &format!("/v1/robots/{robot}/ik"),
                &json!({"target": target, "angle_unit": unit}),
            )
            .await;
            assert_eq!(
                (out["robot"].as_str(), out["angle_unit"].as_str()),
                (Some(robot), Some(unit))
            );
            assert_eq!(out["converged"], true);
            assert!(out["position_error"].as_f64().unwrap() <= 1e-9, "{out}");
            assert!(out["orientation_error"].as_f64().unwrap() <= 1e-9, "{out}");
            assert!(out["iterations"].as_u64().is_some());
            // The joints, in the answer's unit, pass the limit check and give the target.
            let again = fk_ok(
                &app,
                robot,
                json!({"joints": out["joints"], "angle_unit": unit}),
            )
            .await;
            assert_pose_eq(&again["pose"], pose, 1e-9, robot);
            assert_pose_eq(&again["pose"], &out["pose"], SAME_LIB_TOL, robot);
        }
    }
}

#[tokio::test]
async fn an_unreachable_target_is_ik_not_converged_with_the_best_attempt() {
    let app = spawn_app().await;
    let body = json!({"target": {"position": [5.0, 0.0, 0.5], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}},
        "angle_unit": "deg", "restarts": 3});
    let p = problem(app.post("/v1/robots/ur5e/ik", &body).await, 422).await;
    assert_eq!(p["type"], "urn:kinserve:problem:ik-not-converged");
    assert!(
        p["detail"].as_str().unwrap().contains("did not converge"),
        "{p}"
    );
    assert!(
        p["detail"].as_str().unwrap().contains("looks out of reach"),
        "a best attempt metres off says so: {p}"
    );
    let best = &p["best_attempt"];
    assert_eq!(best["converged"], false);
    // UR5e reaches about 0.85 m: the best attempt is at least 4 m short.
    assert!(best["position_error"].as_f64().unwrap() > 4.0, "{best}");
    assert!(best["orientation_error"].as_f64().is_some());
    // Its joints (degrees) are within the limits and give its pose.
    let fk = fk_ok(
        &app,
        "ur5e",
        json!({"joints": best["joints"], "angle_unit": "deg"}),
    )
    .await;
    assert_pose_eq(&fk["pose"], &best["pose"], SAME_LIB_TOL, "best attempt");
}

#[tokio::test]
async fn bad_ik_requests_are_problems_with_field_paths() {
    let app = spawn_app().await;
    let path = "/v1/robots/puma560/ik";
    let bad_row = json!([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 2]]);
    let q = json!({"w": 1, "x": 0, "y": 0, "z": 0});
    for (body, field) in [
        (json!({"target": {"matrix": bad_row}}), "target.matrix[3]"),
        (
            json!({"target": {"position": [0.3, 0, 0.2]}}),
            "target.quaternion",
        ),
        (
            json!({"target": {"position": [0.3, 0, 0.2], "quaternion": q}, "tolerance": 0}),
            "tolerance",
        ),
        (
            json!({"target": {"position": [0.3, 0, 0.2], "quaternion": q}, "max_iterations": 0}),
            "max_iterations",
        ),
        (
            json!({"target": {"position": [0.3, 0, 0.2], "quaternion": q}, "seed": [0, 0, 0, 0, 9, 0]}),
            "seed[4]",
        ),
    ] {
        let p = problem(app.post(path, &body).await, 422).await;
        assert_eq!(p["type"], "urn:kinserve:problem:invalid-input", "{body}");
        assert_eq!(fields(&p), [field], "{body}");
        assert!(p.get("best_attempt").is_none());
    }
    let p = problem(
        app.post(path, &json!({"target": {"position": [0, 0]}}))
            .await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["target.position"]);
    let p = problem(
        app.post(path, &json!({"target": {"matrix": bad_row}, "bogus": 1}))
            .await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["bogus"]);
}

#[tokio::test]
async fn position_only_ik_reaches_the_point_and_reports_no_orientation_error() {
    let app = spawn_app().await;
    let out = ok(
        &app,
        "/v1/robots/planar_2dof/ik",
        &json!({"target": {"position": [0.5, 0.2, 0.0]}, "position_only": true}),
    )
    .await;
    assert_eq!(out["converged"], true);
    assert!(out["orientation_error"].is_null(), "{out}");
    let p = position(&out["pose"]);
    for (x, y) in p.iter().zip([0.5, 0.2, 0.0]) {
        assert_close(*x, y, 1e-9, "position");
    }
}

#[tokio::test]
async fn an_ik_batch_answers_every_target_in_order_and_tracks_the_path() {
    let app = spawn_app().await;
    let mut targets = Vec::new();
    for k in 0..6 {
        let q = json!([0.2 + 0.02 * k as f64, -1.2, 1.1, -0.5, 1.3, 0.2]);
        targets.push(matrix_target(
            &fk_ok(&app, "ur5e", json!({"joints": q})).await["pose"],
        ));
    }
    // An unreachable target in the middle is answered, not converged, and the batch goes on.
    targets.insert(
        3,
        json!({"position": [4.0, 0, 0], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}}),
    );
    let out = ok(
        &app,
        "/v1/robots/ur5e/ik/batch",
        &json!({"targets": targets, "seed": [0.2, -1.2, 1.1, -0.5, 1.3, 0.2], "restarts": 2}),
    )
    .await;
    let results = out["results"].as_array().unwrap();
    assert_eq!(results.len(), 7);
    for (k, r) in results.iter().enumerate() {
        assert_eq!(r["converged"], k != 3, "{k}: {r}");
        let fk = fk_ok(&app, "ur5e", json!({"joints": r["joints"]})).await;
        assert_pose_eq(&fk["pose"], &r["pose"], SAME_LIB_TOL, "answer pose");
        if k != 3 {
            let (reached, wanted) = (matrix16(&fk["pose"]), matrix16(&targets[k]));
            for (x, y) in reached.iter().zip(&wanted) {
                assert_close(*x, *y, 1e-9, &format!("target {k}"));
            }
            // Tracking from the seed: joint 1 follows the path.
            let j1 = floats(&r["joints"])[0];
            let expect = 0.2 + 0.02 * (if k < 3 { k } else { k - 1 }) as f64;
            assert_close(j1, expect, 1e-6, "joint 1 tracks");
        }
    }
}

#[tokio::test]
async fn an_ik_batch_over_the_limit_is_413_naming_targets() {
    let app = spawn_app_with(|c| c.max_batch = 2).await;
    let body =
        json!({"targets": vec![json!({"position": [0.3, 0.1, 0.2]}); 3], "position_only": true});
    let p = problem(app.post("/v1/robots/ur5e/ik/batch", &body).await, 413).await;
    assert_eq!(fields(&p), ["targets"]);
}

// ---------------------------------------------------------------- WebSocket

async fn ws_roundtrip(sock: &mut Ws, msgs: &[Value]) -> Vec<Value> {
    for m in msgs {
        sock.send(Message::Text(m.to_string().into()))
            .await
            .unwrap();
    }
    let mut out = Vec::new();
    for _ in msgs {
        out.push(next_text(sock).await.expect("a reply"));
    }
    out
}

#[tokio::test]
async fn the_stream_answers_fk_jacobian_and_ik_in_order_like_rest() {
    // No time cap in reach: REST and WebSocket answers are compared exactly.
    let app = spawn_app_with(|c| c.ik_time_limit = std::time::Duration::from_secs(30)).await;
    let q = json!([0.3, -0.5, 0.4, 0.2, 0.6, -0.1]);
    let fk = fk_ok(&app, "puma560", json!({"joints": q})).await;
    let ik_body = json!({"target": matrix_target(&fk["pose"]), "angle_unit": "deg"});
    let far = json!({"target": {"position": [5, 0, 0], "quaternion": {"w": 1, "x": 0, "y": 0, "z": 0}}, "restarts": 1});
    let mut sock = open_ws(&app, "puma560").await;
    let replies = ws_roundtrip(
        &mut sock,
        &[
            json!({"id": 1, "joints": q, "jacobian": true, "frame": "tool"}),
            json!({"id": 2, "ik": ik_body}),
            json!({"id": 3, "ik": far}),
            json!({"id": 4, "joints": q}),
            json!({"id": 5, "joints": q, "ik": ik_body}),
            json!({"id": 6}),
        ],
    )
    .await;
    let ids: Vec<i64> = replies.iter().map(|r| r["id"].as_i64().unwrap()).collect();
    assert_eq!(ids, [1, 2, 3, 4, 5, 6]);
    // 1: FK with the Jacobian, as REST answers it.
    let rest = ok(
        &app,
        "/v1/robots/puma560/jacobian",
        &json!({"joints": q, "frame": "tool"}),
    )
    .await;
    for k in [
        "jacobian",
        "manipulability",
        "condition_number",
        "singular",
        "frame",
        "pose",
    ] {
        assert_eq!(replies[0][k], rest[k], "{k}");
    }
    // 2: IK, as REST answers it (deterministic solver).
    let rest = ok(&app, "/v1/robots/puma560/ik", &ik_body).await;
    for k in [
        "joints",
        "converged",
        "position_error",
        "orientation_error",
        "iterations",
        "pose",
    ] {
        assert_eq!(replies[1][k], rest[k], "{k}");
    }
    // 3: not converged, with the best attempt.
    let e = &replies[2]["error"];
    check_problem(e, 422);
    assert_eq!(e["type"], "urn:kinserve:problem:ik-not-converged");
    assert_eq!(e["best_attempt"]["converged"], false);
    // 4: plain FK has no Jacobian or IK fields.
    assert!(replies[3].get("jacobian").is_none() && replies[3].get("joints").is_none());
    assert_pose_eq(&replies[3]["pose"], &fk["pose"], 0.0, "fk");
    // 5, 6: joints and ik together (422), and neither (400, a missing field),
    // are refused naming joints.
    for (r, status) in replies[4..].iter().zip([422, 400]) {
        check_problem(&r["error"], status);
        assert_eq!(fields(&r["error"]), ["joints"], "{r}");
    }
}
