#!/usr/bin/env bash
# kinserve beside its floor (issue 28, "the wire as the only cost").
#   scripts/bench-floor.sh
#   FLOOR_ROUNDS=5 DURATION=5s BIN_DIR=target/release scripts/bench-floor.sh
# Starts kinserve and kinserve-floor (crates/kinserve-load/src/bin/floor.rs:
# the same stack, messages and bytes on the wire, and nothing between the
# socket and the work) on loopback, and alternates the two servers, round
# after round, over the rows behind the per-request goals: gRPC health and
# the FK stream (16 connections, 32 messages in flight, `matrix`), the
# 10,000-configuration packed gRPC batch (one connection), wrk on /healthz
# and on REST FK (64 connections). Prints every round; then, medians over
# the rounds, each server's goal ratios, each row's kinserve ÷ floor, and
# the CPU per request or message of the server and of the load generator
# (they share the cores). A goal the floor misses is out of reach of any
# server on this stack, with this load generator, on this machine.
# Also run at the end of scripts/bench.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/bench-lib.sh
source scripts/bench-lib.sh

DURATION=${DURATION:-5s}
WARMUP=${WARMUP:-1s}
ROBOT=${ROBOT:-puma560}
BIN_DIR=${BIN_DIR:-}
if [ -z "$BIN_DIR" ]; then
  cargo build --release --bins --locked >&2
  BIN_DIR=./target/release
fi
if [ ! -x "$BIN_DIR/kinserve-floor" ] || [ ! -f "robots/$ROBOT.json" ]; then
  echo "# no $BIN_DIR/kinserve-floor or robots/$ROBOT.json: the floor comparison is skipped"
  exit 0
fi
K_HTTP=127.0.0.1:${FLOOR_K_HTTP_PORT:-18580}
K_GRPC=127.0.0.1:${FLOOR_K_GRPC_PORT:-18551}
F_HTTP=127.0.0.1:${FLOOR_HTTP_PORT:-18590}
F_GRPC=127.0.0.1:${FLOOR_GRPC_PORT:-18561}

dir=$(mktemp -d)
env KINSERVE_HTTP_ADDR=$K_HTTP KINSERVE_GRPC_ADDR=$K_GRPC KINSERVE_DATA_DIR=$dir/data "${SERVER_ENV[@]}" \
  "$BIN_DIR/kinserve" serve 2>"$dir/kinserve.log" &
k_pid=$!
f_pid=""
trap 'kill $k_pid $f_pid 2>/dev/null; wait $k_pid $f_pid 2>/dev/null; rm -rf "$dir"' EXIT
wait_ready "$dir/kinserve.log" "http://$K_HTTP/readyz"
# The floor answers REST FK with kinserve's own answer to the same body.
curl -fs -X POST -H 'content-type: application/json' -d "$FK_BODY" \
  "http://$K_HTTP/v1/robots/$ROBOT/fk" >"$dir/fk.json"
"$BIN_DIR/kinserve-floor" --robot-file "robots/$ROBOT.json" --fk-answer "$dir/fk.json" \
  --http-addr "$F_HTTP" --grpc-addr "$F_GRPC" 2>"$dir/floor.log" &
f_pid=$!
wait_ready "$dir/floor.log" "http://$F_HTTP/healthz"
lua=$dir/fk.lua
fk_lua "$lua"

