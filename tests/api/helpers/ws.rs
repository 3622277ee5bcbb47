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
