//! gRPC over a raw HTTP/2 connection (the `h2` crate), for clients no
//! well-behaved library would be: receive windows kept closed, message
//! bodies whose end never comes.

use bytes::{BufMut, Bytes, BytesMut};
use h2::client::SendRequest;
use tokio::net::TcpStream;
use tonic::codegen::http;

use crate::helpers::*;

/// An HTTP/2 connection to `url` (`http://HOST:PORT`) whose streams start
/// with a receive window of `window` bytes (0: the server can send no DATA
/// until the client reads, which it never does here).
pub(crate) async fn h2_connect(url: &str, window: u32) -> SendRequest<Bytes> {
    let tcp = TcpStream::connect(addr_of(url)).await.expect("connects");
    let (send, conn) = h2::client::Builder::new()
        .initial_window_size(window)
        .max_concurrent_reset_streams(4096)
        .handshake(tcp)
        .await
        .expect("HTTP/2 handshake");
    tokio::spawn(async move {
        let _ = conn.await;
    });
    send
}

/// The request head of a gRPC call of `method` of the kinematics service.
pub(crate) fn grpc_head(method: &str) -> http::Request<()> {
    http::Request::builder()
        .method("POST")
        .uri(format!(
            "http://localhost/kinematics.v1.KinematicsService/{method}"
        ))
        .header("content-type", "application/grpc")
        .header("te", "trailers")
        .body(())
        .expect("valid request head")
}

/// One length-prefixed gRPC message.
pub(crate) fn grpc_frame(msg: &impl prost::Message) -> Bytes {
    let body = msg.encode_to_vec();
    let mut b = BytesMut::with_capacity(body.len() + 5);
    b.put_u8(0);
    b.put_u32(body.len() as u32);
    b.put_slice(&body);
    b.freeze()
}

/// The `grpc-status` of a response head: `Some` for a trailers-only answer
/// (every refusal), `None` when the call goes on (a stream under way).
pub(crate) fn head_status(resp: &http::Response<h2::RecvStream>) -> Option<i32> {
    resp.headers()
        .get("grpc-status")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse().ok())
}
