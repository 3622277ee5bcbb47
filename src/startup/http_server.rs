//! The REST listener's accept loop and connections (HTTP/1.1 and h2c, with
//! WebSocket upgrades), with the time limits `axum::serve` does not have:
//!
//! - **Header timeout**, on every request of every connection. HTTP/1: hyper's
//!   header read timeout, which runs for each request head, the first one and
//!   every kept-alive one. HTTP/2 sends a request head as one HEADERS frame
//!   (plus CONTINUATIONs that must follow it at once, nothing else in between),
//!   so a stalled head stalls the whole connection; there "header timeout"
//!   means: a connection with no request and no answer under way for the
//!   header timeout (none yet, or none since the last one ended) is closed,
//!   gracefully (GOAWAY), then for good a second later. The same idle rule
//!   covers connections that never finish a first request head, whatever the
//!   protocol.
//! - **Write timeout**: a connection whose writes make no progress for the
//!   write timeout (the client reads nothing) fails its writes and closes
//!   ([`Lingering`]); and one whose counted answers are not taken for that
//!   long (HTTP/2 flow control stops a stream without blocking any write) is
//!   dropped (see `api::rest::conn`).
//! - **Lingering close**, bounded by time (see [`Lingering`]).
//! - **TLS** (with `--tls-cert`): the handshake runs in the connection's task,
//!   holding its connection slot, and must finish within the header timeout;
//!   then the request heads have their own header timeout as above. ALPN
//!   offers `h2` and `http/1.1`; either way the connection is served as
//!   before (WebSockets over both). The client certificate's subject, if
//!   any, is known to each request (`crate::tls::peer`).

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use axum::Router;
use hyper::body::Incoming;
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use hyper_util::server::conn::auto;
use hyper_util::service::TowerToHyperService;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;
use tower::ServiceExt;

use crate::api::rest::ConnActivity;

/// Time limits of the REST listener's connections.
#[derive(Clone, Copy, Debug)]
pub struct HttpServerSettings {
    /// Longest time to send a request head (see the module docs).
    pub header_timeout: Duration,
    /// Longest time without write progress.
    pub write_timeout: Duration,
    /// Longest lingering close.
    pub linger_timeout: Duration,
}

/// Longest pause between two reads of a lingering close (nginx's `lingering_timeout`).
const LINGER_IDLE: Duration = Duration::from_secs(5);

/// How long an idle connection told to close (GOAWAY) may take to do so.
const IDLE_CLOSE_GRACE: Duration = Duration::from_secs(1);

/// Serves `router` on `listener` until `stop` is cancelled, then waits for the
/// open connections to finish (each is told to close gracefully).
pub async fn serve_http(
    listener: TcpListener,
    router: Router,
    settings: HttpServerSettings,
    connections: crate::api::budget::ConnectionSlots,
    tls: Option<crate::tls::Listener>,
    stop: CancellationToken,
) -> std::io::Result<()> {
    let settings = HttpServerSettings {
        header_timeout: settings.header_timeout.max(Duration::from_millis(1)),
        write_timeout: settings.write_timeout.max(Duration::from_millis(1)),
        linger_timeout: settings.linger_timeout,
    };
    let builder = Arc::new(builder(settings.header_timeout));
    // Every connection task holds a sender: `recv` answers `None` once all are gone.
    let (open, mut all_closed) = mpsc::channel::<()>(1);
    loop {
        let (tcp, peer) = tokio::select! {
            _ = stop.cancelled() => break,
            r = listener.accept() => match r {
                Ok(conn) => conn,
                Err(e) => {
                    crate::api::budget::accept_error(e).await;
                    continue;
                }
            },
        };
        // Served once a connection slot is free; until then nothing more is
        // accepted (new clients wait in the backlog). Accepting first means an
        // idle listener holds no slot.
        let slot = tokio::select! {
            _ = stop.cancelled() => break,
            slot = connections.wait() => match slot {
                Some(slot) => slot,
                None => break,
            },
        };
        let _ = tcp.set_nodelay(true);
        let conn = Conn {
            router: router.clone(),
            builder: builder.clone(),
            settings,
            stop: stop.clone(),
            _open: open.clone(),
            _slot: slot,
            peer: crate::api::rest::PeerAddr(peer),
            tls: tls.clone(),
        };
        tokio::spawn(conn.serve(tcp));
    }
    drop(listener);
    drop(open);
    let _ = all_closed.recv().await;
    Ok(())
}

