//! Core tests of the server crate: the built-in robots as the server loads
//! them, the CLI, the README's model examples and the fuzz corpus replay.
//! The math tests (kinematics, Jacobian, IK, model validation, published
//! poses, closed forms) live with their crates, in
//! `crates/kinserve-kinematics/tests` and `crates/kinserve-model/tests`.
mod builtins;
mod cli;
mod fuzz_corpus;
mod helpers;
mod readme;
mod service_limits;
