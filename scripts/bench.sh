#!/usr/bin/env bash
# Benchmarks the running service end to end and prints one table.
#   scripts/bench.sh                  # every target at 1, 16 and 64 connections, 5 s each
#   DURATION=10s WARMUP=2s scripts/bench.sh
# Builds in release, starts kinserve on loopback with a temporary data dir, runs
# kinserve-load for every target, wrk against REST FK and /healthz when wrk is
# installed (Debian: apt-get install wrk), and records the server's RSS
# (idle, and peak over the whole run, from /proc/PID/status).
set -euo pipefail
cd "$(dirname "$0")/.."

DURATION=${DURATION:-5s}
WARMUP=${WARMUP:-1s}
ROBOT=${ROBOT:-puma560}
CONCURRENCY=${CONCURRENCY:-"1 16 64"}
HTTP=127.0.0.1:${HTTP_PORT:-18480}
GRPC=127.0.0.1:${GRPC_PORT:-18451}

cargo build --release --bins --locked >&2
data=$(mktemp -d)
log=$(mktemp)
KINSERVE_HTTP_ADDR=$HTTP KINSERVE_GRPC_ADDR=$GRPC KINSERVE_DATA_DIR=$data \
  KINSERVE_MAX_CONCURRENT_REQUESTS=4096 RUST_LOG=warn ./target/release/kinserve serve 2>"$log" &
pid=$!
trap 'kill $pid 2>/dev/null; wait $pid 2>/dev/null; rm -rf "$data" "$log"' EXIT
for _ in $(seq 100); do
  curl -fs "http://$HTTP/readyz" >/dev/null 2>&1 && break
  sleep 0.1
done
curl -fs "http://$HTTP/readyz" >/dev/null || { echo "server did not start" >&2; cat "$log" >&2; exit 1; }
sleep 1
idle_rss=$(awk '/VmRSS/ {print $2}' /proc/$pid/status)

load() { ./target/release/kinserve-load --http-addr "$HTTP" --grpc-addr "$GRPC" --robot "$ROBOT" \
  --duration "$DURATION" --warmup "$WARMUP" "$@"; }

echo "# kinserve end-to-end figures"
echo "# machine: $(nproc) cores, $(awk '/model name/ {sub(/.*: /, ""); print; exit}' /proc/cpuinfo)"
echo "# load generator and server share the machine; robot $ROBOT; $DURATION per row after $WARMUP warm-up; closed loop"
echo "# batch rows: 100 configurations per request; stream rows: 32 messages in flight per connection"
echo
first=1
for c in $CONCURRENCY; do
  for t in rest-health rest rest-batch ws grpc-health grpc grpc-batch grpc-stream; do
    out=$(load --target "$t" --concurrency "$c" --batch-size 100 --pipeline 32) || { echo "$out"; echo "FAILED: $t at $c" >&2; exit 1; }
    if [ $first = 1 ]; then echo "$out" | sed -n 1p; first=0; fi
    echo "$out" | sed -n 2p
  done
done

load_rss=$(awk '/VmHWM/ {print $2}' /proc/$pid/status)

echo
echo "# batches of 10,000 configurations, end to end (encoding included), 1 connection"
for t in rest-batch grpc-batch; do
  json=$(load --target "$t" --concurrency 1 --batch-size 10000 --json)
  python3 - "$t" "$json" <<'PY'
import json, sys
r = json.loads(sys.argv[2])
pps = r["poses_per_s"]
print(f"{sys.argv[1]:<12} {r['requests_per_s']:8.1f} req/s  {pps:12.0f} poses/s  {1e6/pps if pps else float('nan'):6.3f} µs/pose  p50 {r['latency_us']['p50']/1000:.1f} ms")
PY
done

if command -v wrk >/dev/null; then
  echo
  echo "# wrk (HTTP/1.1 keep-alive), 2 threads"
  lua=$(mktemp --suffix=.lua)
  cat >"$lua" <<'LUA'
wrk.method = "POST"
wrk.body   = '{"joints": [0.1, -0.5, 0.7, 0.2, 0.3, -0.1]}'
wrk.headers["Content-Type"] = "application/json"
LUA
  for c in 16 64; do
    printf 'healthz   c=%-3s ' "$c"; wrk -t2 -c"$c" -d"$DURATION" --latency "http://$HTTP/healthz" | awk '/Requests\/sec/ {r=$2} /99%/ {p=$2} END {print r " req/s, p99 " p}'
    printf 'fk        c=%-3s ' "$c"; wrk -t2 -c"$c" -d"$DURATION" --latency -s "$lua" "http://$HTTP/v1/robots/$ROBOT/fk" | awk '/Requests\/sec/ {r=$2} /99%/ {p=$2} END {print r " req/s, p99 " p}'
  done
  rm -f "$lua"
else
  echo
  echo "# wrk not installed (apt-get install wrk): skipped"
fi

peak_rss=$(awk '/VmHWM/ {print $2}' /proc/$pid/status)
echo
echo "# server RSS: idle $((idle_rss / 1024)) MB; peak during the table above (up to 64 connections) $((load_rss / 1024)) MB; peak over the whole run incl. 10,000-pose batches and wrk $((peak_rss / 1024)) MB"
