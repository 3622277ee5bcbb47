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
# each at --concurrency CONCURRENCY (default 16); a row reports poses/s (requests/s when a run has
# no poses). Settings of every server: those of scripts/bench.sh.
set -euo pipefail
[ $# -eq 2 ] || { sed -n '2,12p' "$0" >&2; exit 2; }
OLD=$1 NEW=$2
ROUNDS=${ROUNDS:-3}
DURATION=${DURATION:-5s}
CONCURRENCY=${CONCURRENCY:-16}
HTTP=127.0.0.1:${HTTP_PORT:-18580}
GRPC=127.0.0.1:${GRPC_PORT:-18551}
RUNS=${RUNS:-"grpc-health;grpc-stream --pipeline 32 --pose-format matrix;grpc-stream --pipeline 32;ws --pipeline 32 --pose-format matrix;rest"}
IFS=';' read -r -a runs <<<"$RUNS"
pid="" data="" log=$(mktemp)
cleanup() {
  if [ -n "$pid" ]; then kill "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; fi
  [ -n "$data" ] && rm -rf "$data"
  rm -f "$log"
}
trap cleanup EXIT

# rate ARGS...: poses/s of one kinserve-load run (requests/s for a run without
# poses, e.g. health), or "failed" with the load generator's error on stderr.
rate() {
  local out
  if ! out=$("$OLD/kinserve-load" --http-addr "$HTTP" --grpc-addr "$GRPC" --robot puma560 \
    --duration "$DURATION" --warmup 1s --concurrency "$CONCURRENCY" --json --target "$@"); then
    echo "failed"; return
  fi
  python3 -c 'import json,sys; r=json.load(sys.stdin); print(round(r["poses_per_s"] or r["requests_per_s"]))' <<<"$out"
}

for round in $(seq "$ROUNDS"); do
  for dir in "$OLD" "$NEW"; do
    if curl -fs "http://$HTTP/readyz" >/dev/null 2>&1; then
      echo "something already answers on $HTTP: set HTTP_PORT / GRPC_PORT" >&2; exit 1
    fi
    data=$(mktemp -d)
    env KINSERVE_HTTP_ADDR=$HTTP KINSERVE_GRPC_ADDR=$GRPC KINSERVE_DATA_DIR="$data" \
      KINSERVE_MAX_CONCURRENT_REQUESTS=4096 KINSERVE_CLIENT_SHARE_PERCENT=100 \
      KINSERVE_COMPUTE_THREADS=64 RUST_LOG=warn "$dir/kinserve" serve 2>"$log" &
    pid=$!
    for _ in $(seq 100); do curl -fs "http://$HTTP/readyz" >/dev/null 2>&1 && break; sleep 0.1; done
    curl -fs "http://$HTTP/readyz" >/dev/null || { echo "$dir/kinserve did not start:" >&2; cat "$log" >&2; exit 1; }
    line="round $round $dir:"
    for run in "${runs[@]}"; do
      # shellcheck disable=SC2086 # each run is its own word list
      line+=" [$run] $(rate $run)"
    done
    echo "$line"
    kill "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
    pid=""
    rm -rf "$data"
    data=""
  done
done
