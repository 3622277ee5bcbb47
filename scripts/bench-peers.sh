#!/usr/bin/env bash
# kinserve against peers, side by side in one run, as ratios (issue 28):
#   1. core FK in-process against Pinocchio C++ on the same DH tables
#      (PUMA 560, UR5e, Panda, Kinova Gen3): single pose, batch per pose, every
#      frame; kinserve and Pinocchio alternate for ROUNDS rounds;
#   2. REST FK against a FastAPI + uvicorn server (2 workers) computing the same
#      FK with Robotics Toolbox for Python, wrk with 64 connections, alternating.
#   scripts/bench-peers.sh                     # both, 3 rounds each
#   ROUNDS=5 DURATION=10s scripts/bench-peers.sh
#   PEERS=pinocchio scripts/bench-peers.sh     # only the core comparison (or PEERS=fastapi)
#   BIN_DIR=/tmp/old scripts/bench-peers.sh    # kinserve binary of another build for part 2
# Tools: g++, Eigen headers (Debian libeigen3-dev: installed here with apt-get when
# missing), PyPI `pin` (Pinocchio's C++ headers under its cmeel.prefix; nothing of
# its prebuilt libraries is linked, so everything shares one set of flags), and for
# part 2 wrk (Debian wrk), fastapi, uvicorn[standard], roboticstoolbox-python (pip).
# Each side checks its poses against kinserve's before it is timed: the Pinocchio
# program on every exported configuration (max |difference| <= 1e-9), the FastAPI
# peer on one request (position and matrix to 1e-9). See BENCHMARKS.md.
set -euo pipefail
cd "$(dirname "$0")/.."

ROUNDS=${ROUNDS:-3}
ROBOTS=${ROBOTS:-"puma560 ur5e panda kinova_gen3"}
PEERS=${PEERS:-"pinocchio fastapi"}
DURATION=${DURATION:-5s}
REST_ROBOT=${REST_ROBOT:-puma560}
HTTP=127.0.0.1:${HTTP_PORT:-18490}
PEER_HTTP=127.0.0.1:${PEER_PORT:-18491}
CXXFLAGS_PEER=${CXXFLAGS_PEER:-"-O3 -march=native"}
work=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; wait "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT

echo "# kinserve against peers, one run ($(date -u +%Y-%m-%dT%H:%MZ), commit $(git rev-parse --short HEAD 2>/dev/null || echo '?'))"
echo "# CPU: $(lscpu | awk -F: '/Model name/ {gsub(/^ +/, "", $2); print $2; exit}'), $(nproc) cores; load before: $(uptime | sed 's/.*load average: //')"
echo "# the machine may be shared: ratios of alternating rounds, not absolute figures, are what carries"

median() { python3 -c 'import statistics,sys; print(f"{statistics.median(float(x) for x in sys.argv[1:]):.3f}")' "$@"; }

