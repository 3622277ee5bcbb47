//! WebSocket frame abuse (binary, fragmented, invalid, oversized) and a
//! client that never reads.

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::protocol::frame::Frame;
use tokio_tungstenite::tungstenite::protocol::frame::coding::{CloseCode, Data, OpCode};

use crate::helpers::*;

// ---------------------------------------------------------------- WebSocket frames

/// Waits for the server to end a WebSocket (close frame, EOF or error); returns the close code if any.
async fn closed_by_server(sock: &mut Ws) -> Option<u16> {
    let end = tokio::time::timeout(EVENTUALLY, async {
        loop {
            match sock.next().await {
                Some(Ok(Message::Close(frame))) => return frame.map(|f| u16::from(f.code)),
                Some(Ok(_)) => continue,
                Some(Err(_)) | None => return None,
            }
        }
    })
    .await;
    end.expect("the server ends the connection")
}

/// Binary and fragmented frames, invalid UTF-8, an oversized message and a
/// ping flood: each gets an error reply or a close, never a hung or dead server.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn websocket_binary_fragmented_invalid_and_oversized_frames() {
    let app = spawn_app_with(|c| c.max_body_bytes = 64 << 10).await;
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    let mut sock = open_ws(&app, "planar_2dof").await;
    let fk = br#"{"id": 7, "joints": [0, 0]}"#;

    // A binary message: 415 error reply, the stream goes on.
    sock.send(Message::Binary(fk.to_vec().into()))
        .await
        .unwrap();
    let reply = next_text(&mut sock).await.unwrap();
    assert_eq!(reply["error"]["status"], 415, "{reply}");
    // A text message in three fragments: one message, one reply.
    for (i, part) in fk.chunks(10).enumerate() {
        let op = if i == 0 {
            OpCode::Data(Data::Text)
        } else {
            OpCode::Data(Data::Continue)
        };
        let last = (i + 1) * 10 >= fk.len();
        sock.send(Message::Frame(Frame::message(part.to_vec(), op, last)))
            .await
            .unwrap();
    }
    let reply = next_text(&mut sock).await.unwrap();
    assert_eq!(reply["id"], 7, "{reply}");
    assert!(reply["pose"].is_object(), "{reply}");
    // A fragmented binary message: still 415.
    sock.send(Message::Frame(Frame::message(
        fk[..5].to_vec(),
        OpCode::Data(Data::Binary),
        false,
    )))
    .await
    .unwrap();
    sock.send(Message::Frame(Frame::message(
        fk[5..].to_vec(),
        OpCode::Data(Data::Continue),
        true,
    )))
    .await
    .unwrap();
    let reply = next_text(&mut sock).await.unwrap();
    assert_eq!(reply["error"]["status"], 415, "{reply}");
    // A ping flood is answered and does not disturb the replies.
    for i in 0..1000u32 {
        sock.send(Message::Ping(i.to_be_bytes().to_vec().into()))
            .await
            .unwrap();
    }
    sock.send(Message::Text(r#"{"id": 8, "joints": [0, 0]}"#.into()))
        .await
        .unwrap();
    let reply = next_text(&mut sock).await.unwrap();
    assert_eq!(reply["id"], 8, "{reply}");

    // Invalid UTF-8 in a text frame: the connection is closed (1007 or a plain close).
    sock.send(Message::Frame(Frame::message(
        vec![b'{', 0xff, 0xfe, b'}'],
        OpCode::Data(Data::Text),
        true,
    )))
    .await
    .unwrap();
    let code = closed_by_server(&mut sock).await;
    assert!(
        code.is_none_or(|c| c == u16::from(CloseCode::Invalid)),
        "{code:?}"
    );

    // A message over the limit (64 KiB here), whole or in fragments: closed (1009 or plain).
    let mut sock = open_ws(&app, "planar_2dof").await;
    let big = format!(r#"{{"id": "{}", "joints": [0, 0]}}"#, "x".repeat(100 << 10));
    let _ = sock.send(Message::Text(big.clone().into())).await;
    let code = closed_by_server(&mut sock).await;
    assert!(
        code.is_none_or(|c| c == u16::from(CloseCode::Size)),
        "{code:?}"
    );
    let mut sock = open_ws(&app, "planar_2dof").await;
    for (i, part) in big.as_bytes().chunks(16 << 10).enumerate() {
        let op = if i == 0 {
            OpCode::Data(Data::Text)
        } else {
            OpCode::Data(Data::Continue)
        };
        if sock
            .send(Message::Frame(Frame::message(part.to_vec(), op, false)))
            .await
            .is_err()
        {
            break;
        }
    }
    let code = closed_by_server(&mut sock).await;
    assert!(
        code.is_none_or(|c| c == u16::from(CloseCode::Size)),
        "{code:?}"
    );

    // A fresh stream works.
    let mut sock = open_ws(&app, "planar_2dof").await;
    sock.send(Message::Text(r#"{"id": 9, "joints": [0, 0]}"#.into()))
        .await
        .unwrap();
    assert_eq!(next_text(&mut sock).await.unwrap()["id"], 9);
    checker.finish().await;
}

/// A client that sends on a WebSocket and never reads is stopped by
/// backpressure (TCP flow control): the server holds at most one reply per
/// stream and does not buffer the rest, so the client's sends block long
/// before it has pushed an unbounded amount. Other clients are unaffected.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_websocket_client_that_never_reads_is_held_back_by_backpressure() {
    let app = spawn_app().await;
    let (sock, _) =
        tokio_tungstenite::connect_async(format!("{}/v1/robots/planar_2dof/fk/stream", app.ws))
            .await
            .unwrap();
    let (mut tx, rx) = sock.split();
    // 16 KiB ids: every reply echoes one.
    let msg = format!(
        r#"{{"id": "{}", "joints": [0.1, 0.2], "frames": true}}"#,
        "y".repeat(16 << 10)
    );
    const BOUND: usize = 256 << 20; // far above any socket buffers
    let mut sent = 0usize;
    let mut stalled = false;
    while sent < BOUND {
        match tokio::time::timeout(
            Duration::from_secs(2),
            tx.send(Message::Text(msg.clone().into())),
        )
        .await
        {
            Ok(Ok(())) => sent += msg.len(),
            Ok(Err(e)) => panic!("send failed after {sent} bytes: {e}"),
            Err(_) => {
                stalled = true;
                break;
            }
        }
    }
    assert!(stalled, "sent {sent} bytes without being held back");
    // The server is fine meanwhile.
    let checker = Checker::start(&app.http, &app.grpc, &app.ws).await;
    checker.finish().await;
    println!(
        "WebSocket slow reader: held back after {} KiB sent",
        sent >> 10
    );
    drop((tx, rx));
}
