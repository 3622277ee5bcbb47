//! The cross-protocol contract suite: one table of cases (robots, joint
//! configurations, bad inputs) run over REST, gRPC unary, the gRPC stream and
//! the WebSocket against one server, asserting identical poses (to 1e-12, and
//! equal to the library) and the same error class and field paths.
//!
//! Error classes: REST 400/422 ↔ INVALID_ARGUMENT (invalid), 404 ↔ NOT_FOUND,
//! 409 read-only ↔ FAILED_PRECONDITION, 409 already-exists ↔ ALREADY_EXISTS,
//! 401 ↔ UNAUTHENTICATED, 413 ↔ RESOURCE_EXHAUSTED (too large).
//!
//! Non-finite joint values: gRPC sends NaN / ±inf as doubles. JSON cannot carry
//! them, so REST and the WebSocket send the nearest JSON stand-ins instead: the
//! string `"x"` for NaN and the overflowing literal `1e999` / `-1e999` for ±inf.
//! Those are rejected by the JSON layer (400 malformed) rather than by the
//! finiteness check (422), which is the same class (invalid) and must name the
//! same field.
//!
//! Split by area; the case model and the front doors are in
//! `crate::helpers::cross_protocol`.

mod pose_format;
mod poses;
mod registry;
mod vocabulary;
