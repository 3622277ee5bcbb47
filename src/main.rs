//! The `kinserve` binary: parses the command line and hands over to the library.

use clap::Parser;

fn main() -> std::process::ExitCode {
    kinserve::cli::run(kinserve::config::Cli::parse())
}
