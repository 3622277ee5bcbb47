//! Byte budgets of the REST adapter: how many bytes of request bodies may be
//! buffered at once (read before a request permit is taken) and how many
//! bytes of response bodies may wait to be written to clients.
//!
//! A [`ByteBudget`] is a shared counter with a ceiling; a [`Reservation`]
//! holds some of it and gives it back when dropped, so a request or response
//! that ends in any way (answered, refused, connection reset) returns its
//! bytes. The request budget is the one the gRPC adapter charges its
//! undecoded messages to (one [`ByteBudget`], created at start-up).

pub use crate::api::budget::{ByteBudget, Reservation};

/// The budgets of the REST adapter.
#[derive(Clone, Debug)]
pub struct RestBudgets {
    /// Request bodies being read or waiting for their handler.
    pub request: ByteBudget,
    /// Response bodies not yet handed to the connection.
    pub response: ByteBudget,
    /// Batch requests under way at once (the others wait, within the
    /// request timeout; a client holding its share is refused at once): a
    /// batch's working memory is several times its answer, and more batches
    /// at once than cores only adds memory, not speed.
    pub batch_slots: crate::compute::FairBudget,
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
        assert_eq!(b.in_use(), 100);
        drop(a);
        assert_eq!(b.in_use(), 0);
        assert!(b.try_reserve(100).is_some());
        assert_eq!(b.in_use(), 0);
    }
}
