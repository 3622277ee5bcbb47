//! The plumbing of `StreamForwardKinematics`: which connection a call came
//! on (for the per-connection stream budget, and to close it).
//!
//! Why a connection may have to be closed: once the HTTP/2 layer (hyper)
//! holds a reply for a stream whose client keeps its receive window closed,
//! it waits for window and polls nothing else of that stream, so nothing the
//! application does can end (reset) that one stream. A stream closed for
//! idleness while blocked that way has [`STUCK_GRACE`] to go; if its
//! response is still not done then, its connection is closed, which ends
//! every stream on it and frees what they hold.
//!
//! With TLS, each accepted connection's handshake runs in its own task
//! (holding its connection slot, bounded by the header timeout) and the
//! server is handed the connections whose handshake succeeded.

use std::future::Future as _;
use std::pin::Pin;
use std::task::{Context, Poll};

use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;

use crate::tls::{ClientCert, MaybeTls};

use tokio::sync::{OwnedSemaphorePermit, mpsc};
use tokio_stream::Stream;
use tokio_util::sync::{CancellationToken, WaitForCancellationFutureOwned};
use tonic::transport::server::Connected;

use crate::api::budget::{ConnectionSlots, ConnectionStreams, accept_error};

/// The accepted connections of `listener`, each holding a slot of
/// `connections`: an accepted connection is handed on once a slot is free,
/// and until then nothing more is accepted (new clients wait in the kernel's
/// backlog). Accepting first means an idle listener holds no slot. Accept
/// errors are skipped or retried, never handed to the server (which would stop).
pub fn incoming(
    listener: tokio::net::TcpListener,
    connections: ConnectionSlots,
    tls: Option<crate::tls::Listener>,
) -> impl Stream<Item = std::io::Result<GrpcConn>> {
    use futures_util::future::Either;
    match tls {
        None => Either::Left(plain(listener, connections)),
        Some(tls) => Either::Right(handshaken(listener, connections, tls)),
    }
}

fn plain(
    listener: tokio::net::TcpListener,
    connections: ConnectionSlots,
) -> impl Stream<Item = std::io::Result<GrpcConn>> {
    futures_util::stream::unfold(
        (listener, connections),
        |(listener, connections)| async move {
            loop {
                match listener.accept().await {
                    Ok((tcp, _peer)) => {
                        let slot = connections.wait().await?;
                        let _ = tcp.set_nodelay(true);
                        let conn = GrpcConn::new(MaybeTls::Plain(tcp), slot);
                        return Some((Ok(conn), (listener, connections)));
                    }
                    Err(e) => accept_error(e).await,
                }
            }
        },
    )
}

/// Connections handed on at once while the server has not taken them yet.
const HANDSHAKEN_QUEUE: usize = 16;

/// The TLS connections of `listener`: one task accepts (slots as in
/// [`incoming`]), each connection's handshake runs in its own task, and those
/// that finish are handed on. The accepting task ends (closing the listener)
/// once the server drops the stream.
fn handshaken(
    listener: tokio::net::TcpListener,
    connections: ConnectionSlots,
    tls: crate::tls::Listener,
) -> impl Stream<Item = std::io::Result<GrpcConn>> {
    use tokio_stream::StreamExt as _;
    let (tx, rx) = mpsc::channel::<GrpcConn>(HANDSHAKEN_QUEUE);
    tokio::spawn(async move {
        loop {
            let tcp = tokio::select! {
                _ = tx.closed() => return,
                r = listener.accept() => match r {
                    Ok((tcp, _)) => tcp,
                    Err(e) => {
                        accept_error(e).await;
                        continue;
                    }
                },
            };
            let slot = tokio::select! {
                _ = tx.closed() => return,
                slot = connections.wait() => match slot {
                    Some(slot) => slot,
                    None => return,
                },
            };
            let (tx, tls) = (tx.clone(), tls.clone());
            tokio::spawn(async move {
                let _ = tcp.set_nodelay(true);
                if let Ok(io) = crate::tls::server::accept(Some(&tls), tcp).await {
                    let _ = tx.send(GrpcConn::new(io, slot)).await;
                }
            });
        }
    });
    tokio_stream::wrappers::ReceiverStream::new(rx).map(Ok)
}

/// How long a stream closed for idleness while its client did not read may
/// take to finish before its connection is closed.
pub const STUCK_GRACE: Duration = Duration::from_secs(1);

/// What handlers learn about the connection of a call (request extensions).
#[derive(Clone, Debug, Default)]
pub struct GrpcConnInfo {
    /// The streams open on it.
    pub streams: ConnectionStreams,
    /// Cancelling it closes the connection.
    pub close: CancellationToken,
    /// The peer's address (for the per-client shares).
    pub peer: Option<std::net::IpAddr>,
    /// The verified client certificate (TLS with client certificates).
    pub client_cert: Option<ClientCert>,
}

/// An accepted gRPC connection: the TCP stream, the streams open on it, and
/// a token that closes it (reads and writes fail once it is cancelled).
pub struct GrpcConn {
    tcp: MaybeTls<TcpStream>,
    info: GrpcConnInfo,
    closed: Pin<Box<WaitForCancellationFutureOwned>>,
    /// Its slot of `--max-connections`, freed when the connection is dropped.
    _slot: OwnedSemaphorePermit,
}

impl GrpcConn {
    /// A newly accepted connection (TLS handshake done, if any) holding `slot`.
    pub fn new(tcp: MaybeTls<TcpStream>, slot: OwnedSemaphorePermit) -> GrpcConn {
        let info = GrpcConnInfo {
            peer: tcp.get_ref().peer_addr().ok().map(|a| a.ip()),
            client_cert: tcp.client_cert(),
            ..GrpcConnInfo::default()
        };
        let closed = Box::pin(info.close.clone().cancelled_owned());
        GrpcConn {
            tcp,
            info,
            closed,
            _slot: slot,
        }
    }

    /// `Err` once the connection is to be closed.
    fn check(&mut self, cx: &mut Context<'_>) -> std::io::Result<()> {
        match self.closed.as_mut().poll(cx) {
            Poll::Ready(()) => Err(std::io::Error::new(
                std::io::ErrorKind::ConnectionAborted,
                "closed: a stream on it stayed blocked on the client's receive window",
            )),
            Poll::Pending => Ok(()),
        }
    }
}

impl Connected for GrpcConn {
    type ConnectInfo = GrpcConnInfo;
    fn connect_info(&self) -> GrpcConnInfo {
        self.info.clone()
    }
}

impl AsyncRead for GrpcConn {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        let this = self.get_mut();
        this.check(cx)?;
        Pin::new(&mut this.tcp).poll_read(cx, buf)
    }
}

impl AsyncWrite for GrpcConn {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        let this = self.get_mut();
        this.check(cx)?;
        Pin::new(&mut this.tcp).poll_write(cx, buf)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        Pin::new(&mut self.get_mut().tcp).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.tcp.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.get_mut().tcp).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.get_mut().tcp).poll_shutdown(cx)
    }
}
