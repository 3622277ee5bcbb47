//! The buffered request bytes budget of the gRPC server: a tower layer on
//! the HTTP request body, below tonic, so that message bytes are counted
//! *before* tonic has them whole and decodes them.
//!
//! tonic holds a message's bytes until the last one has arrived, in a buffer
//! of the message's declared length allocated as soon as the 5-byte header
//! is read; a client that sends big messages and withholds their end would
//! otherwise make the server hold them all, whatever the request concurrency
//! limit (handlers, and the admission check, run only after decoding). Here
//! each request's body reserves, from the shared [`ByteBudget`], the
//! declared length of the message it is delivering (the framing is
//! followed) before the bytes reach tonic. A complete message stays charged
//! until the next one starts or the call ends: tonic keeps a unary call's
//! decoded message until the request body has ended, and a client may never
//! end it.
//! The first [`FREE_BYTES`] a request holds are not charged: small calls
//! (every FK call, health checks) never depend on the budget, and what they
//! hold is bounded by the streams per connection and the HTTP/2 windows
//! instead. When the budget cannot cover more bytes, the call fails at once
//! with `RESOURCE_EXHAUSTED` (and its bytes are given back), never waits.

use std::pin::Pin;
use std::task::{Context, Poll};

use bytes::{Buf, Bytes};
use http_body::{Frame, SizeHint};
use tonic::Status;
use tonic::body::Body;
use tonic::codegen::http;
use tower::{Layer, Service};

use crate::api::budget::{ByteBudget, Reservation, request_bytes_refusal};

/// Bytes a request may hold without charge (one HTTP/2 stream window).
pub const FREE_BYTES: usize = 64 << 10;

/// Length of a gRPC message header (compressed flag, 4-byte length).
const HEADER: u8 = 5;

/// The layer; wraps every request body of the server.
#[derive(Clone, Debug)]
pub struct BufferedBytesLayer {
    budget: ByteBudget,
}

impl BufferedBytesLayer {
    /// Charges request bodies to `budget`.
    pub fn new(budget: ByteBudget) -> BufferedBytesLayer {
        BufferedBytesLayer { budget }
    }
}

impl<S> Layer<S> for BufferedBytesLayer {
    type Service = BufferedBytes<S>;
    fn layer(&self, inner: S) -> BufferedBytes<S> {
        BufferedBytes {
            inner,
            budget: self.budget.clone(),
        }
    }
}

/// The service of [`BufferedBytesLayer`].
#[derive(Clone, Debug)]
pub struct BufferedBytes<S> {
    inner: S,
    budget: ByteBudget,
}

impl<S> Service<http::Request<Body>> for BufferedBytes<S>
where
    S: Service<http::Request<Body>>,
{
    type Response = S::Response;
    type Error = S::Error;
    type Future = S::Future;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, req: http::Request<Body>) -> S::Future {
        let reservation = self.budget.reservation();
        self.inner
            .call(req.map(|body| Body::new(Charged::new(body, reservation))))
    }
}

/// Where a body is in the gRPC message framing, and what tonic may hold.
#[derive(Clone, Debug, Default)]
struct Framing {
    /// Header bytes seen of the message under way (0 to 5).
    header_seen: u8,
    /// Its length, as far as the header has been seen.
    length: u64,
    /// Its bytes still to come once the header is complete.
    remaining: u64,
    /// Its bytes seen so far (header included).
    partial: usize,
    /// Size of the last complete message: tonic may hold it decoded (a
    /// unary call holds its message until the request body ends) until the
    /// next message starts.
    last: usize,
    /// Messages completed since tonic last asked for data, before `last`:
    /// still in tonic's buffer, not decoded yet.
    earlier: usize,
}

impl Framing {
    /// Follows the framing over `data`.
    fn advance(&mut self, data: &[u8]) {
        let mut rest = data;
        while !rest.is_empty() {
            if self.header_seen < HEADER {
                if self.header_seen == 0 {
                    // A new message: the last one was delivered with it.
                    self.earlier += std::mem::take(&mut self.last);
                    // Its whole header here (nearly always): read at once.
                    if let Some((&[_, a, b, c, d], tail)) = rest.split_first_chunk::<5>() {
                        self.length = u64::from(u32::from_be_bytes([a, b, c, d]));
                        (self.header_seen, self.partial) = (HEADER, usize::from(HEADER));
                        self.remaining = self.length;
                        self.finish_if_complete();
                        rest = tail;
                        continue;
                    }
                }
                let (byte, tail) = rest.split_at(1);
                if self.header_seen > 0 {
                    self.length =
                        (self.length << 8) | u64::from(byte.first().copied().unwrap_or(0));
                }
                self.header_seen += 1;
                self.partial += 1;
                rest = tail;
                if self.header_seen == HEADER {
                    self.remaining = self.length;
                    self.finish_if_complete();
                }
                continue;
            }
            let n = usize::try_from(self.remaining)
                .unwrap_or(usize::MAX)
                .min(rest.len());
            self.remaining -= n as u64;
            self.partial += n;
            rest = rest.split_at(n).1;
            self.finish_if_complete();
        }
    }

    fn finish_if_complete(&mut self) {
        if self.header_seen == HEADER && self.remaining == 0 {
            self.last = std::mem::take(&mut self.partial);
            self.header_seen = 0;
            self.length = 0;
        }
    }

    /// tonic asks for more data only once it has decoded every complete
    /// message it holds (and, on a stream, the handler took them one by one).
    fn asked_for_more(&mut self) {
        self.earlier = 0;
    }

