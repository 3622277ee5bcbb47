#!/usr/bin/env bash
# Figures of BENCHMARKS.md "Many replicas":
#  1. propagation delay between two replicas (p50/p99 over 1,000 changes) and
#     write latency with the database and with the file store: the ignored test
#     tests/api/replicas_bench.rs, in release;
#  2. FK throughput with the file store and with --database-url set
#     (kinserve-load, REST and gRPC unary, CONCURRENCY connections), alternated
#     ROUNDS times so that drift of the machine shows.
# Starts a private PostgreSQL (initdb in a temporary directory, as the
# postgres user when run as root) on a free loopback port; removes it at exit.
#   scripts/bench-replicas.sh            DURATION=5s ROUNDS=3 CONCURRENCY=64
set -euo pipefail
cd "$(dirname "$0")/.."

DURATION=${DURATION:-5s}
ROUNDS=${ROUNDS:-3}
CONCURRENCY=${CONCURRENCY:-64}
HTTP=127.0.0.1:${HTTP_PORT:-18580}
GRPC=127.0.0.1:${GRPC_PORT:-18551}
PG_PORT=${PG_PORT:-18532}

target=${CARGO_TARGET_DIR:-target}
cargo build --release --bins --locked >&2
echo "# 1. propagation and write latency (cargo test --release --test api -- --ignored replicas_bench)"
cargo test --release --locked --test api -- --ignored --nocapture replicas_bench 2>&1 |
  grep -E '^(propagation|write latency)'

bin=$(dirname "$(readlink -f "$(command -v pg_ctl 2>/dev/null || ls -d /usr/lib/postgresql/*/bin/pg_ctl | sort -V | tail -1)")")
pgdir=$(mktemp -d)
as_pg=()
if [ "$(id -u)" = 0 ]; then chown postgres: "$pgdir"; as_pg=(runuser -u postgres --); fi
echo bench >"$pgdir/pw"; chmod 644 "$pgdir/pw"
data=$(mktemp -d)
pid=
cleanup() {
  [ -n "$pid" ] && kill "$pid" 2>/dev/null && wait "$pid" 2>/dev/null
  "${as_pg[@]}" "$bin/pg_ctl" -D "$pgdir/data" -m immediate stop >/dev/null 2>&1 || true
  rm -rf "$pgdir" "$data"
}
trap cleanup EXIT
"${as_pg[@]}" "$bin/initdb" -U kinserve -A scram-sha-256 --pwfile="$pgdir/pw" -D "$pgdir/data" >/dev/null
"${as_pg[@]}" "$bin/pg_ctl" -D "$pgdir/data" -l "$pgdir/log" -w \
  -o "-p $PG_PORT -c listen_addresses=127.0.0.1 -c unix_socket_directories=$pgdir" start >/dev/null
url="postgres://kinserve:bench@127.0.0.1:$PG_PORT/postgres"

serve() { # serve [database url]
  env KINSERVE_HTTP_ADDR=$HTTP KINSERVE_GRPC_ADDR=$GRPC KINSERVE_DATA_DIR=$data \
    KINSERVE_MAX_CONCURRENT_REQUESTS=4096 RUST_LOG=warn ${1:+KINSERVE_DATABASE_URL=$1} \
    "$target"/release/kinserve serve 2>/dev/null &
  pid=$!
  for _ in $(seq 100); do curl -fs "http://$HTTP/readyz" >/dev/null 2>&1 && break; sleep 0.1; done
  curl -fs "http://$HTTP/v1/robots/puma560" >/dev/null
}
stop() { kill "$pid"; wait "$pid" 2>/dev/null || true; pid=; }
load() { "$target"/release/kinserve-load --http-addr "$HTTP" --grpc-addr "$GRPC" --robot puma560 \
  --duration "$DURATION" --warmup 1s --concurrency "$CONCURRENCY" --json "$@" |
  python3 -c 'import json,sys; r=json.load(sys.stdin); print(f"{r[\"requests_per_s\"]:9.0f} req/s  p99 {r[\"latency_us\"][\"p99\"]/1000:.2f} ms")'; }

echo
echo "# 2. FK throughput, $CONCURRENCY connections, $DURATION per row (server and load generator share the machine)"
for round in $(seq "$ROUNDS"); do
  for store in file postgres; do
    if [ $store = postgres ]; then serve "$url"; else serve; fi
    printf 'round %s  %-8s  rest %s\n' "$round" "$store" "$(load --target rest)"
    printf 'round %s  %-8s  grpc %s\n' "$round" "$store" "$(load --target grpc)"
    stop
  done
done
