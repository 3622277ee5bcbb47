//! REST contract tests: every endpoint and status code of the REST API, FK of
//! built-ins against their closed forms, the token rule, persistence across a
//! restart and start-up with a corrupt data directory; the binary batch
//! formats (`binary_batch`).
//!
//! Split by area; the shared helpers are in `crate::helpers`.

mod batch;
mod binary_batch;
mod fk;
mod input;
mod ops;
mod overload;
mod robots;
mod storage;
