//! What bounds the CPU one client can take: who a client is, budgets with a
//! share per client, and the compute pool the expensive operations run on.
//!
//! * [`ClientId`]: a request's client — its peer IP address (IPv6 by its /64,
//!   the block one host is given), or, behind a trusted proxy
//!   (`--trust-forwarded-for`), the address the proxy put last in
//!   `X-Forwarded-For`.
//! * [`FairBudget`]: a counted budget (requests in flight, batch slots,
//!   compute permits) of which no client holds more than its share.
//! * [`ComputePool`]: IK, batches, closed forms and URDF run on blocking
//!   threads, each under one permit of a [`FairBudget`] (one per CPU but
//!   one, at least two, so the async threads that serve `/healthz`, gRPC
//!   health and single FK keep a core, or on two cores share them evenly). Past the budget or the client's share a
//!   request is refused at once ([`Error::Overloaded`]: 503 + `Retry-After`,
//!   `RESOURCE_EXHAUSTED`); nothing queues. The work gets a cancel flag that
//!   is set when the caller stops waiting (client gone, call cancelled,
//!   deadline passed): the loops check it once per iteration or chunk, and
//!   the permit is held until the work has really stopped.
//!
//! Protocol-neutral: depends on the error type and tokio, never on an adapter.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use tokio::sync::{OwnedSemaphorePermit, Semaphore};

use crate::error::{Error, Result};

// ---------------------------------------------------------------- clients

/// Who a request comes from, for the per-client shares.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ClientId(Option<IpAddr>);

impl ClientId {
    /// A client the transport cannot name (in-process calls); all such share one share.
    pub const UNKNOWN: ClientId = ClientId(None);

    /// The client at `ip`: IPv4 (also when mapped into IPv6) by its address,
    /// IPv6 by its /64 prefix.
    pub fn from_ip(ip: IpAddr) -> ClientId {
        let ip = match ip {
            IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
                Some(v4) => IpAddr::V4(v4),
                None => {
                    let mut seg = v6.segments();
                    seg[4..].fill(0);
                    IpAddr::V6(seg.into())
                }
            },
            v4 => v4,
        };
        ClientId(Some(ip))
    }

    /// The client of a request from `peer` that carried `forwarded_for`
    /// (its `X-Forwarded-For` header or metadata). With `trust_forwarded`
    /// (the peer is a proxy of the operator's), the last address of the
    /// header is the client — the one the proxy itself appended; an absent
    /// or unreadable header leaves the peer.
    ///
    /// ```
    /// use kinserve::compute::ClientId;
    /// let proxy = "10.0.0.2".parse().ok();
    /// let seen = ClientId::resolve(proxy, Some("203.0.113.9, 198.51.100.7"), true);
    /// assert_eq!(seen, ClientId::from_ip("198.51.100.7".parse().unwrap()));
    /// assert_eq!(ClientId::resolve(proxy, Some("198.51.100.7"), false), ClientId::resolve(proxy, None, true));
    /// ```
    pub fn resolve(
        peer: Option<IpAddr>,
        forwarded_for: Option<&str>,
        trust_forwarded: bool,
    ) -> ClientId {
        let forwarded = forwarded_for
            .filter(|_| trust_forwarded)
            .and_then(|v| v.rsplit(',').next())
            .and_then(|last| last.trim().parse::<IpAddr>().ok());
        match forwarded.or(peer) {
            Some(ip) => ClientId::from_ip(ip),
            None => ClientId::UNKNOWN,
        }
    }
}

impl std::fmt::Display for ClientId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            Some(ip) => write!(f, "{ip}"),
            None => f.write_str("unknown"),
        }
    }
}

// ---------------------------------------------------------------- fair budgets

/// The share of a budget of `size` that one client may hold: `percent` of it
/// (rounded down), at least 1.
pub fn share_of(size: usize, percent: u8) -> usize {
    (size.saturating_mul(usize::from(percent.min(100))) / 100).max(1)
}

