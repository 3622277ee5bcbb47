#!/usr/bin/env bash
# Two builds of the server side by side, alternating (issue 28's "before and
# after each change"): for ROUNDS rounds, each build in turn gets a fresh
# server and the same kinserve-load runs (the first build's load generator
# for both, so only the server differs). Prints one line per round and build.
#   scripts/bench-ab.sh OLD_RELEASE_DIR NEW_RELEASE_DIR
#   ROUNDS=5 DURATION=10s scripts/bench-ab.sh /tmp/old ./target/release
#   RUNS="grpc-health;grpc-stream --pipeline 32 --pose-format matrix" scripts/bench-ab.sh A B
# RUNS: `;`-separated kinserve-load arguments after --target (default: gRPC
# health, the gRPC stream in `matrix` and `full`, WebSocket `matrix`, REST FK),
# each at --concurrency 16; a row reports poses/s (requests/s when a run has
# no poses). Settings of every server: those of scripts/bench.sh.
set -euo pipefail
[ $# -eq 2 ] || { sed -n '2,12p' "$0" >&2; exit 2; }
OLD=$1 NEW=$2
ROUNDS=${ROUNDS:-3}
DURATION=${DURATION:-5s}
HTTP=127.0.0.1:${HTTP_PORT:-18580}
GRPC=127.0.0.1:${GRPC_PORT:-18551}
RUNS=${RUNS:-"grpc-health;grpc-stream --pipeline 32 --pose-format matrix;grpc-stream --pipeline 32;ws --pipeline 32 --pose-format matrix;rest"}
IFS=';' read -r -a runs <<<"$RUNS"
pid=""
trap '[ -n "$pid" ] && kill "$pid" 2>/dev/null' EXIT

rate() {
  "$OLD/kinserve-load" --http-addr "$HTTP" --grpc-addr "$GRPC" --robot puma560 \
    --duration "$DURATION" --warmup 1s --concurrency 16 --json --target "$@" |
    python3 -c 'import json,sys; r=json.load(sys.stdin); print(round(r["poses_per_s"] or r["requests_per_s"]))'
}

for round in $(seq "$ROUNDS"); do
  for dir in "$OLD" "$NEW"; do
    data=$(mktemp -d)
    env KINSERVE_HTTP_ADDR=$HTTP KINSERVE_GRPC_ADDR=$GRPC KINSERVE_DATA_DIR="$data" \
      KINSERVE_MAX_CONCURRENT_REQUESTS=4096 KINSERVE_CLIENT_SHARE_PERCENT=100 \
      KINSERVE_COMPUTE_THREADS=64 RUST_LOG=warn "$dir/kinserve" serve 2>/dev/null &
    pid=$!
    for _ in $(seq 100); do curl -fs "http://$HTTP/readyz" >/dev/null 2>&1 && break; sleep 0.1; done
    line="round $round $dir:"
    for run in "${runs[@]}"; do
      # shellcheck disable=SC2086 # each run is its own word list
      line+=" [$run] $(rate $run)"
    done
    echo "$line"
    kill "$pid"; wait "$pid" 2>/dev/null || true
    rm -rf "$data"
  done
done
