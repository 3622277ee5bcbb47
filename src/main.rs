//! The `kinserve` binary: parses the command line and hands over to the library.

use clap::Parser;

/// mimalloc: the request path allocates small short-lived buffers (bodies,
/// headers, JSON); glibc malloc cost ~10% of a single-FK request in profiles.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    kinserve::cli::run(kinserve::config::Cli::parse())
}

/// mimalloc's options set in code.
mod allocator {
    use std::ffi::{c_int, c_long};

    // mimalloc 3's C API (the static library the `mimalloc` crate links);
    // `libmimalloc-sys` does not export this option's id.
    unsafe extern "C" {
        fn mi_option_get(option: c_int) -> c_long;
        fn mi_option_set(option: c_int, value: c_long);
    }
    /// `mi_option_arena_eager_commit` in mimalloc 3's `mi_option_e`.
    const ARENA_EAGER_COMMIT: c_int = 4;

    /// Arena memory committed as it is used instead of all at once (mimalloc's
    /// `arena_eager_commit` 0 instead of 2): idle RSS 20 MB instead of 35, and
    /// a lower peak, at the same batch speed (docs/benchmarks-history.md, issue 28
    /// "Before and after each change").
    /// Runs as a constructor of the executable, before the Rust runtime's
    /// first allocation reserves mimalloc's first arena (set in `main` it
    /// came too late). mimalloc reads `MIMALLOC_ARENA_EAGER_COMMIT` on the
    /// first look, so an operator's value other than the default 2 is kept.
    #[cfg(target_os = "linux")]
    #[used]
    #[unsafe(link_section = ".init_array")]
    static COMMIT_ON_DEMAND: extern "C" fn() = commit_on_demand;

    extern "C" fn commit_on_demand() {
        // SAFETY: plain C calls on mimalloc's option table (an int id and a
        // long value), made before any other thread exists; 2 is the
        // documented default of this id, so a different id meaning is not written.
        unsafe {
            if mi_option_get(ARENA_EAGER_COMMIT) == 2 {
                mi_option_set(ARENA_EAGER_COMMIT, 0);
            }
        }
    }
}
