//! Budgets shared by the front doors, separate from the request permits:
//!
//! * [`StreamBudget`]: open streams (WebSockets and gRPC
//!   `StreamForwardKinematics` calls together), in total and per connection.
//!   A stream holds a [`StreamPermit`] for as long as it is open, never a
//!   request permit, so streams cannot starve unary calls and REST requests
//!   (and unary calls cannot starve streams). Past either limit a new stream
//!   is refused at once ([`Error::Overloaded`]: 503 + `Retry-After` before the
//!   WebSocket upgrade, `RESOURCE_EXHAUSTED` on gRPC).
//! * [`ByteBudget`]: bytes of request bodies the server holds before it can
//!   decode them (gRPC messages still arriving). Reservations are taken as
//!   data arrives and given back when it has been consumed; when the budget is
//!   spent the request fails at once instead of waiting.
//!
//! * [`ConnectionSlots`]: accepted connections, over both listeners. When
//!   every slot is taken the listeners stop accepting (new clients wait in the
//!   kernel's backlog) until a connection closes.
//!
//! The first two are lock-free counters; a refused reservation changes nothing.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use tokio::sync::{OwnedSemaphorePermit, Semaphore};

use crate::compute::{ClientId, FairBudget, FairPermit};
use crate::error::Error;

/// Takes `n` from `counter` if the result stays within `limit`.
fn try_add(counter: &AtomicUsize, n: usize, limit: usize) -> bool {
    counter
        .fetch_update(Ordering::AcqRel, Ordering::Acquire, |used| {
            used.checked_add(n).filter(|total| *total <= limit)
        })
        .is_ok()
}

// ---------------------------------------------------------------- connections

/// Slots for open connections, shared by the REST and gRPC listeners.
#[derive(Clone, Debug)]
pub struct ConnectionSlots(Arc<Semaphore>);

impl ConnectionSlots {
    /// At most `max` connections at once (at least 1).
    pub fn new(max: usize) -> ConnectionSlots {
        ConnectionSlots(Arc::new(Semaphore::new(max.max(1))))
    }

    /// Waits for a free slot; the connection holds it until it is dropped.
    /// `None` only if the slots were closed (never, in practice).
    pub async fn wait(&self) -> Option<OwnedSemaphorePermit> {
        self.0.clone().acquire_owned().await.ok()
    }

    /// Free slots now.
    pub fn available(&self) -> usize {
        self.0.available_permits()
    }
}

/// Errors of `accept`: a connection that failed before it was accepted is
/// skipped; anything else (e.g. out of file descriptors) is logged and retried
/// after a pause instead of spinning.
pub async fn accept_error(e: std::io::Error) {
    use std::io::ErrorKind::{ConnectionAborted, ConnectionRefused, ConnectionReset};
    if matches!(
        e.kind(),
        ConnectionAborted | ConnectionRefused | ConnectionReset
    ) {
        return;
    }
    tracing::error!(error = %e, "accept failed; retrying shortly");
    tokio::time::sleep(std::time::Duration::from_millis(100)).await;
}

/// The budgets the gRPC adapter shares with the REST one.
#[derive(Clone, Debug)]
pub struct Budgets {
    /// Requests in flight (REST requests and gRPC unary calls together).
    pub permits: FairBudget,
    /// Open streams.
    pub streams: StreamBudget,
    /// Buffered request bytes.
    pub request_bytes: ByteBudget,
    /// Open connections.
    pub connections: ConnectionSlots,
}

// ---------------------------------------------------------------- streams

/// The open-streams budget: at most `total` streams at once over both
/// protocols, and at most `per_connection` on one connection.
#[derive(Clone, Debug)]
pub struct StreamBudget {
    total: FairBudget,
    per_connection: usize,
}

/// The streams open on one connection (one per HTTP/1 connection, which
/// carries at most one WebSocket; many on HTTP/2). The transport creates one
/// per accepted connection and puts it in every request's extensions.
#[derive(Clone, Debug, Default)]
pub struct ConnectionStreams(Arc<AtomicUsize>);

impl ConnectionStreams {
    /// Streams open on this connection now.
    pub fn open(&self) -> usize {
        self.0.load(Ordering::Acquire)
    }
}

/// One open stream's share of the [`StreamBudget`]; dropping it frees it.
#[derive(Debug)]
pub struct StreamPermit {
    _total: FairPermit,
    connection: Option<ConnectionStreams>,
}

impl Drop for StreamPermit {
    fn drop(&mut self) {
        if let Some(c) = &self.connection {
            c.0.fetch_sub(1, Ordering::AcqRel);
        }
    }
}

impl StreamBudget {
    /// A budget of `total` streams (at least one), at most `per_connection`
    /// (at least one) on any connection and `per_client` on any client's.
    pub fn new(total: usize, per_connection: usize, per_client: usize) -> StreamBudget {
        StreamBudget {
            total: FairBudget::new("streams", "--max-streams", total, per_client),
            per_connection: per_connection.max(1),
        }
    }

    /// Streams that may still open (over all connections).
    pub fn available(&self) -> usize {
        self.total.available()
    }