pinocchio_part() {
  [ -d /usr/include/eigen3 ] || { echo "installing libeigen3-dev" >&2; apt-get install -y libeigen3-dev >&2; }
  python3 -c 'import cmeel, pinocchio' 2>/dev/null || { echo "installing PyPI pin" >&2; python3 -m pip install --quiet pin >&2; }
  local prefix pin_version
  prefix=$(python3 -c 'import cmeel, os; print(os.path.join(os.path.dirname(os.path.dirname(cmeel.__file__)), "cmeel.prefix"))')
  pin_version=$(python3 -c 'import pinocchio; print(pinocchio.__version__)')
  [ -f "$prefix/include/pinocchio/multibody.hpp" ] || { echo "no Pinocchio headers under $prefix" >&2; exit 1; }
  cargo build --release --locked -p kinserve-kinematics --example peer_fk >&2
  local target=${CARGO_TARGET_DIR:-./target}
  local peer_fk=$target/release/examples/peer_fk pin_bin=$target/peers/pinocchio_fk
  mkdir -p "$target/peers"
  # Pinocchio's own CMake target sets these definitions (its joint variant has
  # more alternatives than Boost.MPL's preprocessed lists allow).
  local defs="-DNDEBUG -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12"
  local stamp="$CXXFLAGS_PEER $defs $pin_version $(g++ --version | head -1)"
  if [ ! -x "$pin_bin" ] || [ scripts/peers/pinocchio_fk.cpp -nt "$pin_bin" ] || [ "$(cat "$pin_bin.flags" 2>/dev/null)" != "$stamp" ]; then
    echo "compiling scripts/peers/pinocchio_fk.cpp (headers only, $CXXFLAGS_PEER)" >&2
    # shellcheck disable=SC2086
    g++ -std=c++17 $CXXFLAGS_PEER $defs -Wno-stringop-overread -Wno-deprecated-declarations \
      -I"$prefix/include" -I/usr/include/eigen3 scripts/peers/pinocchio_fk.cpp -o "$pin_bin"
    echo "$stamp" >"$pin_bin.flags"
  fi
  # shellcheck disable=SC2086
  "$peer_fk" export "$work" $ROBOTS
  echo
  echo "## 1. core FK in-process: kinserve (peer_fk example, release) vs Pinocchio $pin_version C++ ($CXXFLAGS_PEER, headers only)"
  echo "# ns per pose, median of 7 samples per figure; $ROUNDS alternating rounds (kinserve, Pinocchio, kinserve, ...)"
  echo "# single = one pose (Pinocchio: forwardKinematics + updateFramePlacement of the tool frame);"
  echo "# batch = 10,000 configurations per call, per pose (Pinocchio: the same pair in a loop, pose copied out);"
  echo "# frames = every frame (kinserve: forward_frames_to, as the service computes them; Pinocchio: forwardKinematics, every joint placement)"
  local lines="$work/core.txt"
  : >"$lines"
  for r in $(seq "$ROUNDS"); do
    # shellcheck disable=SC2086
    "$peer_fk" time "$work" $ROBOTS | sed "s/^/$r /" >>"$lines"
    # shellcheck disable=SC2086
    "$pin_bin" "$work" $ROBOTS 2>"$work/check.txt" | sed "s/^/$r /" >>"$lines" || { cat "$work/check.txt" >&2; exit 1; }
  done
  sed 's/^/# check: /' "$work/check.txt"
  python3 - "$lines" <<'PY'
import collections, statistics, sys
t = collections.defaultdict(dict)
for line in open(sys.argv[1]):
    rnd, side, robot, what, ns = line.split()
    t[(robot, what)].setdefault(side, {})[int(rnd)] = float(ns)
robots = list(dict.fromkeys(r for r, _ in t))
goals = {"single": "<= 0.15", "batch": "<= 0.05", "frames": "<= 0.35"}
print(f"{'robot':<12} {'measure':<7} {'kinserve ns':>12} {'Pinocchio ns':>13} {'ratio (median of rounds)':>26}  goal")
for what in ("single", "batch", "frames"):
    meds = []
    for robot in robots:
        k, p = t[(robot, what)]["kinserve"], t[(robot, what)]["pinocchio"]
        ratios = sorted(k[r] / p[r] for r in k if r in p)
        med = statistics.median(ratios)
        meds.append(med)
        print(f"{robot:<12} {what:<7} {statistics.median(k.values()):12.1f} {statistics.median(p.values()):13.1f} "
              f"{med:8.3f} (rounds {ratios[0]:.3f}–{ratios[-1]:.3f})  {goals[what]}")
    print(f"{'all four':<12} {what:<7} {'':>12} {'':>13} {min(meds):8.3f}–{max(meds):.3f}")
PY
}