/// A budget of `size` units of which no client holds more than `share`.
/// Cloning shares it.
#[derive(Clone, Debug)]
pub struct FairBudget {
    total: Arc<Semaphore>,
    shares: Arc<Shares>,
    size: usize,
    name: BudgetName,
}

/// What a [`FairBudget`] counts and the flag that sizes it, for the words of
/// its refusals.
#[derive(Clone, Copy, Debug)]
struct BudgetName {
    /// Plural, e.g. `computations`.
    units: &'static str,
    /// e.g. `--compute-threads`.
    flag: &'static str,
}

#[derive(Debug)]
struct Shares {
    share: usize,
    held: Mutex<HashMap<ClientId, usize>>,
}

/// One unit of a [`FairBudget`], held by one client; dropping it gives it back.
#[derive(Debug)]
pub struct FairPermit {
    _total: Option<OwnedSemaphorePermit>,
    _share: Option<ShareGuard>,
}

#[derive(Debug)]
struct ShareGuard {
    shares: Arc<Shares>,
    client: ClientId,
}

impl Drop for ShareGuard {
    fn drop(&mut self) {
        let mut held = self
            .shares
            .held
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if let Some(n) = held.get_mut(&self.client) {
            *n -= 1;
            if *n == 0 {
                held.remove(&self.client);
            }
        }
    }
}

impl Shares {
    /// One more unit for `client`, unless it holds its share already.
    fn take(self: &Arc<Self>, client: ClientId) -> Option<ShareGuard> {
        let mut held = self.held.lock().unwrap_or_else(PoisonError::into_inner);
        let n = held.entry(client).or_insert(0);
        if *n >= self.share {
            return None;
        }
        *n += 1;
        Some(ShareGuard {
            shares: Arc::clone(self),
            client,
        })
    }
}

impl FairBudget {
    /// `size` units (at least 1), at most `share` (at least 1, at most `size`)
    /// per client; its refusals say that it counts `units` (plural, e.g.
    /// `"computations on the compute pool"`) and is sized by `flag`.
    ///
    /// ```
    /// use kinserve::compute::{ClientId, FairBudget};
    /// let b = FairBudget::new("streams", "--max-streams", 2, 1);
    /// let me = ClientId::from_ip("192.0.2.7".parse().unwrap());
    /// let _held = b.try_acquire(me).unwrap();
    /// let refusal = b.try_acquire(me).unwrap_err().to_string();
    /// assert!(refusal.contains("client 192.0.2.7 holds 1 of the server's 2 streams"), "{refusal}");
    /// ```
    pub fn new(units: &'static str, flag: &'static str, size: usize, share: usize) -> FairBudget {
        let size = size.clamp(1, Semaphore::MAX_PERMITS);
        FairBudget {
            total: Arc::new(Semaphore::new(size)),
            shares: Arc::new(Shares {
                share: share.clamp(1, size),
                held: Mutex::new(HashMap::new()),
            }),
            size,
            name: BudgetName { units, flag },
        }
    }

    /// The refusal of a client holding its share.
    fn share_refusal(&self, client: ClientId) -> Error {
        let BudgetName { units, flag } = self.name;
        Error::Overloaded {
            detail: format!(
                "client {client} holds {} of the server's {} {units}, its share \
                 (--client-share-percent of {flag}): wait until one has ended, \
                 or retry in a second",
                self.shares.share, self.size
            ),
        }
    }

    /// The refusal when every unit is taken.
    fn full_refusal(&self) -> Error {
        let BudgetName { units, flag } = self.name;
        Error::Overloaded {
            detail: format!(
                "all {} of the server's {units} are taken ({flag}): retry in a second",
                self.size
            ),
        }
    }

    /// Units in all.
    pub fn size(&self) -> usize {
        self.size
    }

    /// Units one client may hold.
    pub fn share(&self) -> usize {
        self.shares.share
    }

    /// Units free now.
    pub fn available(&self) -> usize {
        self.total.available_permits()
    }

