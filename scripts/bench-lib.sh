# Shared by scripts/bench.sh and scripts/bench-floor.sh (sourced, not run).

# The settings of every kinserve the benchmarks start. kinserve-load is one
# client with many connections: it gets every budget (share 100 %), and
# batches queue on the batch slots as a throughput test wants instead of
# being refused by the compute pool (64 permits).
SERVER_ENV=(KINSERVE_MAX_CONCURRENT_REQUESTS=4096 KINSERVE_CLIENT_SHARE_PERCENT=100 KINSERVE_COMPUTE_THREADS=64 RUST_LOG=warn)

# The body of the benchmarks' one REST FK request (PUMA 560's six joints).
FK_BODY='{"joints": [0.1, -0.5, 0.7, 0.2, 0.3, -0.1]}'

# wait_ready LOG CURL_ARGS... : until the readiness URL (last argument) answers, or exit.
wait_ready() {
  local log=$1; shift
  for _ in $(seq 100); do
    curl -fs "$@" >/dev/null 2>&1 && return
    sleep 0.1
  done
  curl -fs "$@" >/dev/null || { echo "server did not start" >&2; cat "$log" >&2; exit 1; }
}

# fk_lua FILE: the wrk script of one REST FK request.
fk_lua() {
  cat >"$1" <<LUA
wrk.method = "POST"
wrk.body   = '$FK_BODY'
wrk.headers["Content-Type"] = "application/json"
LUA
}

# cpu_of PID: CPU seconds (user + system) the process has used so far.
cpu_of() { awk -v hz="$(getconf CLK_TCK)" '{printf "%.2f", ($14 + $15) / hz}' "/proc/$1/stat"; }

# children_cpu FILE: CPU seconds (user + system) of the finished children of
# the shell it runs in, in $children_s (FILE: scratch for `times`, which must
# run in that shell itself, not in a pipe or a `$(…)` of its own).
children_cpu() {
  times >"$1"
  children_s=$(awk 'NR == 2 {s = 0; for (i = 1; i <= 2; i++) {split($i, p, /[ms]/); s += p[1] * 60 + p[2]} printf "%.3f", s}' "$1")
}