fastapi_part() {
  command -v wrk >/dev/null || { echo "wrk not installed (apt-get install wrk): FastAPI part skipped"; return; }
  python3 -c 'import fastapi, uvicorn, uvloop, httptools, roboticstoolbox' 2>/dev/null || {
    echo "installing fastapi, uvicorn[standard], roboticstoolbox-python" >&2
    python3 -m pip install --quiet fastapi 'uvicorn[standard]' roboticstoolbox-python >&2
  }
  local bin_dir=${BIN_DIR:-}
  if [ -z "$bin_dir" ]; then
    cargo build --release --locked --bin kinserve >&2
    bin_dir=${CARGO_TARGET_DIR:-./target}/release
  fi
  mkdir -p "$work/data"
  KINSERVE_HTTP_ADDR=$HTTP KINSERVE_GRPC_ADDR=127.0.0.1:${GRPC_PORT:-18492} KINSERVE_DATA_DIR="$work/data" \
    KINSERVE_MAX_CONCURRENT_REQUESTS=4096 KINSERVE_CLIENT_SHARE_PERCENT=100 \
    RUST_LOG=warn "$bin_dir/kinserve" serve 2>"$work/kinserve.log" &
  pids+=($!)
  PEER_ROBOT=$REST_ROBOT python3 -m uvicorn --app-dir scripts/peers fastapi_fk:app --host "${PEER_HTTP%:*}" \
    --port "${PEER_HTTP#*:}" --workers 2 --log-level warning --no-access-log 2>"$work/peer.log" &
  pids+=($!)
  for url in "http://$HTTP/readyz" "http://$PEER_HTTP/healthz"; do
    for _ in $(seq 300); do curl -fs "$url" >/dev/null 2>&1 && break; sleep 0.2; done
    curl -fs "$url" >/dev/null || { echo "$url did not come up" >&2; cat "$work/kinserve.log" "$work/peer.log" >&2; exit 1; }
  done
  local body='{"joints": [0.1, -0.5, 0.7, 0.2, 0.3, -0.1]}'
  local ours theirs
  ours=$(curl -fs -H 'Content-Type: application/json' -d "$body" "http://$HTTP/v1/robots/$REST_ROBOT/fk")
  theirs=$(curl -fs -H 'Content-Type: application/json' -d "$body" "http://$PEER_HTTP/v1/robots/$REST_ROBOT/fk")
  python3 - "$ours" "$theirs" <<'PY'
import json, sys
a, b = (json.loads(x)["pose"] for x in sys.argv[1:3])
d = max(abs(x - y) for ra, rb in zip(a["matrix"], b["matrix"]) for x, y in zip(ra, rb))
d = max(d, max(abs(x - y) for x, y in zip(a["position"], b["position"])))
print(f"# check: FastAPI peer vs kinserve, max |difference| of matrix and position: {d:.3g}")
sys.exit(0 if d <= 1e-9 else 1)
PY
  echo
  echo "## 2. REST FK: kinserve vs FastAPI $(python3 -c 'import fastapi; print(fastapi.__version__)') + uvicorn $(python3 -c 'import uvicorn; print(uvicorn.__version__)') (2 workers, uvloop/httptools) + Robotics Toolbox $(python3 -c 'import roboticstoolbox; print(roboticstoolbox.__version__)')"
  echo "# wrk -t2 -c64 -d$DURATION, POST /v1/robots/$REST_ROBOT/fk, $ROUNDS alternating rounds; both servers up, each measured alone"
  local lua="$work/fk.lua"
  cat >"$lua" <<LUA
wrk.method = "POST"
wrk.body   = '$body'
wrk.headers["Content-Type"] = "application/json"
LUA
  wrk_rate() {
    local out
    out=$(wrk -t2 -c64 -d"$DURATION" -s "$lua" "$1")
    if echo "$out" | grep -q 'Non-2xx'; then echo "$1: error answers under wrk" >&2; echo "$out" >&2; exit 1; fi
    echo "$out" | awk '/Requests\/sec/ {print $2}'
  }
  local rps=()
  for r in $(seq "$ROUNDS"); do
    local k p
    k=$(wrk_rate "http://$HTTP/v1/robots/$REST_ROBOT/fk")
    p=$(wrk_rate "http://$PEER_HTTP/v1/robots/$REST_ROBOT/fk")
    echo "round $r: kinserve $k req/s, FastAPI $p req/s, ratio $(python3 -c "print(f'{$k / $p:.1f}')")"
    rps+=("$(python3 -c "print($k / $p)")")
  done
  echo "REST FK kinserve / FastAPI (median of rounds): $(median "${rps[@]}")"
}

for peer in $PEERS; do
  case $peer in
    pinocchio) pinocchio_part ;;
    fastapi) fastapi_part ;;
    *) echo "unknown peer $peer (pinocchio, fastapi)" >&2; exit 2 ;;
  esac
done
echo
echo "# load after: $(uptime | sed 's/.*load average: //')"
