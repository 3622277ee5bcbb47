//! WebSocket contract tests: `GET /v1/robots/{name}/fk/stream`.

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream, connect_async};

use crate::helpers::pose::assert_pose_eq;
use crate::helpers::*;

type Ws = WebSocketStream<MaybeTlsStream<TcpStream>>;

const SAME_LIB_TOL: f64 = 1e-12;
const CLOSED_FORM_TOL: f64 = 1e-9;

async fn open(app: &TestApp, robot: &str) -> Ws {
    let (ws, resp) = connect_async(format!("{}/v1/robots/{robot}/fk/stream", app.ws))
        .await
        .expect("websocket opens");
    assert_eq!(resp.status(), 101);
    ws
}

async fn send(ws: &mut Ws, text: &str) {
    ws.send(Message::Text(text.into())).await.expect("send");
}

/// The next data message (text, parsed); fails on anything else but pongs.
async fn next_reply(ws: &mut Ws) -> Value {
    loop {
        match ws.next().await.expect("stream open").expect("no error") {
            Message::Text(t) => return serde_json::from_str(t.as_str()).expect("reply is JSON"),
            Message::Pong(_) => continue,
            other => panic!("unexpected message {other:?}"),
        }
    }
}

/// Asserts `reply` is an error reply for `id` with `status`; returns the problem.
fn error_of(reply: &Value, id: &Value, status: u16) -> Value {
    assert_eq!(&reply["id"], id, "id echoed in {reply}");
    assert!(
        reply.get("pose").is_none(),
        "no pose in an error reply: {reply}"
    );
    let p = reply["error"].clone();
    check_problem(&p, status);
    p
}

#[tokio::test]
async fn each_message_gets_one_reply_in_order_and_a_bad_message_does_not_end_the_stream() {
    let app = spawn_app().await;
    let mut ws = open(&app, "scara_4dof").await;
    // Any JSON value is a valid id.
    let ids = [
        json!(1),
        json!("two"),
        json!({"k": [3]}),
        json!(null),
        json!(5.5),
        json!([6]),
        json!(true),
        json!(8),
        json!("nine"),
    ];
    let msgs = [
        json!({"id": ids[0], "joints": [0, 0, 0.1, 0]}).to_string(),
        // Not JSON: id unknown, so null.
        "{this is not json".to_string(),
        // Wrong joint count.
        json!({"id": ids[2], "joints": [0, 0]}).to_string(),
        // Quill over its limit.
        json!({"id": ids[3], "joints": [0, 0, 0.5, 0]}).to_string(),
        // Wrong type.
        json!({"id": ids[4], "joints": ["a", 0, 0, 0]}).to_string(),
        // Unknown field.
        json!({"id": ids[5], "joints": [0, 0, 0, 0], "extra": 1}).to_string(),
        // Good again, with options.
        json!({"id": ids[6], "joints": [30, -60, 0.2, 45], "angle_unit": "deg", "frames": true})
            .to_string(),
        json!({"id": ids[7], "joints": [0, 0, 0.5, 0], "check_limits": false}).to_string(),
        json!({"id": ids[8], "joints": [0.1, 0.2, 0.05, 0.3]}).to_string(),
    ];
    // Pipelined: all sent before any reply is read.
    for m in &msgs {
        send(&mut ws, m).await;
    }
    let mut replies = Vec::new();
    for _ in &msgs {
        replies.push(next_reply(&mut ws).await);
    }

    assert_eq!(replies[0]["id"], ids[0]);
    assert!(replies[0].get("error").is_none() && replies[0].get("frames").is_none());
    assert_close(
        position(&replies[0]["pose"])[2],
        0.4 - 0.1 - 0.05,
        CLOSED_FORM_TOL,
        "z",
    );

    let p = error_of(&replies[1], &Value::Null, 400);
    assert_eq!(p["type"], "urn:kinserve:problem:malformed-request");
    let p = error_of(&replies[2], &ids[2], 422);
    assert_eq!(fields(&p), ["joints"]);
    let p = error_of(&replies[3], &ids[3], 422);
    assert_eq!(fields(&p), ["joints[2]"]);
    let p = error_of(&replies[4], &ids[4], 400);
    assert_eq!(fields(&p), ["joints[0]"]);
    let p = error_of(&replies[5], &ids[5], 400);
    assert_eq!(fields(&p), ["extra"]);

    assert_eq!(replies[6]["id"], ids[6]);
    assert_eq!(replies[6]["frames"].as_array().expect("frames").len(), 5);
    let rest = app
        .post(
            "/v1/robots/scara_4dof/fk",
            &json!({"joints": [30, -60, 0.2, 45], "angle_unit": "deg", "frames": true}),
        )
        .await
        .json::<Value>()
        .await
        .unwrap();
    assert_pose_eq(
        &replies[6]["pose"],
        &rest["pose"],
        SAME_LIB_TOL,
        "ws vs rest",
    );
    for (i, f) in rest["frames"].as_array().unwrap().iter().enumerate() {
        assert_pose_eq(
            &replies[6]["frames"][i],
            f,
            SAME_LIB_TOL,
            &format!("frame {i}"),
        );
    }
    assert_eq!(replies[7]["id"], ids[7]);
    assert_close(
        position(&replies[7]["pose"])[2],
        0.4 - 0.5 - 0.05,
        CLOSED_FORM_TOL,
        "z",
    );
    assert_eq!(replies[8]["id"], ids[8]);
    assert!(replies[8]["pose"].is_object());

    // A binary message is refused with an error reply; the stream goes on.
    ws.send(Message::Binary(vec![1, 2, 3].into()))
        .await
        .unwrap();
    let p = error_of(&next_reply(&mut ws).await, &Value::Null, 415);
    assert_eq!(p["type"], "urn:kinserve:problem:unsupported-media-type");
    send(
        &mut ws,
        &json!({"id": "last", "joints": [0, 0, 0, 0]}).to_string(),
    )
    .await;
    assert_eq!(next_reply(&mut ws).await["id"], "last");
    ws.close(None).await.unwrap();
}

