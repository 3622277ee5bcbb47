//! The one rule for tests whose tools may be missing (a browser, PostgreSQL,
//! grpcurl, Pinocchio, a CPU feature): under CI they fail, elsewhere they
//! say SKIPPED where the person running `cargo test` sees it.
//!
//! "Under CI" is [`under_ci`]: the `CI` variable set to anything but empty,
//! `0` or `false` (any case) — what GitHub Actions, GitLab and `.ci/run`
//! (`CI=true`) set. The SKIPPED line goes to the process's stderr handle
//! directly: the test harness captures `eprintln!` of a passing test and
//! would hide it. Depends only on `std`.

use std::io::Write;

/// Whether the tests run under CI: `CI` is set and is not empty, `0` or
/// `false` (case-insensitive).
pub fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| {
        let v = v.trim().to_ascii_lowercase();
        !(v.is_empty() || v == "0" || v == "false")
    })
}

/// A test cannot run because `missing` is not there (`fix` says how to
/// install it). Under CI: panics (the test fails). Elsewhere: writes
/// `SKIPPED <test>: <missing> (<fix>)` past the harness's capture and
/// returns, so the caller returns early.
#[track_caller]
pub fn skip_unless_ci(test: &str, missing: &str, fix: &str) {
    if under_ci() {
        panic!("{test} cannot run under CI: {missing}. {fix}");
    }
    let _ = writeln!(
        std::io::stderr().lock(),
        "SKIPPED {test}: {missing} ({fix})"
    );
}

/// Writes `line` to the process's stderr past the harness's capture: for
/// what a test must report even when it passes (e.g. which kernels ran).
pub fn report(line: &str) {
    let _ = writeln!(std::io::stderr().lock(), "{line}");
}
