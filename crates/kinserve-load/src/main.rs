//! `kinserve-load`: load generator for kinserve (the library of this crate).

use clap::Parser;

/// The server's allocator: the load generator shares the machine with the
/// server, so its per-message allocations should cost as little.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use kinserve_load::{LoadArgs, Report, run};

#[tokio::main]
async fn main() -> std::process::ExitCode {
    let args = LoadArgs::parse();
    let json = args.json;
    match run(args).await {
        Ok(report) => {
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&report).unwrap_or_default()
                );
            } else {
                println!("{}", Report::table_header());
                println!("{}", report.table_row());
                if !report.errors.is_empty() {
                    println!("errors: {:?}", report.errors);
                }
                println!(
                    "sent {} answered {} poses {} ({} s, {})",
                    report.sent, report.answered, report.poses, report.duration_s, report.mode
                );
            }
            if report.error_count() > 0 || report.sent != report.answered {
                std::process::ExitCode::FAILURE
            } else {
                std::process::ExitCode::SUCCESS
            }
        }
        Err(e) => {
            eprintln!("kinserve-load: {e}");
            std::process::ExitCode::from(2)
        }
    }
}
