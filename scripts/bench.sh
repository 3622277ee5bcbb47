#!/usr/bin/env bash
# Benchmarks the running service end to end and prints one table.
#   scripts/bench.sh                  # every target at 1, 16 and 64 connections, 5 s each
#   DURATION=10s WARMUP=2s scripts/bench.sh
#   WRK_ROUNDS=5 scripts/bench.sh     # alternating /healthz–FK wrk pairs behind the REST ratio (3)
#   TLS_ROUNDS=5 scripts/bench.sh     # alternating plain–TLS rounds behind the TLS ratios (3)
#   TLS_ONLY=1 scripts/bench.sh       # only the TLS-vs-plain comparison (issue 27)
#   PER_MESSAGE=64 scripts/bench.sh   # configurations per stream message in the grouped stream rows (16)
# Builds in release, starts kinserve on loopback with a temporary data dir, runs
# kinserve-load for every target, wrk against REST FK and /healthz when wrk is
# installed (Debian: apt-get install wrk), and records the server's RSS
# (idle, and peak over the whole run, from /proc/PID/status). Ends with the
# issue-15 targets (ratios computed from rows measured in this run) and the
# CPU split behind the per-request ratios: the server's and the load
# generator's CPU per request or message (they share the cores, so a ratio
# of two rows is a ratio of both processes' CPU) with what each goal allows,
# then TLS beside plain, then kinserve beside its floor (scripts/bench-floor.sh).
#   BIN_DIR=/tmp/old scripts/bench.sh   # binaries of another build (no cargo build;
#                                       # an old kinserve-load without --pose-format
#                                       # runs every row in the full format)
set -euo pipefail
cd "$(dirname "$0")/.."

DURATION=${DURATION:-5s}
WARMUP=${WARMUP:-1s}
ROBOT=${ROBOT:-puma560}
CONCURRENCY=${CONCURRENCY:-"1 16 64"}
HTTP=127.0.0.1:${HTTP_PORT:-18480}
GRPC=127.0.0.1:${GRPC_PORT:-18451}

BIN_DIR=${BIN_DIR:-}
if [ -z "$BIN_DIR" ]; then
  cargo build --release --bins --locked >&2
  BIN_DIR=./target/release
fi
formats="full matrix position"
"$BIN_DIR/kinserve-load" --help | grep -q -- --pose-format || formats="full"
# shellcheck source=scripts/bench-lib.sh
source scripts/bench-lib.sh
data=$(mktemp -d)
log=$(mktemp)
env KINSERVE_HTTP_ADDR=$HTTP KINSERVE_GRPC_ADDR=$GRPC KINSERVE_DATA_DIR=$data "${SERVER_ENV[@]}" \
  "$BIN_DIR/kinserve" serve 2>"$log" &
pid=$!
tls_pid=""
tls_dir=""
trap 'kill $pid $tls_pid 2>/dev/null; wait $pid $tls_pid 2>/dev/null; rm -rf "$data" "$log" $tls_dir ${split_log:-} ${split_times:-}' EXIT
wait_ready "$log" "http://$HTTP/readyz"
sleep 1
idle_rss=$(awk '/VmRSS/ {print $2}' /proc/$pid/status)

load() { "$BIN_DIR/kinserve-load" --http-addr "$HTTP" --grpc-addr "$GRPC" --robot "$ROBOT" \
  --duration "$DURATION" --warmup "$WARMUP" "$@"; }

# The CPU split of a row: the server and the load generator share the two
# cores, so every end-to-end ratio is a ratio of their CPU together.
# server_cpu: CPU seconds (user + system) the server has used so far;
# children_cpu (bench-lib.sh): those of this shell's finished children (the generator).
server_cpu() { cpu_of "$pid"; }
split_log=$(mktemp)
split_times=$(mktemp)
# run_split NAME CMD...: runs CMD (its standard output passes through) and
# appends "NAME server_s generator_s" to $split_log, both over the whole
# command (a kinserve-load row's warm-up included).
run_split() {
  local name=$1 s0 c0 s1
  shift
  s0=$(server_cpu); children_cpu "$split_times"; c0=$children_s
  "$@"
  s1=$(server_cpu); children_cpu "$split_times"
  echo "$name $s1 $s0 $children_s $c0" >>"$split_log"
}

