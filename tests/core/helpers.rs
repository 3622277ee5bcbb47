//! Running the `kinserve` binary from the core tests.

use std::path::Path;
use std::process::{Command, Output};

/// `kinserve`, run from the repository root (so `robots/…` paths work).
pub fn kinserve() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_kinserve"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

/// `kinserve` run in `cwd`, with no robots dir in its environment.
pub fn kinserve_elsewhere(cwd: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_kinserve"));
    c.current_dir(cwd).env_remove("KINSERVE_ROBOTS_DIR");
    c
}

/// Asserts the command succeeded (its stderr is the failure message).
pub fn assert_ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The JSON a successful command printed.
pub fn stdout_json(out: &Output) -> serde_json::Value {
    assert_ok(out);
    serde_json::from_slice(&out.stdout).expect("the command prints JSON")
}
