//! What one HTTP connection is doing, shared between the connection's task
//! (in `startup`) and the REST middleware that sees its requests.
//!
//! The connection task inserts its [`ConnActivity`] into every request's
//! extensions. A request counts as busy from the moment it reaches the router
//! until its handler returns; a counted response body (see
//! `body_budget`/`buffered`) counts until it is finished or dropped, and marks
//! progress each time the connection takes a frame of it. From that the task
//! learns two things: how long the connection has been idle (no request and no
//! answer under way: the header timeout of HTTP/2, see
//! `startup::serve_http`), and whether answers are waiting that the client
//! has not taken for a while (the write timeout at the body level, which also
//! covers HTTP/2, where flow control stalls a stream without any write
//! blocking).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Activity of one connection.
#[derive(Debug)]
pub struct ConnActivity {
    start: Instant,
    busy: AtomicUsize,
    bodies: AtomicUsize,
    idle_since_ms: AtomicU64,
    progress_ms: AtomicU64,
}

/// Held while a request is handled (see [`ConnActivity::enter`]).
#[derive(Debug)]
pub struct Busy(Arc<ConnActivity>);

/// Held by a counted response body until it ends (see [`ConnActivity::body`]).
#[derive(Debug)]
pub struct BodyTicket(Arc<ConnActivity>);

impl ConnActivity {
    /// A connection that just opened (idle since now).
    pub fn new() -> Arc<ConnActivity> {
        Arc::new(ConnActivity {
            start: Instant::now(),
            busy: AtomicUsize::new(0),
            bodies: AtomicUsize::new(0),
            idle_since_ms: AtomicU64::new(0),
            progress_ms: AtomicU64::new(0),
        })
    }

    fn now_ms(&self) -> u64 {
        u64::try_from(self.start.elapsed().as_millis()).unwrap_or(u64::MAX)
    }

    /// A request reached the router; busy until the guard drops.
    pub fn enter(self: &Arc<Self>) -> Busy {
        self.busy.fetch_add(1, Ordering::AcqRel);
        Busy(self.clone())
    }

    /// A counted response body starts; it counts as busy, and as pending
    /// output, until the ticket drops.
    pub fn body(self: &Arc<Self>) -> BodyTicket {
        self.progress_ms.store(self.now_ms(), Ordering::Release);
        self.bodies.fetch_add(1, Ordering::AcqRel);
        self.busy.fetch_add(1, Ordering::AcqRel);
        BodyTicket(self.clone())
    }

    fn leave(&self) {
        if self.busy.fetch_sub(1, Ordering::AcqRel) == 1 {
            self.idle_since_ms.store(self.now_ms(), Ordering::Release);
        }
    }

    /// Resolves once the connection has had no request and no counted answer
    /// under way for `limit`.
    pub async fn idle_for(&self, limit: Duration) {
        let limit_ms = u64::try_from(limit.as_millis()).unwrap_or(u64::MAX);
        loop {
            let wait = if self.busy.load(Ordering::Acquire) > 0 {
                limit_ms
            } else {
                let idle = self
                    .now_ms()
                    .saturating_sub(self.idle_since_ms.load(Ordering::Acquire));
                if idle >= limit_ms {
                    return;
                }
                limit_ms - idle
            };
            tokio::time::sleep(Duration::from_millis(wait.max(1))).await;
        }
    }

    /// Resolves once counted answers are waiting and the connection has taken
    /// no frame of any of them for `limit`.
    pub async fn write_stalled(&self, limit: Duration) {
        let limit_ms = u64::try_from(limit.as_millis()).unwrap_or(u64::MAX);
        loop {
            let wait = if self.bodies.load(Ordering::Acquire) == 0 {
                limit_ms
            } else {
                let stalled = self
                    .now_ms()
                    .saturating_sub(self.progress_ms.load(Ordering::Acquire));
                if stalled >= limit_ms {
                    return;
                }
                limit_ms - stalled
            };
            tokio::time::sleep(Duration::from_millis(wait.max(1))).await;
        }
    }
}

impl Drop for Busy {
    fn drop(&mut self) {
        self.0.leave();
    }
}

impl BodyTicket {
    /// The connection took a frame of this answer.
    pub fn progress(&self) {
        self.0.progress_ms.store(self.0.now_ms(), Ordering::Release);
    }
}

impl Drop for BodyTicket {
    fn drop(&mut self) {
        self.0.bodies.fetch_sub(1, Ordering::AcqRel);
        self.0.leave();
    }
}