    /// Opens a stream for `client` on `connection` (`None`: a transport that
    /// does not tell connections apart; only the total and the client's share
    /// apply), or refuses it with [`Error::Overloaded`] when the connection,
    /// the client or the server has as many as it may.
    pub fn try_open(
        &self,
        connection: Option<&ConnectionStreams>,
        client: ClientId,
    ) -> Result<StreamPermit, Error> {
        if let Some(c) = connection
            && !try_add(&c.0, 1, self.per_connection)
        {
            return Err(Error::Overloaded {
                detail: format!(
                    "this connection has {} streams open (--max-streams-per-connection): \
                     end one, or open another connection",
                    self.per_connection
                ),
            });
        }
        let connection = connection.cloned();
        match self.total.try_acquire(client) {
            Ok(total) => Ok(StreamPermit {
                _total: total,
                connection,
            }),
            Err(e) => {
                if let Some(c) = &connection {
                    c.0.fetch_sub(1, Ordering::AcqRel);
                }
                Err(e)
            }
        }
    }
}

// ---------------------------------------------------------------- bytes

/// The refusal when the buffered request bytes budget is spent.
pub fn request_bytes_refusal() -> Error {
    Error::Overloaded {
        detail: "the server's buffer for request bodies is full \
                 (--max-buffered-request-bytes): retry in a second"
            .into(),
    }
}

/// The refusal when the buffered response bytes budget is spent.
pub fn response_bytes_refusal() -> Error {
    Error::Overloaded {
        detail: "the server's buffer for answers is full \
                 (--max-buffered-response-bytes): retry in a second"
            .into(),
    }
}

/// A budget of bytes held at once, shared by everything that reserves from
/// it (cloning shares it).
#[derive(Clone, Debug)]
pub struct ByteBudget {
    inner: Arc<BudgetInner>,
}

#[derive(Debug)]
struct BudgetInner {
    limit: usize,
    used: AtomicUsize,
}

impl ByteBudget {
    /// A budget of `limit` bytes.
    pub fn new(limit: usize) -> ByteBudget {
        ByteBudget {
            inner: Arc::new(BudgetInner {
                limit,
                used: AtomicUsize::new(0),
            }),
        }
    }

    /// The budget's size in bytes.
    pub fn limit(&self) -> usize {
        self.inner.limit
    }

    /// Bytes reserved now.
    pub fn in_use(&self) -> usize {
        self.inner.used.load(Ordering::Acquire)
    }

    /// Takes `n` bytes, or `None` (nothing taken) when they do not fit.
    pub fn try_reserve(&self, n: usize) -> Option<Reservation> {
        let mut r = self.reservation();
        r.resize(n).then_some(r)
    }

    /// An empty reservation, to grow as data arrives.
    pub fn reservation(&self) -> Reservation {
        Reservation {
            budget: self.clone(),
            bytes: 0,
        }
    }
}

/// Bytes held from a [`ByteBudget`]; dropping it gives them back.
#[derive(Debug)]
pub struct Reservation {
    budget: ByteBudget,
    bytes: usize,
}

impl Reservation {
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    /// Holds `n` more bytes; `false` (and nothing taken) when they do not fit.
    pub fn grow(&mut self, n: usize) -> bool {
        self.bytes
            .checked_add(n)
            .is_some_and(|total| self.resize(total))
    }

    /// Holds at least `n` bytes in all (grows by the difference if needed).
    pub fn grow_to(&mut self, n: usize) -> bool {
        n <= self.bytes || self.resize(n)
    }

    /// Grows or shrinks the reservation to `bytes`. Growing fails (and
    /// changes nothing) when the budget has not that much left.
    pub fn resize(&mut self, bytes: usize) -> bool {
        let used = &self.budget.inner.used;
        if bytes > self.bytes {
            if !try_add(used, bytes - self.bytes, self.budget.inner.limit) {
                return false;
            }
        } else {
            used.fetch_sub(self.bytes - bytes, Ordering::AcqRel);
        }
        self.bytes = bytes;
        true
    }
}

impl Drop for Reservation {
    fn drop(&mut self) {
        self.budget
            .inner
            .used
            .fetch_sub(self.bytes, Ordering::AcqRel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_limited_per_connection_and_in_total() {
        let budget = StreamBudget::new(3, 2, 3);
        let who = ClientId::UNKNOWN;
        let (a, b) = (ConnectionStreams::default(), ConnectionStreams::default());
        let a1 = budget.try_open(Some(&a), who).unwrap();
        let _a2 = budget.try_open(Some(&a), who).unwrap();
        assert!(budget.try_open(Some(&a), who).is_err(), "per connection");
        let _b1 = budget.try_open(Some(&b), who).unwrap();
        assert!(budget.try_open(Some(&b), who).is_err(), "in total");
        assert_eq!(b.open(), 1, "a refusal gives the connection's slot back");
        drop(a1);
        assert_eq!(a.open(), 1);
        let _b2 = budget.try_open(Some(&b), who).unwrap();
        assert_eq!(budget.available(), 0);
    }

    #[test]
    fn bytes_are_reserved_up_to_the_limit_and_given_back() {
        let budget = ByteBudget::new(100);
        let mut r1 = budget.reservation();
        let mut r2 = budget.reservation();
        assert!(r1.resize(60));
        assert!(!r2.resize(41), "over the limit");
        assert_eq!(r2.bytes(), 0);
        assert!(r2.resize(40));
        assert!(r1.resize(10));
        assert_eq!(budget.in_use(), 50);
        drop(r2);
        assert_eq!(budget.in_use(), 10);
        drop(r1);
        assert_eq!(budget.in_use(), 0);
    }
}
