//! The plumbing of `StreamForwardKinematics`: which connection a call came
//! on (for the per-connection stream budget), and the outbound half of a
//! stream, which can end with a status even while the client does not read.

use std::future::Future as _;
use std::pin::Pin;
use std::task::{Context, Poll};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tokio::sync::{mpsc, oneshot};
use tokio_stream::Stream;
use tonic::Status;
use tonic::transport::server::Connected;

use crate::api::budget::ConnectionStreams;

/// Replies of one stream queued for the client, beyond the one its task is
/// holding: a client that does not read holds this little.
pub const REPLY_BUFFER: usize = 1;

/// An accepted gRPC connection: the TCP stream and the streams open on it
/// (found by handlers in the request extensions).
pub struct GrpcConn {
    tcp: TcpStream,
    streams: ConnectionStreams,
}

impl GrpcConn {
    /// A newly accepted connection (TCP_NODELAY set).
    pub fn new(tcp: TcpStream) -> GrpcConn {
        let _ = tcp.set_nodelay(true);
        GrpcConn {
            tcp,
            streams: ConnectionStreams::default(),
        }
    }
}

impl Connected for GrpcConn {
    type ConnectInfo = ConnectionStreams;
    fn connect_info(&self) -> ConnectionStreams {
        self.streams.clone()
    }
}

impl AsyncRead for GrpcConn {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.get_mut().tcp).poll_read(cx, buf)
    }
}

impl AsyncWrite for GrpcConn {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        Pin::new(&mut self.get_mut().tcp).poll_write(cx, buf)
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

/// The sending half of a stream, used by its task.
pub struct Replies<T> {
    tx: mpsc::Sender<Result<T, Status>>,
    last: Option<oneshot::Sender<Status>>,
}

/// The outbound stream tonic sends: the replies, then the final status (if
/// the task ended with one) once every queued reply went out.
pub struct Outbound<T> {
    rx: mpsc::Receiver<Result<T, Status>>,
    last: Option<oneshot::Receiver<Status>>,
}

/// A stream's two halves, with [`REPLY_BUFFER`] replies of room.
pub fn channel<T>() -> (Replies<T>, Outbound<T>) {
    let (tx, rx) = mpsc::channel(REPLY_BUFFER);
    let (last_tx, last_rx) = oneshot::channel();
    (
        Replies {
            tx,
            last: Some(last_tx),
        },
        Outbound {
            rx,
            last: Some(last_rx),
        },
    )
}

impl<T> Replies<T> {
    /// Queues a reply; waits while the queue is full (the client reads
    /// slowly). `false` once the client is gone.
    pub async fn send(&self, reply: T) -> bool {
        self.tx.send(Ok(reply)).await.is_ok()
    }

    /// Resolves when the client has gone (cancelled the call).
    pub async fn closed(&self) {
        self.tx.closed().await
    }

    /// Ends the stream with `status` after the queued replies, without
    /// waiting for the client to read them.
    pub fn end(mut self, status: Status) {
        if let Some(last) = self.last.take() {
            let _ = last.send(status);
        }
    }
}

impl<T> Stream for Outbound<T> {
    type Item = Result<T, Status>;

    fn poll_next(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        let this = self.get_mut();
        match this.rx.poll_recv(cx) {
            Poll::Ready(None) => {}
            other => return other,
        }
        // The task is done: its final status, if it left one.
        let Some(last) = this.last.as_mut() else {
            return Poll::Ready(None);
        };
        let status = std::task::ready!(Pin::new(last).poll(cx)).ok();
        this.last = None;
        Poll::Ready(status.map(Err))
    }
}