#[tokio::test]
async fn ws_poses_equal_rest_poses() {
    let app = spawn_app().await;
    let mut ws = open(&app, "puma560").await;
    let qs = [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.3, -0.7, 1.1, -0.4, 0.9, 2.0],
        [-1.2, 0.5, -0.8, 1.4, -1.0, -2.5],
    ];
    for (i, q) in qs.iter().enumerate() {
        send(&mut ws, &json!({"id": i, "joints": q}).to_string()).await;
        let reply = next_reply(&mut ws).await;
        assert_eq!(reply["id"], i);
        let rest: Value = app
            .post("/v1/robots/puma560/fk", &json!({"joints": q}))
            .await
            .json()
            .await
            .unwrap();
        assert_pose_eq(&reply["pose"], &rest["pose"], SAME_LIB_TOL, "puma560");
    }
}

#[tokio::test]
async fn pings_are_answered() {
    let app = spawn_app().await;
    let mut ws = open(&app, "planar_2dof").await;
    ws.send(Message::Ping(b"are you there".to_vec().into()))
        .await
        .unwrap();
    // The pong arrives (before the reply to the message sent after the ping).
    send(&mut ws, &json!({"id": 1, "joints": [0, 0]}).to_string()).await;
    let mut pong = None;
    loop {
        match ws.next().await.expect("open").expect("ok") {
            Message::Pong(p) => pong = Some(p),
            Message::Text(t) => {
                let reply: Value = serde_json::from_str(t.as_str()).unwrap();
                assert_eq!(reply["id"], 1);
                break;
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(pong.expect("pong").as_ref(), b"are you there");
}

#[tokio::test]
async fn unknown_robot_is_404_before_the_upgrade() {
    let app = spawn_app().await;
    let err = connect_async(format!("{}/v1/robots/no_such_robot/fk/stream", app.ws))
        .await
        .expect_err("no upgrade");
    match err {
        tokio_tungstenite::tungstenite::Error::Http(resp) => {
            assert_eq!(resp.status(), 404);
            let body: Value = serde_json::from_slice(resp.body().as_deref().unwrap()).unwrap();
            check_problem(&body, 404);
            assert_eq!(body["type"], "urn:kinserve:problem:not-found");
        }
        other => panic!("expected an HTTP 404, got {other:?}"),
    }
}

/// A plain GET (no handshake) gets a problem, and 404 still wins for an unknown robot.
#[tokio::test]
async fn a_get_without_a_handshake_is_a_400_problem() {
    let app = spawn_app().await;
    let r = app.get("/v1/robots/planar_2dof/fk/stream").await;
    let p = crate::helpers::problem(r, 400).await;
    assert_eq!(p["type"], "urn:kinserve:problem:malformed-request");
    let r = app.get("/v1/robots/no_such_robot/fk/stream").await;
    crate::helpers::problem(r, 404).await;
}

#[tokio::test]
async fn a_top_level_array_message_is_a_wrong_type() {
    let app = spawn_app().await;
    let mut ws = open(&app, "planar_2dof").await;
    send(&mut ws, "[7, [0.5, 0]]").await;
    let reply = next_reply(&mut ws).await;
    assert!(reply.get("pose").is_none(), "{reply}");
    check_problem(&reply["error"], 400);
    send(&mut ws, &json!({"id": 8, "joints": [0, 0]}).to_string()).await;
    assert_eq!(next_reply(&mut ws).await["id"], 8);
}

#[tokio::test]
async fn a_robot_deleted_mid_stream_gives_error_replies_and_the_stream_goes_on() {
    let app = spawn_app().await;
    assert_eq!(
        app.post("/v1/robots", &planar_model("temp")).await.status(),
        201
    );
    let mut ws = open(&app, "temp").await;
    send(&mut ws, &json!({"id": 1, "joints": [0, 0]}).to_string()).await;
    assert!(next_reply(&mut ws).await["pose"].is_object());
    let r = app
        .client
        .delete(format!("{}/v1/robots/temp", app.http))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204);
    send(&mut ws, &json!({"id": 2, "joints": [0, 0]}).to_string()).await;
    let p = error_of(&next_reply(&mut ws).await, &json!(2), 404);
    assert_eq!(p["type"], "urn:kinserve:problem:not-found");
    // Re-registered: served again on the same stream.
    assert_eq!(
        app.post("/v1/robots", &planar_model("temp")).await.status(),
        201
    );
    send(&mut ws, &json!({"id": 3, "joints": [0, 0]}).to_string()).await;
    let reply = next_reply(&mut ws).await;
    assert_eq!(reply["id"], 3);
    assert_close(position(&reply["pose"])[0], 0.8, CLOSED_FORM_TOL, "x");
}

#[tokio::test]
async fn the_stream_is_open_with_a_token_configured() {
    let app = spawn_app_with(|c| c.api_token = Some("tok".into())).await;
    let mut ws = open(&app, "planar_2dof").await;
    send(&mut ws, &json!({"id": "a", "joints": [0, 0]}).to_string()).await;
    assert!(next_reply(&mut ws).await["pose"].is_object());
}

/// Shutdown sends every stream a close frame 1001 (going away).
#[tokio::test]
async fn shutdown_closes_streams_with_a_close_frame() {
    let app = spawn_app().await;
    let mut ws = open(&app, "planar_2dof").await;
    let mut ws2 = open(&app, "puma560").await;
    // The stream is live before shutdown.
    send(&mut ws, &json!({"id": 0, "joints": [0, 0]}).to_string()).await;
    assert!(next_reply(&mut ws).await["pose"].is_object());

    let stopping = tokio::spawn(app.stop());
    for ws in [&mut ws, &mut ws2] {
        let frame = loop {
            match ws.next().await.expect("a close frame before the end") {
                Ok(Message::Close(f)) => break f.expect("close frame has a code"),
                Ok(Message::Pong(_)) => continue,
                other => panic!("expected a close frame, got {other:?}"),
            }
        };
        assert_eq!(frame.code, CloseCode::Away, "1001 going away");
        assert!(frame.reason.contains("shutting down"), "{}", frame.reason);
    }
    stopping.await.unwrap().unwrap();
}

/// A stream with no message for `stream_idle_timeout` is closed with 1001.
#[tokio::test]
async fn an_idle_stream_is_closed_with_1001() {
    let app =
        spawn_app_with(|c| c.stream_idle_timeout = std::time::Duration::from_millis(200)).await;
    let mut ws = open(&app, "planar_2dof").await;
    send(&mut ws, &json!({"id": 1, "joints": [0, 0]}).to_string()).await;
    assert_eq!(next_reply(&mut ws).await["id"], 1);
    match ws.next().await.expect("a close frame").expect("ok") {
        Message::Close(Some(f)) => {
            assert_eq!(f.code, CloseCode::Away);
            assert!(f.reason.contains("idle"), "{}", f.reason);
        }
        other => panic!("expected a close frame, got {other:?}"),
    }
}

/// The stream route takes `CONNECT` (WebSockets over HTTP/2, RFC 8441), but
/// `Allow` advertises only what the OpenAPI document describes.
#[tokio::test]
async fn allow_on_the_stream_route_lists_get_and_head_only() {
    let app = spawn_app().await;
    let url = format!("{}/v1/robots/puma560/fk/stream", app.http);
    for method in [reqwest::Method::OPTIONS, reqwest::Method::POST] {
        let r = app
            .client
            .request(method.clone(), &url)
            .send()
            .await
            .unwrap();
        let allow = r.headers()["allow"].to_str().unwrap().to_string();
        assert_eq!(allow, "GET,HEAD", "{method}");
    }
}

/// A client's close frame is answered with a close frame carrying its code
/// (RFC 6455 §5.5.1), so the client sees a clean close, not 1006.
#[tokio::test]
async fn a_clients_close_is_answered_with_its_code() {
    let app = spawn_app().await;
    let mut ws = open(&app, "planar_2dof").await;
    send(&mut ws, &json!({"id": 1, "joints": [0, 0]}).to_string()).await;
    assert_eq!(next_reply(&mut ws).await["id"], 1);
    ws.send(Message::Close(Some(
        tokio_tungstenite::tungstenite::protocol::CloseFrame {
            code: CloseCode::Normal,
            reason: "done".into(),
        },
    )))
    .await
    .unwrap();
    let reply = tokio::time::timeout(std::time::Duration::from_secs(5), async {
        loop {
            match ws.next().await {
                Some(Ok(Message::Close(f))) => return f,
                Some(Ok(_)) => continue,
                other => panic!("expected the server's close frame, got {other:?}"),
            }
        }
    })
    .await
    .expect("the server answers the close");
    assert_eq!(reply.map(|f| f.code), Some(CloseCode::Normal));
}

/// A message with `configurations` (FK of many, as the gRPC stream's
/// `configurations`) is answered in the field `POST …/fk/batch` uses, with
/// the batch route's numbers; it is refused beside `joints`, `ik`, the
/// Jacobian, frames or an operation on one configuration (naming the field),
/// over the batch limit (413), and the stream goes on after each.
#[tokio::test]
async fn many_configurations_in_one_message_equal_the_rest_batch() {
    let app = spawn_app_with(|c| c.max_batch = 4).await;
    let mut ws = open(&app, "puma560").await;
    // Degrees, a zero configuration and a −0.0 among them.
    let qs = json!([
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [10.0, -40.0, 60.0, -0.0, 30.0, 120.0],
        [-70.0, 20.0, -45.0, 80.0, -60.0, -150.0]
    ]);
    for (i, format) in ["full", "matrix", "position"].iter().enumerate() {
        let msg =
            json!({"id": i, "configurations": qs, "angle_unit": "deg", "pose_format": format});
        send(&mut ws, &msg.to_string()).await;
        let reply = next_reply(&mut ws).await;
        let rest: Value = app
            .post(
                "/v1/robots/puma560/fk/batch",
                &json!({"configurations": qs, "angle_unit": "deg", "pose_format": format}),
            )
            .await
            .json()
            .await
            .unwrap();
        let field = ["poses", "matrices", "positions"][i];
        assert_eq!(reply["id"], i);
        assert_eq!(reply["length_unit"], "m");
        // Same numbers, bit for bit (both print f64 the same way).
        assert_eq!(reply[field], rest[field], "{format}: {reply}");
        assert_eq!(reply[field].as_array().map(Vec::len), Some(3));
        for other in [
            "pose",
            "matrix",
            "position",
            "poses",
            "matrices",
            "positions",
        ] {
            assert!(
                other == field || reply.get(other).is_none(),
                "{other} in {reply}"
            );
        }
    }
    let refused = [
        (
            json!({"configurations": qs, "joints": [0, 0, 0, 0, 0, 0]}),
            422,
            "configurations",
        ),
        (
            json!({"configurations": qs, "jacobian": true}),
            422,
            "jacobian",
        ),
        (
            json!({"configurations": qs, "link_transforms": true}),
            422,
            "link_transforms",
        ),
        (json!({"configurations": qs, "frames": true}), 400, "frames"),
        (
            json!({"configurations": [[0, 0, 0, 0, 0, 0], [0, 0, 9, 0, 0, 0]]}),
            422,
            "configurations[1][2]",
        ),
    ];
    for (k, (msg, status, field)) in refused.iter().enumerate() {
        let mut msg = msg.clone();
        msg["id"] = json!(format!("bad{k}"));
        send(&mut ws, &msg.to_string()).await;
        let p = error_of(&next_reply(&mut ws).await, &msg["id"], *status);
        assert_eq!(fields(&p), [*field], "{msg}: {p}");
    }
    // Over the limit (4): refused, 4 answered.
    let five = json!({"id": "five", "configurations": vec![[0.0; 6]; 5]});
    send(&mut ws, &five.to_string()).await;
    let p = error_of(&next_reply(&mut ws).await, &json!("five"), 413);
    assert!(p["detail"].as_str().unwrap().contains("at most 4"), "{p}");
    let four =
        json!({"id": "four", "configurations": vec![[0.0; 6]; 4], "pose_format": "position"});
    send(&mut ws, &four.to_string()).await;
    assert_eq!(
        next_reply(&mut ws).await["positions"]
            .as_array()
            .map(Vec::len),
        Some(4)
    );
    // A single-configuration message after them.
    send(
        &mut ws,
        &json!({"id": "one", "joints": [0, 0, 0, 0, 0, 0]}).to_string(),
    )
    .await;
    assert!(next_reply(&mut ws).await["pose"].is_object());
}