    /// Bytes tonic may hold: the messages not decoded yet, the whole declared
    /// length of the one under way (tonic allocates it when it has the
    /// header) and the last complete one.
    fn held(&self) -> usize {
        let rest = usize::try_from(self.remaining).unwrap_or(usize::MAX);
        self.partial
            .saturating_add(rest)
            .saturating_add(self.last)
            .saturating_add(self.earlier)
    }
}

/// A request body that charges the bytes tonic holds to the budget.
struct Charged {
    inner: Body,
    reservation: Reservation,
    framing: Framing,
}

impl Charged {
    fn new(inner: Body, reservation: Reservation) -> Charged {
        Charged {
            inner,
            reservation,
            framing: Framing::default(),
        }
    }

    /// The charge for what `framing` says tonic holds.
    fn charge_for(framing: &Framing) -> usize {
        framing.held().saturating_sub(FREE_BYTES)
    }

    /// Charges `data` before it is delivered; `false` if the budget cannot cover it.
    fn charge(&mut self, data: &Bytes) -> bool {
        let mut framing = self.framing.clone();
        framing.advance(data.chunk());
        if !self.reservation.resize(Charged::charge_for(&framing)) {
            return false;
        }
        self.framing = framing;
        true
    }
}

impl http_body::Body for Charged {
    type Data = Bytes;
    type Error = Status;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, Status>>> {
        let this = self.get_mut();
        this.framing.asked_for_more();
        let _ = this.reservation.resize(Charged::charge_for(&this.framing));
        let frame = match Pin::new(&mut this.inner).poll_frame(cx) {
            Poll::Ready(Some(Ok(frame))) => frame,
            other => return other,
        };
        if let Some(data) = frame.data_ref()
            && !this.charge(data)
        {
            let _ = this.reservation.resize(0);
            metrics::counter!("kinserve_grpc_rejected_total", "reason" => "buffered_bytes")
                .increment(1);
            tracing::debug!("gRPC request refused: the buffered request bytes budget is spent");
            return Poll::Ready(Some(Err(Status::from(request_bytes_refusal()))));
        }
        Poll::Ready(Some(Ok(frame)))
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.inner.size_hint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(len: usize) -> Vec<u8> {
        let mut m = vec![0u8];
        m.extend_from_slice(&(len as u32).to_be_bytes());
        m.extend(std::iter::repeat_n(7u8, len));
        m
    }

    #[test]
    fn framing_follows_messages_split_anywhere() {
        let mut bytes = message(10);
        bytes.extend(message(0));
        bytes.extend(message(300));
        for split in 1..bytes.len() {
            let mut f = Framing::default();
            for chunk in bytes.chunks(split) {
                f.asked_for_more();
                f.advance(chunk);
            }
            assert_eq!(f.partial, 0, "split {split}");
            assert_eq!(f.last, 305, "split {split}: the last message stays held");
        }
        let mut f = Framing::default();
        f.advance(&bytes[..bytes.len() - 1]);
        assert_eq!(f.partial, 304, "the last message is one byte short");
        assert_eq!(
            f.held(),
            15 + 5 + 305,
            "all of it, declared length included"
        );
        f.asked_for_more();
        assert_eq!(f.held(), 305, "the complete ones were decoded");
    }

    #[tokio::test]
    async fn a_big_message_is_charged_until_decoded_and_refused_past_the_budget() {
        use http_body_util::BodyExt;
        let budget = ByteBudget::new(FREE_BYTES * 3);
        let big = message(FREE_BYTES * 3 - 5);
        let mut first = Charged::new(
            Body::new(http_body_util::Full::new(Bytes::from(
                big[..FREE_BYTES * 2].to_vec(),
            ))),
            budget.reservation(),
        );
        assert!(first.frame().await.unwrap().is_ok());
        // Charged: the whole declared message (tonic allocates it), less the free part.
        assert_eq!(budget.in_use(), FREE_BYTES * 2);
        let mut second = Charged::new(
            Body::new(http_body_util::Full::new(Bytes::from(big.clone()))),
            budget.reservation(),
        );
        let err = second.frame().await.unwrap().unwrap_err();
        assert_eq!(err.code(), tonic::Code::ResourceExhausted);
        assert_eq!(
            budget.in_use(),
            FREE_BYTES * 2,
            "the refused call holds nothing"
        );
        drop(first);
        assert_eq!(budget.in_use(), 0);
    }

    /// A unary message complete but its request body never ended: tonic
    /// holds it (decoded) waiting for the end, so it stays charged.
    #[tokio::test]
    async fn a_complete_message_stays_charged_until_the_body_ends() {
        use http_body_util::BodyExt;
        let budget = ByteBudget::new(FREE_BYTES * 8);
        let (tx, rx) = tokio::sync::mpsc::channel::<Result<Frame<Bytes>, Status>>(1);
        let rx = tokio_stream::wrappers::ReceiverStream::new(rx);
        let mut body = Charged::new(
            Body::new(http_body_util::StreamBody::new(rx)),
            budget.reservation(),
        );
        tx.try_send(Ok(Frame::data(Bytes::from(message(FREE_BYTES * 3)))))
            .unwrap();
        assert!(body.frame().await.unwrap().is_ok());
        assert_eq!(budget.in_use(), FREE_BYTES * 2 + 5);
        // tonic asks for the end of the body: nothing comes; still charged.
        let pending = futures_util::FutureExt::now_or_never(body.frame());
        assert!(pending.is_none());
        assert_eq!(budget.in_use(), FREE_BYTES * 2 + 5);
        drop(body);
        assert_eq!(budget.in_use(), 0);
    }
}
