//! The `kinserve` binary: parses the command line and hands over to the library.

use clap::Parser;

/// mimalloc: the request path allocates small short-lived buffers (bodies,
/// headers, JSON); glibc malloc cost ~10% of a single-FK request in profiles.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    kinserve::cli::run(kinserve::config::Cli::parse())
}
