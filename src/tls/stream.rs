//! An accepted connection, plain or TLS ([`MaybeTls`]), and the TLS
//! handshake that makes one, bounded in time ([`handshake`]).
//!
//! The handshake runs in the connection's own task while the connection
//! holds its slot of `--max-connections`: a flood of handshakes is bounded
//! by the connection limit like any other flood of connections, and one that
//! stalls (a client that sends half a ClientHello, or none) is dropped after
//! the timeout the listener gives (its header timeout).

use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio_rustls::TlsAcceptor;
use tokio_rustls::server::TlsStream;

use super::peer::ClientCert;

/// A server-side connection: plain, or TLS over `IO`.
pub enum MaybeTls<IO> {
    /// No TLS configured.
    Plain(IO),
    /// A finished TLS handshake.
    Tls(Box<TlsStream<IO>>),
}

impl<IO> MaybeTls<IO> {
    /// The connection underneath (TLS or not).
    pub fn get_ref(&self) -> &IO {
        match self {
            MaybeTls::Plain(io) => io,
            MaybeTls::Tls(tls) => tls.get_ref().0,
        }
    }

    /// The verified client certificate of a TLS connection, if it sent one.
    pub fn client_cert(&self) -> Option<ClientCert> {
        match self {
            MaybeTls::Plain(_) => None,
            MaybeTls::Tls(tls) => tls
                .get_ref()
                .1
                .peer_certificates()
                .and_then(|c| c.first())
                .map(ClientCert::from_der),
        }
    }

    /// The application protocol TLS negotiated (ALPN), if any.
    pub fn alpn(&self) -> Option<&[u8]> {
        match self {
            MaybeTls::Plain(_) => None,
            MaybeTls::Tls(tls) => tls.get_ref().1.alpn_protocol(),
        }
    }
}

/// Why a handshake did not give a connection.
#[derive(Debug)]
pub enum HandshakeError {
    /// Not finished within the timeout.
    TimedOut,
    /// Refused (no common version or protocol, a missing or bad client
    /// certificate, not TLS at all) or the connection failed.
    Failed(std::io::Error),
}

/// Runs the TLS handshake on `io` for at most `timeout`. Failures are
/// counted (`kinserve_tls_handshake_failures_total{listener, reason}`) and
/// logged at debug level (a flood of them must not flood the log).
pub async fn handshake<IO>(
    acceptor: TlsAcceptor,
    io: IO,
    timeout: Duration,
    listener: &'static str,
) -> Result<MaybeTls<IO>, HandshakeError>
where
    IO: AsyncRead + AsyncWrite + Unpin,
{
    let result = match tokio::time::timeout(timeout, acceptor.accept(io)).await {
        Ok(Ok(tls)) => return Ok(MaybeTls::Tls(Box::new(tls))),
        Ok(Err(e)) => HandshakeError::Failed(e),
        Err(_) => HandshakeError::TimedOut,
    };
    let reason = match &result {
        HandshakeError::TimedOut => "timeout",
        HandshakeError::Failed(_) => "failed",
    };
    metrics::counter!("kinserve_tls_handshake_failures_total", "listener" => listener, "reason" => reason)
        .increment(1);
    tracing::debug!(listener, error = ?result, "TLS handshake failed");
    Err(result)
}

impl<IO: AsyncRead + AsyncWrite + Unpin> AsyncRead for MaybeTls<IO> {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        match self.get_mut() {
            MaybeTls::Plain(io) => Pin::new(io).poll_read(cx, buf),
            MaybeTls::Tls(tls) => Pin::new(tls.as_mut()).poll_read(cx, buf),
        }
    }
}

impl<IO: AsyncRead + AsyncWrite + Unpin> AsyncWrite for MaybeTls<IO> {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        match self.get_mut() {
            MaybeTls::Plain(io) => Pin::new(io).poll_write(cx, buf),
            MaybeTls::Tls(tls) => Pin::new(tls.as_mut()).poll_write(cx, buf),
        }
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        match self.get_mut() {
            MaybeTls::Plain(io) => Pin::new(io).poll_write_vectored(cx, bufs),
            MaybeTls::Tls(tls) => Pin::new(tls.as_mut()).poll_write_vectored(cx, bufs),
        }
    }

    fn is_write_vectored(&self) -> bool {
        match self {
            MaybeTls::Plain(io) => io.is_write_vectored(),
            MaybeTls::Tls(tls) => tls.is_write_vectored(),
        }
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        match self.get_mut() {
            MaybeTls::Plain(io) => Pin::new(io).poll_flush(cx),
            MaybeTls::Tls(tls) => Pin::new(tls.as_mut()).poll_flush(cx),
        }
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        match self.get_mut() {
            MaybeTls::Plain(io) => Pin::new(io).poll_shutdown(cx),
            MaybeTls::Tls(tls) => Pin::new(tls.as_mut()).poll_shutdown(cx),
        }
    }
}