    /// One more unit of `client`'s share, or [`Error::Overloaded`] when it
    /// holds its share already. A share of the whole budget (100 %) is no
    /// per-client cap at all: nothing is counted.
    fn take_share(&self, client: ClientId) -> Result<Option<ShareGuard>> {
        if self.shares.share >= self.size {
            return Ok(None);
        }
        match self.shares.take(client) {
            Some(guard) => Ok(Some(guard)),
            None => Err(self.share_refusal(client)),
        }
    }

    /// A unit for `client` now, or [`Error::Overloaded`] (nothing taken)
    /// when the client holds its share or the budget is spent.
    pub fn try_acquire(&self, client: ClientId) -> Result<FairPermit> {
        let share = self.take_share(client)?;
        let total = self
            .total
            .clone()
            .try_acquire_owned()
            .map_err(|_| self.full_refusal())?;
        Ok(FairPermit {
            _total: Some(total),
            _share: share,
        })
    }

    /// A unit for `client`: refused at once when the client holds its share
    /// (below 100 %), else waits for a free unit (the caller bounds the wait).
    pub async fn acquire(&self, client: ClientId) -> Result<FairPermit> {
        let share = self.take_share(client)?;
        let total = self.total.clone().acquire_owned().await.ok();
        Ok(FairPermit {
            _total: total,
            _share: share,
        })
    }
}

// ---------------------------------------------------------------- compute pool

/// Blocking threads for the expensive operations, under a [`FairBudget`] of
/// permits. Cloning shares it.
#[derive(Clone, Debug)]
pub struct ComputePool {
    permits: FairBudget,
}