# TLS beside plain (issue 27): a second server on the same settings with a
# throwaway certificate (openssl, valid one day), and rounds alternating the
# plain and the TLS server: REST FK with wrk (HTTP/1.1 keep-alive, 64
# connections) and gRPC unary FK and the gRPC stream with kinserve-load
# (16 connections; --tls-ca). Prints each round and the median ratio TLS ÷ plain.
tls_vs_plain() {
  if ! command -v openssl >/dev/null; then echo "# openssl not installed: TLS comparison skipped"; return; fi
  tls_dir=$(mktemp -d)
  local d=$tls_dir thttp=127.0.0.1:${TLS_HTTP_PORT:-18482} tgrpc=127.0.0.1:${TLS_GRPC_PORT:-18453}
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 1 -subj "/CN=kinserve bench CA" \
    -addext basicConstraints=critical,CA:TRUE -addext keyUsage=keyCertSign -keyout "$d/ca.key" -out "$d/ca.pem" 2>/dev/null
  openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -subj "/CN=localhost" \
    -keyout "$d/server.key" -out "$d/server.csr" 2>/dev/null
  printf 'subjectAltName=DNS:localhost,IP:127.0.0.1\nextendedKeyUsage=serverAuth\n' >"$d/ext"
  openssl x509 -req -in "$d/server.csr" -CA "$d/ca.pem" -CAkey "$d/ca.key" -CAcreateserial -days 1 \
    -extfile "$d/ext" -out "$d/server.crt" 2>/dev/null
  env KINSERVE_HTTP_ADDR=$thttp KINSERVE_GRPC_ADDR=$tgrpc KINSERVE_DATA_DIR=$d/data \
    KINSERVE_TLS_CERT=$d/server.crt KINSERVE_TLS_KEY=$d/server.key "${SERVER_ENV[@]}" \
    "$BIN_DIR/kinserve" serve 2>"$d/log" &
  tls_pid=$!
  wait_ready "$d/log" --cacert "$d/ca.pem" "https://localhost:${thttp##*:}/readyz"
  echo
  echo "# TLS beside plain (same settings, rounds alternate plain and TLS); REST: wrk -c64, gRPC: kinserve-load -c16"
  local lua=$d/fk.lua rows=""
  fk_lua "$lua"
  wrk_rate() { wrk -t2 -c64 -d"$DURATION" -s "$lua" "$1/v1/robots/$ROBOT/fk" | awk '/Requests\/sec/ {print $2}'; }
  grpc_rate() { "$BIN_DIR/kinserve-load" --grpc-addr "$1" --robot "$ROBOT" --duration "$DURATION" --warmup "$WARMUP" \
    --target "$2" --concurrency 16 --json "${@:3}" | python3 -c 'import json,sys; r=json.load(sys.stdin); assert not r["errors"], r["errors"]; print(round(r["poses_per_s"]))'; }
  for round in $(seq "${TLS_ROUNDS:-3}"); do
    local rp="-" rt="-"
    if command -v wrk >/dev/null; then
      rp=$(wrk_rate "http://$HTTP"); rt=$(wrk_rate "https://localhost:${thttp##*:}")
    fi
    local gp gt sp st
    gp=$(grpc_rate "$GRPC" grpc); gt=$(grpc_rate "$tgrpc" grpc --tls-ca "$d/ca.pem")
    sp=$(grpc_rate "$GRPC" grpc-stream --pipeline 32); st=$(grpc_rate "$tgrpc" grpc-stream --pipeline 32 --tls-ca "$d/ca.pem")
    echo "round $round  REST FK req/s plain $rp TLS $rt; gRPC FK req/s plain $gp TLS $gt; gRPC stream poses/s plain $sp TLS $st"
    rows="$rows $rp:$rt:$gp:$gt:$sp:$st"
  done
  python3 - "$rows" <<'PY'
import sys
rounds = [r.split(":") for r in sys.argv[1].split()]
def median(pairs):
    xs = sorted(float(t) / float(p) for p, t in pairs if p != "-" and t != "-")
    if not xs:
        return "n/a (wrk not installed)"
    mid = xs[len(xs) // 2] if len(xs) % 2 else (xs[len(xs) // 2 - 1] + xs[len(xs) // 2]) / 2
    return f"{mid:.2f} (rounds {xs[0]:.2f}–{xs[-1]:.2f})"
for name, i in (("REST FK (wrk, 64 conn)", 0), ("gRPC unary FK (16 conn)", 2), ("gRPC stream FK (16 streams x 32)", 4)):
    print(f"TLS / plain, {name:<34} {median([(r[i], r[i + 1]) for r in rounds])}")
PY
  kill "$tls_pid" 2>/dev/null; wait "$tls_pid" 2>/dev/null || true
  tls_pid=""
}

if [ -n "${TLS_ONLY:-}" ]; then
  echo "# kinserve TLS beside plain"
  echo "# machine: $(nproc) cores, $(awk '/model name/ {sub(/.*: /, ""); print; exit}' /proc/cpuinfo)"
  echo "# load generator and server share the machine; robot $ROBOT; $DURATION per measurement after $WARMUP warm-up"
  tls_vs_plain
  exit 0
fi

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
echo "# batches of 10,000 configurations, end to end (encoding included), 1 connection, by pose format"
declare -A batch_us
# grpc-batch-packed: the same batch in packed_configurations (an older
# kinserve-load without that target skips it).
batch_targets="rest-batch rest-batch-packed grpc-batch"
"$BIN_DIR/kinserve-load" --help | grep -q grpc-batch-packed && batch_targets="$batch_targets grpc-batch-packed"
for f in $formats; do
  # rest-batch-packed: the same batch as application/octet-stream both ways.
  for t in $batch_targets; do
    fmt=(); [ "$f" = full ] || fmt=(--pose-format "$f")
    json=$(load --target "$t" --concurrency 1 --batch-size 10000 --json "${fmt[@]}")
    batch_us[$t.$f]=$(python3 - "$t" "$f" "$json" <<'PY'
import json, sys
r = json.loads(sys.argv[3])
pps = r["poses_per_s"]
us = 1e6 / pps if pps else float("nan")
print(f"{sys.argv[1]:<17} {sys.argv[2]:<9} {r['requests_per_s']:8.1f} req/s  {pps:12.0f} poses/s  {us:6.3f} µs/pose  p50 {r['latency_us']['p50']/1000:.1f} ms", file=sys.stderr)
print(f"{us:.3f}")
PY
)
  done
done 2>&1

echo
echo "# streams and health at 16 connections, compact format (the issue-15 ratios)"
# rate NAME ARGS...: the row's poses/s (or requests/s); its CPU split and
# answered count go to $split_log.
rate() {
  local name=$1 answered per_s
  shift
  read -r answered per_s < <(run_split "$name" load "$@" --json |
    python3 -c 'import json,sys; r=json.load(sys.stdin); print(r["answered"], round(r["poses_per_s"] or r["requests_per_s"]))')
  echo "$name answered $answered" >>"$split_log"
  echo "$per_s"
}
f16=matrix; [ "$formats" = full ] && f16=full
fmt16=(); [ "$f16" = full ] || fmt16=(--pose-format "$f16")
grpc_health16=$(rate grpc-health --target grpc-health --concurrency 16)
rest16=$(rate rest --target rest --concurrency 16 "${fmt16[@]}")
grpc_stream16=$(rate grpc-stream --target grpc-stream --concurrency 16 --pipeline 32 "${fmt16[@]}")
ws16=$(rate ws --target ws --concurrency 16 --pipeline 32 "${fmt16[@]}")
echo "grpc-health $grpc_health16 req/s; rest ($f16) $rest16 poses/s; grpc-stream ($f16) $grpc_stream16 poses/s; ws ($f16) $ws16 poses/s"
# The same streams with PER_MESSAGE configurations per message
# (`configurations`, answered with as many poses): what a client that can
# group its configurations gets (reported beside the per-message ratio).
PER_MESSAGE=${PER_MESSAGE:-16}
per_message=(); "$BIN_DIR/kinserve-load" --help | grep -q -- --per-message && per_message=(--per-message "$PER_MESSAGE")
if [ ${#per_message[@]} -gt 0 ]; then
  grpc_stream16_many=$(rate grpc-stream-many --target grpc-stream --concurrency 16 --pipeline 32 "${fmt16[@]}" "${per_message[@]}")
  ws16_many=$(rate ws-many --target ws --concurrency 16 --pipeline 32 "${fmt16[@]}" "${per_message[@]}")
  echo "$PER_MESSAGE configurations per message: grpc-stream ($f16) $grpc_stream16_many poses/s; ws ($f16) $ws16_many poses/s"
else
  grpc_stream16_many=nan; ws16_many=nan
  echo "kinserve-load has no --per-message: the rows of many configurations per message are skipped"
fi

if command -v wrk >/dev/null; then
  echo
  echo "# wrk (HTTP/1.1 keep-alive), 2 threads"
  lua=$(mktemp --suffix=.lua)
  fk_lua "$lua"
  for c in 16 64; do
    h=$(wrk -t2 -c"$c" -d"$DURATION" --latency "http://$HTTP/healthz")
    f=$(wrk -t2 -c"$c" -d"$DURATION" --latency -s "$lua" "http://$HTTP/v1/robots/$ROBOT/fk")
    for which in healthz fk; do
      out=$h; [ $which = fk ] && out=$f
      printf '%-9s c=%-3s %s\n' "$which" "$c" "$(echo "$out" | awk '/Requests\/sec/ {r=$2} $1 == "99%" {p=$2} END {print r " req/s, p99 " p}')"
    done
  done
  # One pair is noisy on two shared cores: alternate /healthz and FK at 64
  # connections WRK_ROUNDS more times; the targets use the median pair ratio.
  wrk_pairs=""
  for _ in $(seq "${WRK_ROUNDS:-3}"); do
    h=$(run_split wrk-healthz wrk -t2 -c64 -d"$DURATION" --latency "http://$HTTP/healthz")
    f=$(run_split wrk-fk wrk -t2 -c64 -d"$DURATION" --latency -s "$lua" "http://$HTTP/v1/robots/$ROBOT/fk")
    echo "wrk-healthz answered $(echo "$h" | awk '/requests in/ {print $1}')" >>"$split_log"
    echo "wrk-fk answered $(echo "$f" | awk '/requests in/ {print $1}')" >>"$split_log"
    # The latency distribution's own line (`99%` as its first field): a
    # thread-stats line whose spread column ends in `99%` (85.99%) is not it.
    pair=$(printf '%s:%s:%s:%s' "$(echo "$h" | awk '/Requests\/sec/ {print $2}')" "$(echo "$f" | awk '/Requests\/sec/ {print $2}')" \
      "$(echo "$h" | awk '$1 == "99%" {print $2}')" "$(echo "$f" | awk '$1 == "99%" {print $2}')")
    echo "pair c=64  healthz:fk req/s and p99  $pair"
    wrk_pairs="$wrk_pairs $pair"
  done
  rm -f "$lua"
else
  echo
  echo "# wrk not installed (apt-get install wrk): skipped"
fi

peak_rss=$(awk '/VmHWM/ {print $2}' /proc/$pid/status)

# The core batch per pose on this machine, now (issue 28: the wire's cost is
# the batch ratio to it); the server is idle meanwhile.
core_batch_ns=$("$BIN_DIR/kinserve" bench --robot "$ROBOT" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["batch_ns_per_pose"])')
echo
echo "# server RSS: idle $((idle_rss / 1024)) MB; peak during the table above (up to 64 connections) $((load_rss / 1024)) MB; peak over the whole run incl. 10,000-pose batches and wrk $((peak_rss / 1024)) MB"

echo
echo "# issue-15 and issue-28 targets (this run)"
python3 - "${wrk_pairs:-}" "${batch_us[rest-batch.$f16]}" "${batch_us[grpc-batch.$f16]}" \
  "$grpc_health16" "$rest16" "$grpc_stream16" "$ws16" "$((idle_rss / 1024))" "$((peak_rss / 1024))" "$f16" "$core_batch_ns" \
  "${batch_us[rest-batch-packed.$f16]}" "$grpc_stream16_many" "$ws16_many" "$PER_MESSAGE" \
  "${batch_us[grpc-batch-packed.$f16]:-nan}" <<'PY'
import sys
a = sys.argv[1:]
def ms(v):
    v = str(v)
    for unit, k in (("us", 1e-3), ("ms", 1.0), ("s", 1e3)):
        if v.endswith(unit):
            return float(v[: -len(unit)]) * k
    return float(v)
pairs = [p.split(":") for p in a[0].split()]
rate = sorted(float(f) / float(h) for h, f, _, _ in pairs)
p99 = sorted(ms(fp) / ms(hp) for _, _, hp, fp in pairs)
def median(xs):
    if not xs:
        return "n/a"
    mid = xs[len(xs) // 2] if len(xs) % 2 else (xs[len(xs) // 2 - 1] + xs[len(xs) // 2]) / 2
    return f"{mid:.2f} (pairs {xs[0]:.2f}–{xs[-1]:.2f})"
rest_us, grpc_us = float(a[1]), float(a[2])
gh, rest, gs, ws = (float(x) for x in a[3:7])
idle, peak, fmt = int(a[7]), int(a[8]), a[9]
core_ns = float(a[10])
packed_us = float(a[11])
gs_many, ws_many, per_message = float(a[12]), float(a[13]), a[14]
grpc_packed_us = float(a[15])
rows = [
    ("REST FK / healthz req/s (wrk, 64 conn)", ">= 0.9", median(rate)),
    ("REST FK p99 / healthz p99 (wrk, 64 conn)", "<= 1.2", median(p99)),
    (f"10,000-pose batch, {fmt}, REST µs/pose", "<= 1.0", f"{rest_us:.3f}"),
    (f"10,000-pose batch, {fmt}, gRPC µs/pose", "<= 0.4", f"{grpc_us:.3f}"),
    (f"gRPC stream ({fmt}, 16) / gRPC health (16)", ">= 20", f"{gs / gh:.1f}"),
    (f"WebSocket ({fmt}, 16) / REST FK (16)", ">= 8", f"{ws / rest:.1f}"),
    (f"gRPC stream, {per_message} per message / health", "report", f"{gs_many / gh:.1f}"),
    (f"WebSocket, {per_message} per message / REST FK", "report", f"{ws_many / rest:.1f}"),
    (f"gRPC 10k {fmt} batch / core batch, per pose", "<= 10", f"{grpc_us * 1000 / core_ns:.1f} (core {core_ns:.1f} ns)"),
    (f"gRPC 10k {fmt} batch packed / core, per pose", "<= 10", f"{grpc_packed_us * 1000 / core_ns:.1f}"),
    (f"gRPC 10k {fmt} batch packed / repeated", "report", f"{grpc_packed_us / grpc_us:.2f}"),
    (f"REST 10k {fmt} batch / gRPC's, per pose", "<= 2.5", f"{rest_us / grpc_us:.2f}"),
    (f"REST 10k {fmt} batch packed / JSON, per pose", "report", f"{packed_us / rest_us:.2f}"),
    (f"REST 10k {fmt} batch packed / gRPC's, per pose", "report", f"{packed_us / grpc_us:.2f}"),
    ("RSS idle MB", "<= 30", str(idle)),
    ("RSS peak MB over the whole run", "<= 100", str(peak)),
]
for name, goal, got in rows:
    print(f"{name:<46} goal {goal:<7} measured {got}")
PY

echo
echo "# CPU per request or message, server and load generator (this run; kinserve-load rows over warm-up and run, counted at the run's rate)"
python3 - "$split_log" "$DURATION" "$WARMUP" <<'PY'
import sys
from collections import defaultdict
def secs(v):
    for unit, k in (("ms", 1e-3), ("s", 1.0), ("m", 60.0)):
        if v.endswith(unit):
            return float(v[: -len(unit)]) * k
    return float(v)
duration, warmup = secs(sys.argv[2]), secs(sys.argv[3])
server, gen, count = defaultdict(float), defaultdict(float), defaultdict(float)
for line in open(sys.argv[1]):
    f = line.split()
    if len(f) == 3 and f[1] == "answered" and f[2]:
        # wrk counts its whole run; kinserve-load only after the warm-up.
        scale = 1.0 if f[0].startswith("wrk") else (duration + warmup) / duration
        count[f[0]] += float(f[2]) * scale
    elif len(f) == 5:
        server[f[0]] += float(f[1]) - float(f[2])
        gen[f[0]] += float(f[3]) - float(f[4])
per = {}
for name in sorted(count):
    n = count[name]
    if n <= 0:
        continue
    s, g = server[name] * 1e6 / n, gen[name] * 1e6 / n
    per[name] = s + g
    print(f"{name:<17} server {s:7.2f} µs  generator {g:7.2f} µs  together {s + g:7.2f} µs")
# What a goal on a ratio of two rows allows the row below it, both
# processes together (they share the cores).
for row, base, goal, what in (("grpc-stream", "grpc-health", 20, "gRPC stream ÷ health >= 20"),
                              ("ws", "rest", 8, "WebSocket ÷ REST FK >= 8"),
                              ("wrk-fk", "wrk-healthz", 0.9, "REST FK ÷ /healthz >= 0.9 (wrk)")):
    if row in per and base in per:
        print(f"{what}: a {row} unit may cost both {per[base] / goal:.2f} µs; it costs {per[row]:.2f}")
PY
tls_vs_plain
echo
# The floor starts its own kinserve: this run's server is stopped first.
kill "$pid" 2>/dev/null; wait "$pid" 2>/dev/null || true
BIN_DIR=$BIN_DIR DURATION=$DURATION WARMUP=$WARMUP ROBOT=$ROBOT scripts/bench-floor.sh
