//! Hostile input: the bad-input corpus in `tests/corpus/` run over REST, the
//! WebSocket stream and gRPC (typed messages and raw frames), while a parallel
//! client keeps asking for correct FK and checks every answer; plus WebSocket
//! frame abuse, slowloris, floods, slow readers, panics and the token rule.
//!
//! Every case must get its documented status (HTTP 4xx problem+json or gRPC
//! code) with the field at fault, and the server must keep answering.
//!
//! Split by area; the shared helpers (corpus, parallel checker, WebSocket)
//! are in `crate::helpers`.

mod auth;
mod corpus_grpc;
mod corpus_http;
mod cpu;
mod http_budgets;
mod overload;
mod streams;
mod ws;