fn builder(header_timeout: Duration) -> auto::Builder<TokioExecutor> {
    let mut builder = auto::Builder::new(TokioExecutor::new());
    builder
        .http1()
        .timer(TokioTimer::new())
        .header_read_timeout(header_timeout);
    // CONNECT protocol for WebSockets over HTTP/2; pings so dead h2 peers are noticed.
    builder
        .http2()
        .timer(TokioTimer::new())
        .enable_connect_protocol()
        .keep_alive_interval(Duration::from_secs(30));
    builder
}

/// One accepted connection and what it needs.
struct Conn {
    router: Router,
    builder: Arc<auto::Builder<TokioExecutor>>,
    settings: HttpServerSettings,
    stop: CancellationToken,
    _open: mpsc::Sender<()>,
    /// The connection's slot of `--max-connections`, freed when it ends.
    _slot: tokio::sync::OwnedSemaphorePermit,
    /// Who is on the other end (for the per-client shares).
    peer: crate::api::rest::PeerAddr,
    /// The listener's TLS, if it serves TLS.
    tls: Option<crate::tls::Listener>,
}

impl Conn {
    async fn serve(self, tcp: TcpStream) {
        let io = tokio::select! {
            io = crate::tls::server::accept(self.tls.as_ref(), tcp) => match io {
                Ok(io) => io,
                Err(_) => return,
            },
            _ = self.stop.cancelled() => return,
        };
        let client_cert = io.client_cert();
        let activity = ConnActivity::new();
        let router = self.router.clone();
        let seen = activity.clone();
        // The connection's open streams (WebSockets), for the per-connection budget.
        let streams = crate::api::budget::ConnectionStreams::default();
        let peer = self.peer;
        let service = tower::service_fn(move |mut req: hyper::Request<Incoming>| {
            let busy = seen.enter();
            req.extensions_mut().insert(peer);
            req.extensions_mut().insert(seen.clone());
            req.extensions_mut().insert(streams.clone());
            let router = router.clone();
            let cert = client_cert.clone();
            crate::tls::peer::scope(cert, async move {
                let resp = router
                    .oneshot(req)
                    .await
                    .map(crate::api::rest::hide_connect);
                drop(busy);
                resp
            })
        });
        let io = Lingering::new(io, self.settings);
        let conn = self
            .builder
            .serve_connection_with_upgrades(TokioIo::new(io), TowerToHyperService::new(service));
        let mut conn = std::pin::pin!(conn);
        let idle = tokio::select! {
            _ = conn.as_mut() => return,
            _ = self.stop.cancelled() => false,
            _ = activity.idle_for(self.settings.header_timeout) => true,
            _ = activity.write_stalled(self.settings.write_timeout) => {
                tracing::debug!("closing a connection whose client takes none of its answers");
                return;
            }
        };
        conn.as_mut().graceful_shutdown();
        if idle {
            tracing::debug!("closing a connection with no request under way");
            let _ = tokio::time::timeout(IDLE_CLOSE_GRACE, conn).await;
        } else {
            tokio::select! {
                _ = conn => {}
                _ = activity.write_stalled(self.settings.write_timeout) => {}
            }
        }
    }
}

/// A server-side TCP connection with a write timeout and a lingering close.
///
/// **Write timeout.** A write that cannot proceed (the socket buffer is full:
/// the client reads nothing) for the write timeout fails with `TimedOut`, and
/// the connection closes; any progress restarts the clock.
///
/// **Lingering close.** When the server answers before reading the whole
/// request body (a request refused with 503, 413 or 401) and then closes, the
/// kernel answers the unread bytes with a reset, which can destroy the answer
/// before the client has read it: the client sees "connection reset" or
/// "broken pipe", not the status. So once a connection that sent something is
/// dropped, its write side is shut down (FIN after the complete answer) and
/// what the client still sends is read and discarded, for at most the linger
/// timeout and at most [`LINGER_IDLE`] between two reads (nginx's
/// `lingering_time` and `lingering_timeout`), whatever the byte count.
/// Connections that never sent anything (e.g. closed for a header timeout)
/// and those that timed out writing close at once.
pub struct Lingering<IO: Io = TcpStream> {
    tcp: Option<IO>,
    wrote: bool,
    timed_out: bool,
    write_timeout: Duration,
    linger_timeout: Duration,
    stall: Pin<Box<tokio::time::Sleep>>,
    stalling: bool,
}

