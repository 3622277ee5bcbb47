#!/usr/bin/env bash
# Runs the cargo-fuzz (libFuzzer) targets in fuzz/ for a bounded time each.
#
#   scripts/fuzz.sh                  # every target, FUZZ_SECONDS (default 60) each
#   FUZZ_SECONDS=300 scripts/fuzz.sh model
#
# Targets: `model` (robot model parsing + validation + FK at in-limit
# configurations), `fk_request` (REST single/batch FK bodies and the
# WebSocket message, decoded and evaluated) and `ik_request` (REST single/batch
# IK bodies and the WebSocket `ik` message, validated and solved). The properties they check live in
# `kinserve_testkit::fuzzing` (crates/kinserve-testkit/src/fuzzing.rs).
#
# Corpus: fuzz/corpus/<target>/ (kept small and commit-worthy: minimised with
# `cargo fuzz cmin` once it holds more than FUZZ_CORPUS_MAX files).
# Crashes, leaks, timeouts and OOMs go to fuzz/artifacts/<target>/. Both are
# replayed by `cargo test --test core fuzz_corpus` (tests/core/fuzz_corpus.rs),
# together with fuzz/regressions/<target>/ (minimal reproducers of fixed bugs:
# move an artifact there once it is fixed).
#
# cargo-fuzz needs nightly-only rustc flags (-Zsanitizer); on a stable toolchain
# RUSTC_BOOTSTRAP=1 unlocks them. cargo-fuzz is installed from crates.io if missing.
#
# Environment:
#   FUZZ_SECONDS     seconds per target (default 60)
#   FUZZ_JOBS        parallel libFuzzer workers per target (default 1)
#   FUZZ_CORPUS_MAX  corpus size that triggers minimisation (default 400)
#   FUZZ_SANITIZER   address (default) or none
# Exit status: 0 if every target ran clean, 1 if any found a failure.
set -euo pipefail

cd "$(dirname "$0")/.."
root=$(pwd)

FUZZ_SECONDS=${FUZZ_SECONDS:-60}
FUZZ_JOBS=${FUZZ_JOBS:-1}
FUZZ_CORPUS_MAX=${FUZZ_CORPUS_MAX:-400}
FUZZ_SANITIZER=${FUZZ_SANITIZER:-address}
MAX_LEN=65536
ALL_TARGETS=(model fk_request ik_request)
if [ $# -gt 0 ]; then targets=("$@"); else targets=("${ALL_TARGETS[@]}"); fi

export RUSTC_BOOTSTRAP=1

if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "fuzz.sh: installing cargo-fuzz from crates.io" >&2
    cargo install cargo-fuzz --locked
fi

# Same libFuzzer options for run and cmin.
libfuzzer_opts=(
    -max_len="$MAX_LEN"
    -timeout=10            # one input taking >10 s is a hang
    -rss_limit_mb=2048
    -malloc_limit_mb=512   # one allocation >512 MB from ≤64 KB of input is unbounded
)

count() { find "$1" -maxdepth 1 -type f | wc -l | tr -d ' '; }

status=0
for t in "${targets[@]}"; do
    corpus="$root/fuzz/corpus/$t"
    artifacts="$root/fuzz/artifacts/$t"
    mkdir -p "$corpus" "$artifacts"
    echo "== $t: ${FUZZ_SECONDS}s, corpus $(count "$corpus") files" >&2
    (cd fuzz && cargo fuzz build -s "$FUZZ_SANITIZER" "$t")
    run_opts=(
        -dict="$root/fuzz/dict/$t.dict"
        -max_total_time="$FUZZ_SECONDS"
        -artifact_prefix="$artifacts/"
        -print_final_stats=1
    )
    if [ "$FUZZ_JOBS" -gt 1 ]; then
        # Workers log to fuzz/fuzz-N.log; each runs for the whole time limit.
        run_opts+=(-jobs="$FUZZ_JOBS" -workers="$FUZZ_JOBS")
    fi
    set +e
    (cd fuzz && cargo fuzz run -s "$FUZZ_SANITIZER" "$t" "$corpus" -- \
        "${libfuzzer_opts[@]}" "${run_opts[@]}")
    rc=$?
    set -e
    if [ "$rc" -ne 0 ]; then
        echo "== $t: FAILED (exit $rc); reproducers in $artifacts" >&2
        status=1
    fi
    n=$(count "$corpus")
    if [ "$n" -gt "$FUZZ_CORPUS_MAX" ]; then
        echo "== $t: corpus has $n files, minimising" >&2
        # Edge coverage only (-use_counters=0; hit-count buckets would keep
        # thousands of near-duplicate JSON inputs) and a greedy set cover.
        (cd fuzz && cargo fuzz cmin -s "$FUZZ_SANITIZER" "$t" "$corpus" -- \
            "${libfuzzer_opts[@]}" -use_counters=0 -set_cover_merge=1)
    fi
    echo "== $t: corpus $(count "$corpus") files, $(cat "$corpus"/* | wc -c | tr -d ' ') bytes" >&2
done

if [ "$status" -ne 0 ]; then
    echo "fuzz.sh: failures found; see fuzz/artifacts/ (replay: cargo test --test core fuzz_corpus)" >&2
fi
exit "$status"
