//! WebSocket: opening the FK stream and reading its replies.

use futures_util::StreamExt;
use serde_json::Value;
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;

use crate::helpers::*;

pub(crate) type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<TcpStream>>;

/// The next text message of a WebSocket as JSON (None: closed or errored).
pub(crate) async fn next_text(sock: &mut Ws) -> Option<Value> {
    loop {
        match sock.next().await? {
            Ok(Message::Text(t)) => return serde_json::from_str(t.as_str()).ok(),
            Ok(Message::Ping(_) | Message::Pong(_)) => continue,
            _ => return None,
        }
    }
}

pub(crate) async fn open_ws(app: &TestApp, robot: &str) -> Ws {
    let url = format!("{}/v1/robots/{robot}/fk/stream", app.ws);
    tokio_tungstenite::connect_async(url.as_str())
        .await
        .expect("websocket opens")
        .0
}

/// Opens a WebSocket to `url` (`ws://127.0.0.1:PORT/…`) from the local
/// address `from`; `Err(status)` when the server refuses the upgrade.
pub(crate) async fn ws_connect_from(from: [u8; 4], url: &str) -> Result<Ws, u16> {
    let host = url
        .trim_start_matches("ws://")
        .split('/')
        .next()
        .expect("host:port");
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.bind(std::net::SocketAddr::from((from, 0))).unwrap();
    let tcp = socket.connect(host.parse().unwrap()).await.unwrap();
    let tcp = tokio_tungstenite::MaybeTlsStream::Plain(tcp);
    match tokio_tungstenite::client_async(url, tcp).await {
        Ok((ws, _)) => Ok(ws),
        Err(tokio_tungstenite::tungstenite::Error::Http(resp)) => Err(resp.status().as_u16()),
        Err(e) => panic!("WebSocket handshake failed: {e}"),
    }
}

/// Sends `msg` and returns the reply (within 10 s).
pub(crate) async fn ws_ask(sock: &mut Ws, msg: &Value) -> Value {
    use futures_util::SinkExt;
    sock.send(Message::Text(msg.to_string().into()))
        .await
        .unwrap();
    tokio::time::timeout(std::time::Duration::from_secs(10), next_text(sock))
        .await
        .expect("a reply within 10 s")
        .expect("a JSON reply")
}

/// Whether the server has closed `sock` (a close frame or the end of the
/// stream arrives within 1 s).
pub(crate) async fn ws_is_closed(sock: &mut Ws) -> bool {
    match tokio::time::timeout(std::time::Duration::from_secs(1), sock.next()).await {
        Ok(None) | Ok(Some(Ok(Message::Close(_)))) | Ok(Some(Err(_))) => true,
        Ok(Some(Ok(_))) | Err(_) => false,
    }
}