# The generator's CPU: `row` runs in a `$(…)` subshell of its own, which
# runs the generator and reads `children_cpu` (bench-lib.sh) before and after
# it: both readings are that subshell's, so the difference is the
# generator's (with its small JSON filter).
# row WHO NAME PID CMD...: runs CMD (a generator printing "answered per_s"),
# prints its rate and appends "WHO NAME per_s server_us generator_us" (CPU
# per request or message over the whole command, warm-up included) to $dir/rows.
row() {
  local who=$1 name=$2 spid=$3 s0 g0 s1 out
  shift 3
  s0=$(cpu_of "$spid"); children_cpu "$dir/times"; g0=$children_s
  out=$("$@")
  s1=$(cpu_of "$spid"); children_cpu "$dir/times"
  echo "$who $name $out $s0 $s1 $g0 $children_s" >>"$dir/rows"
  echo "${out#* }"
}
# Warm-up ÷ run: kinserve-load counts answers after the warm-up only.
warm=$(python3 -c "
s = lambda v: float(v[:-2]) / 1e3 if v.endswith('ms') else float(v[:-1])
print(s('$WARMUP') / s('$DURATION'))")
# kinserve-load against gRPC at $1; prints "units_over_the_whole_run per_s".
grpc_load() {
  "$BIN_DIR/kinserve-load" --grpc-addr "$1" --robot "$ROBOT" --duration "$DURATION" --warmup "$WARMUP" \
    --pose-format matrix --json "${@:2}" | python3 -c '
import json, sys
r = json.load(sys.stdin)
assert not r["errors"] and r["sent"] == r["answered"], (r["errors"], r["sent"], r["answered"])
per_s = r["poses_per_s"] if r["target"] == "grpc-batch-packed" else r["requests_per_s"]
print(r["answered"] * (1 + float(sys.argv[1])), per_s)' "$warm"
}
# wrk at 64 connections on URL ($2, with the FK script when $1 is fk); prints "requests req_per_s".
wrk_load() {
  local script=()
  [ "$1" = fk ] && script=(-s "$lua")
  wrk -t2 -c64 -d"$DURATION" "${script[@]}" "$2" | awk '/requests in/ {n = $1} /Requests\/sec/ {r = $2} END {print n, r}'
}

echo "# kinserve beside kinserve-floor (the same stack without anything between the socket and the work)"
echo "# machine: $(nproc) cores, $(awk '/model name/ {sub(/.*: /, ""); print; exit}' /proc/cpuinfo)"
echo "# robot $ROBOT; $DURATION per row after $WARMUP warm-up (wrk: none); rounds alternate the servers"
for round in $(seq "${FLOOR_ROUNDS:-3}"); do
  for who in kinserve floor; do
    if [ $who = kinserve ]; then spid=$k_pid http=$K_HTTP grpc=$K_GRPC; else spid=$f_pid http=$F_HTTP grpc=$F_GRPC; fi
    h=$(row $who grpc-health "$spid" grpc_load "$grpc" --target grpc-health --concurrency 16)
    s=$(row $who grpc-stream "$spid" grpc_load "$grpc" --target grpc-stream --concurrency 16 --pipeline 32)
    b=$(row $who grpc-batch-packed "$spid" grpc_load "$grpc" --target grpc-batch-packed --concurrency 1 --batch-size 10000)
    if command -v wrk >/dev/null; then
      wh=$(row $who wrk-healthz "$spid" wrk_load healthz "http://$http/healthz")
      wf=$(row $who wrk-fk "$spid" wrk_load fk "http://$http/v1/robots/$ROBOT/fk")
    else
      wh=-; wf=-
    fi
    printf 'round %s %-8s gRPC health %s/s, stream %s messages/s, 10k packed batch %s poses/s; wrk /healthz %s/s, FK %s/s\n' \
      "$round" "$who" "$h" "$s" "$b" "$wh" "$wf"
  done
done
core_ns=$("$BIN_DIR/kinserve" bench --robot "$ROBOT" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["batch_ns_per_pose"])')

python3 - "$dir/rows" "$core_ns" <<'PY'
import sys
from collections import defaultdict
rate, cpu = defaultdict(list), defaultdict(list)  # (who, row) -> per round
for line in open(sys.argv[1]):
    who, name, units, per_s, s0, s1, g0, g1 = line.split()
    rate[who, name].append(float(per_s))
    units = float(units) * (10_000 if name == "grpc-batch-packed" else 1)
    cpu[who, name].append(((float(s1) - float(s0)) * 1e6 / units, (float(g1) - float(g0)) * 1e6 / units))
core_ns = float(sys.argv[2])
def median(xs):
    xs = sorted(xs)
    m = len(xs) // 2
    return xs[m] if len(xs) % 2 else (xs[m - 1] + xs[m]) / 2
def ratio(who, a, b):
    return [x / y for x, y in zip(rate[who, a], rate[who, b])]
print(f"\n# goal ratios, median of rounds (range); core batch {core_ns:.1f} ns per pose")
goals = (("gRPC stream (16, matrix) ÷ gRPC health (16)", ">= 20", lambda w: ratio(w, "grpc-stream", "grpc-health")),
         ("REST FK ÷ /healthz (wrk, 64 conn)", ">= 0.9", lambda w: ratio(w, "wrk-fk", "wrk-healthz")),
         ("gRPC 10k packed batch per pose ÷ core", "<= 10", lambda w: [1e9 / x / core_ns for x in rate[w, "grpc-batch-packed"]]))
for name, goal, f in goals:
    cells = []
    for who in ("kinserve", "floor"):
        xs = f(who)
        cells.append(f"{who} {median(xs):.2f} ({min(xs):.2f}–{max(xs):.2f})" if xs else f"{who} n/a")
    print(f"{name:<44} goal {goal:<6} {'; '.join(cells)}")
print("\n# each row: kinserve ÷ floor (rate, median of rounds); CPU per request, message or pose, µs, server + generator (medians)")
for name in ("grpc-health", "grpc-stream", "grpc-batch-packed", "wrk-healthz", "wrk-fk"):
    if not rate["floor", name]:
        continue
    r = median([k / f for k, f in zip(rate["kinserve", name], rate["floor", name])])
    cells = []
    for who in ("kinserve", "floor"):
        s, g = median([c[0] for c in cpu[who, name]]), median([c[1] for c in cpu[who, name]])
        cells.append(f"{who} {s:.3f} + {g:.3f}")
    print(f"{name:<18} kinserve ÷ floor {r:.2f}   {';  '.join(cells)}")
PY
