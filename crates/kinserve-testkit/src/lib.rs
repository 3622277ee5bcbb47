//! kinserve-testkit: what only tests, benchmarks and fuzzers need — never a
//! dependency of a production crate.
//!
//! It owns the plain reference FK product that the fast paths are tested
//! against ([`mod@reference`]), the property checks shared by the `cargo fuzz`
//! targets in `fuzz/` and the corpus replay test (`fuzzing`), and the
//! built-in robot files as bytes for those checks, and the one skip rule for
//! tests whose tools may be missing ([`mod@skip`]: fail under CI, else say
//! SKIPPED where it is seen).
//!
//! Features: the reference path needs only the math crates
//! (`kinserve-kinematics`, `kinserve-model`), so the math crates' own tests
//! use it without building the server; the fuzz checks parse requests as the
//! server does and come with the `server` feature (the server's tests and
//! `fuzz/` enable it).
//!
//! May depend on anything in the workspace; nothing in the workspace may
//! depend on it except as a dev-dependency.

#[cfg(feature = "server")]
mod fuzz_ik;
#[cfg(feature = "server")]
mod fuzz_shared;
#[cfg(feature = "server")]
pub mod fuzzing;
pub mod reference;
pub mod rng;
pub mod skip;

pub use reference::{RobotExt, forward_reference, supported_kernels};
pub use rng::SplitMix64;
pub use skip::{report, skip_unless_ci, under_ci};