/// Sets its flag when dropped: the caller stopped waiting for the work.
struct CancelOnDrop(Arc<AtomicBool>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

impl ComputePool {
    /// A pool of `permits` computations at once (at least 1), at most
    /// `share` of them for one client.
    pub fn new(permits: usize, share: usize) -> ComputePool {
        ComputePool {
            permits: FairBudget::new(
                "computations on the compute pool",
                "--compute-threads",
                permits,
                share,
            ),
        }
    }

    /// The default number of permits: one per CPU but one, at least 2 (with
    /// one, a client's share would be all of it).
    pub fn default_permits() -> usize {
        std::thread::available_parallelism()
            .map_or(2, |n| n.get().saturating_sub(1))
            .max(2)
    }

    /// The permits.
    pub fn budget(&self) -> &FairBudget {
        &self.permits
    }

    /// Runs `work` on a blocking thread under one of `client`'s permits, or
    /// refuses at once ([`Error::Overloaded`]). `work` gets the cancel flag,
    /// set when the returned future is dropped (the caller left or its
    /// deadline passed); the permit is released when `work` returns, not
    /// before, so abandoned work still counts until it has stopped.
    pub async fn run<T, F>(&self, client: ClientId, work: F) -> Result<T>
    where
        T: Send + 'static,
        F: FnOnce(&AtomicBool) -> Result<T> + Send + 'static,
    {
        let permit = self.permits.try_acquire(client).inspect_err(|_| {
            metrics::counter!("kinserve_compute_rejected_total").increment(1);
        })?;
        let cancel = Arc::new(AtomicBool::new(false));
        let _armed = CancelOnDrop(Arc::clone(&cancel));
        // The caller's span goes along to the blocking thread (free when
        // trace export is off: the span is disabled).
        let span = crate::trace_span!("compute pool");
        tokio::task::spawn_blocking(move || {
            let _permit = permit;
            span.in_scope(|| work(&cancel))
        })
        .await
        .map_err(|e| Error::Internal {
            detail: format!("a computation failed: {e}"),
        })?
    }
}

/// Whether `cancel` is set (a computation's caller left).
pub fn cancelled(cancel: &AtomicBool) -> bool {
    cancel.load(Ordering::Relaxed)
}

/// The error of a computation stopped because its caller left or its deadline passed.
pub fn stopped() -> Error {
    Error::Unavailable {
        detail: "the computation was stopped: its client left or its deadline passed".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    fn ip(s: &str) -> ClientId {
        ClientId::from_ip(s.parse().unwrap())
    }

    #[test]
    fn one_client_holds_at_most_its_share() {
        let b = FairBudget::new("units", "--test", 4, 2);
        let a1 = b.try_acquire(ip("127.0.0.1")).unwrap();
        let _a2 = b.try_acquire(ip("127.0.0.1")).unwrap();
        assert!(b.try_acquire(ip("127.0.0.1")).is_err(), "past the share");
        let _b1 = b.try_acquire(ip("127.0.0.2")).unwrap();
        let _b2 = b.try_acquire(ip("127.0.0.2")).unwrap();
        assert!(b.try_acquire(ip("127.0.0.3")).is_err(), "budget spent");
        drop(a1);
        assert!(
            b.try_acquire(ip("127.0.0.2")).is_err(),
            "still at its share"
        );
        let _c = b.try_acquire(ip("127.0.0.3")).unwrap();
        assert_eq!(b.available(), 0);
    }

    #[tokio::test]
    async fn a_share_of_the_whole_budget_waits_for_a_unit_instead_of_refusing() {
        let b = FairBudget::new("units", "--test", 2, 2);
        let me = ip("127.0.0.1");
        let first = b.acquire(me).await.unwrap();
        let _second = b.acquire(me).await.unwrap();
        assert!(b.try_acquire(me).is_err(), "the budget is spent");
        let third = tokio::spawn({
            let b = b.clone();
            async move { b.acquire(me).await.map(|_| ()) }
        });
        tokio::time::sleep(Duration::from_millis(50)).await;
        assert!(
            !third.is_finished(),
            "it waits for a unit, it is not refused"
        );
        drop(first);
        assert!(third.await.unwrap().is_ok());
        // Below 100 %, a client at its share is refused at once.
        let half = FairBudget::new("units", "--test", 2, 1);
        let _mine = half.acquire(me).await.unwrap();
        assert!(half.acquire(me).await.is_err());
    }

    #[test]
    fn ipv6_clients_are_their_64_and_mapped_ipv4_is_ipv4() {
        assert_eq!(ip("2001:db8:1:2:aaaa::1"), ip("2001:db8:1:2:bbbb::2"));
        assert_ne!(ip("2001:db8:1:2::1"), ip("2001:db8:1:3::1"));
        assert_eq!(ip("::ffff:127.0.0.2"), ip("127.0.0.2"));
        let peer = "10.1.1.1".parse().ok();
        assert_eq!(ClientId::resolve(peer, Some("junk"), true), ip("10.1.1.1"));
        assert_eq!(ClientId::resolve(None, None, true), ClientId::UNKNOWN);
    }

    #[test]
    fn shares_are_percent_of_the_size_at_least_one() {
        assert_eq!(share_of(64, 50), 32);
        assert_eq!(share_of(1, 50), 1);
        assert_eq!(share_of(3, 50), 1);
        assert_eq!(share_of(10, 200), 10);
    }

    #[tokio::test]
    async fn dropped_work_is_cancelled_and_keeps_its_permit_until_it_stops() {
        let pool = ComputePool::new(1, 1);
        let client = ip("127.0.0.1");
        let (tx, rx) = std::sync::mpsc::channel();
        let job = pool.run(client, move |cancel| {
            let start = Instant::now();
            while !cancelled(cancel) && start.elapsed() < Duration::from_secs(10) {
                std::thread::sleep(Duration::from_millis(1));
            }
            std::thread::sleep(Duration::from_millis(50));
            let _ = tx.send(cancelled(cancel));
            Ok(())
        });
        // Started, then abandoned.
        let _ = tokio::time::timeout(Duration::from_millis(50), job).await;
        assert!(
            pool.run(ip("127.0.0.2"), |_| Ok(())).await.is_err(),
            "the permit is held while the abandoned work winds down"
        );
        let saw_cancel = tokio::task::spawn_blocking(move || rx.recv().unwrap())
            .await
            .unwrap();
        assert!(saw_cancel, "the work saw the cancel flag");
        tokio::time::sleep(Duration::from_millis(20)).await;
        assert!(pool.run(ip("127.0.0.2"), |_| Ok(1)).await.is_ok());
    }
}