fn closed() -> std::io::Error {
    std::io::Error::from(std::io::ErrorKind::NotConnected)
}

/// What a [`Lingering`] connection runs over: TCP, or TLS over TCP.
pub trait Io: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin + Send + 'static {}

impl<T: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin + Send + 'static> Io for T {}

impl<IO: Io> Lingering<IO> {
    fn new(tcp: IO, settings: HttpServerSettings) -> Lingering<IO> {
        Lingering {
            tcp: Some(tcp),
            wrote: false,
            timed_out: false,
            write_timeout: settings.write_timeout,
            linger_timeout: settings.linger_timeout,
            stall: Box::pin(tokio::time::sleep(settings.write_timeout)),
            stalling: false,
        }
    }

    /// Runs one write; a write that stays pending for the write timeout fails.
    fn write_with<T>(
        &mut self,
        cx: &mut Context<'_>,
        write: impl FnOnce(Pin<&mut IO>, &mut Context<'_>) -> Poll<std::io::Result<T>>,
    ) -> Poll<std::io::Result<T>> {
        self.wrote = true;
        let Some(tcp) = self.tcp.as_mut() else {
            return Poll::Ready(Err(closed()));
        };
        if let Poll::Ready(r) = write(Pin::new(tcp), cx) {
            self.stalling = false;
            return Poll::Ready(r);
        }
        if !self.stalling {
            self.stalling = true;
            let deadline = tokio::time::Instant::now() + self.write_timeout;
            self.stall.as_mut().reset(deadline);
        }
        match self.stall.as_mut().poll(cx) {
            Poll::Ready(()) => {
                self.timed_out = true;
                Poll::Ready(Err(std::io::Error::new(
                    std::io::ErrorKind::TimedOut,
                    "write timeout: the client took none of the answer",
                )))
            }
            Poll::Pending => Poll::Pending,
        }
    }
}

impl<IO: Io> tokio::io::AsyncRead for Lingering<IO> {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut tokio::io::ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        match self.get_mut().tcp.as_mut() {
            Some(tcp) => Pin::new(tcp).poll_read(cx, buf),
            None => Poll::Ready(Err(closed())),
        }
    }
}

impl<IO: Io> tokio::io::AsyncWrite for Lingering<IO> {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        self.get_mut()
            .write_with(cx, |tcp, cx| tcp.poll_write(cx, buf))
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        self.get_mut()
            .write_with(cx, |tcp, cx| tcp.poll_write_vectored(cx, bufs))
    }

    fn is_write_vectored(&self) -> bool {
        self.tcp.as_ref().is_some_and(|t| t.is_write_vectored())
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        match self.get_mut().tcp.as_mut() {
            Some(tcp) => Pin::new(tcp).poll_flush(cx),
            None => Poll::Ready(Ok(())),
        }
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        match self.get_mut().tcp.as_mut() {
            Some(tcp) => Pin::new(tcp).poll_shutdown(cx),
            None => Poll::Ready(Ok(())),
        }
    }
}

impl<IO: Io> Drop for Lingering<IO> {
    fn drop(&mut self) {
        let Some(tcp) = self.tcp.take() else {
            return;
        };
        if !self.wrote || self.timed_out || self.linger_timeout.is_zero() {
            return;
        }
        let Ok(runtime) = tokio::runtime::Handle::try_current() else {
            return;
        };
        runtime.spawn(linger(tcp, self.linger_timeout));
    }
}

/// Shuts the write side of `tcp` and discards what the client still sends,
/// for at most `limit` in all and [`LINGER_IDLE`] between two reads.
async fn linger<IO: Io>(mut tcp: IO, limit: Duration) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let _ = tcp.shutdown().await;
    let mut buf = vec![0u8; 16 << 10];
    let _ = tokio::time::timeout(limit, async {
        while let Ok(Ok(n)) = tokio::time::timeout(LINGER_IDLE, tcp.read(&mut buf)).await {
            if n == 0 {
                break;
            }
        }
    })
    .await;
}
