//! Byte budgets of the REST adapter: how many bytes of request bodies may be
//! buffered at once (read before a request permit is taken) and how many
//! bytes of response bodies may wait to be written to clients.
//!
//! A [`ByteBudget`] is a shared counter with a ceiling; a [`Reservation`]
//! holds some of it and gives it back when dropped, so a request or response
//! that ends in any way (answered, refused, connection reset) returns its
//! bytes. (The gRPC adapter has its own budget type of the same name; the two
//! are meant to become one.)

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A shared ceiling on buffered bytes.
#[derive(Clone, Debug)]
pub struct ByteBudget {
    used: Arc<AtomicUsize>,
    limit: usize,
}

impl ByteBudget {
    /// A budget of `limit` bytes.
    pub fn new(limit: usize) -> ByteBudget {
        ByteBudget {
            used: Arc::new(AtomicUsize::new(0)),
            limit,
        }
    }

    /// The ceiling in bytes.
    pub fn limit(&self) -> usize {
        self.limit
    }

    /// Bytes held right now.
    pub fn used(&self) -> usize {
        self.used.load(Ordering::Acquire)
    }

    /// Takes `n` bytes, or `None` when they do not fit.
    pub fn try_reserve(&self, n: usize) -> Option<Reservation> {
        let mut r = Reservation {
            budget: self.clone(),
            held: 0,
        };
        r.grow(n).then_some(r)
    }

    fn take(&self, n: usize) -> bool {
        self.used
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |used| {
                used.checked_add(n).filter(|total| *total <= self.limit)
            })
            .is_ok()
    }

    fn give_back(&self, n: usize) {
        self.used.fetch_sub(n, Ordering::AcqRel);
    }
}

/// Bytes held from a [`ByteBudget`] until dropped.
#[derive(Debug)]
pub struct Reservation {
    budget: ByteBudget,
    held: usize,
}

impl Reservation {
    /// Holds `n` more bytes; `false` (and nothing taken) when they do not fit.
    pub fn grow(&mut self, n: usize) -> bool {
        if n == 0 {
            return true;
        }
        if !self.budget.take(n) {
            return false;
        }
        self.held += n;
        true
    }

    /// Holds at least `n` bytes in all (grows by the difference if needed).
    pub fn grow_to(&mut self, n: usize) -> bool {
        self.grow(n.saturating_sub(self.held))
    }

    /// Bytes held.
    pub fn held(&self) -> usize {
        self.held
    }
}

impl Drop for Reservation {
    fn drop(&mut self) {
        if self.held > 0 {
            self.budget.give_back(self.held);
        }
    }
}

/// The budgets of the REST adapter.
#[derive(Clone, Debug)]
pub struct RestBudgets {
    /// Request bodies being read or waiting for their handler.
    pub request: ByteBudget,
    /// Response bodies not yet handed to the connection.
    pub response: ByteBudget,
    /// Batch requests computed at once (the others wait, within the request
    /// timeout): a batch's working memory is several times its answer, more
    /// batches at once than cores only adds memory, not speed, and batches
    /// that occupy every runtime worker stall all other connections.
    pub batch_slots: std::sync::Arc<tokio::sync::Semaphore>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reservations_fit_the_ceiling_and_return_on_drop() {
        let b = ByteBudget::new(100);
        let mut a = b.try_reserve(60).unwrap();
        assert!(b.try_reserve(41).is_none());
        assert!(!a.grow(41));
        assert!(a.grow_to(100));
        assert_eq!(b.used(), 100);
        drop(a);
        assert_eq!(b.used(), 0);
        assert!(b.try_reserve(100).is_some());
        assert_eq!(b.used(), 0);
    }
}
