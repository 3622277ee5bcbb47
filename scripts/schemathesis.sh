#!/usr/bin/env bash
# API fuzzing from the OpenAPI document with schemathesis (https://schemathesis.io).
#
#   scripts/schemathesis.sh                     # bounded run, default settings
#   ST_MAX_EXAMPLES=200 ST_MAX_TIME=900 scripts/schemathesis.sh
#   scripts/schemathesis.sh --include-path-regex fk   # extra args go to `st run`
#
# Builds the release server, starts it on free loopback ports with a temporary
# data directory, runs `st run <server>/openapi.json` and stops the server.
# Checks: no 5xx ever (not_a_server_error), and every response is documented
# and matches the document: status code, content type, headers and body schema.
# Fails as well if the server log shows a panic.
#
# Uses an `st` (schemathesis 4.x) on PATH if there is one, else a venv under
# target/schemathesis-venv with `pip install 'schemathesis>=4,<5'`.
#
# Environment:
#   ST_MAX_EXAMPLES  test cases per operation and phase (default 50)
#   ST_MAX_TIME      time budget of the whole run in seconds (default 300)
#   ST_SEED          random seed (default: random; printed by st for replay)
#   ST_CHECKS        comma-separated schemathesis checks (default below)
#   ST_PHASES        phases (default examples,coverage,fuzzing,stateful)
# Reports (JUnit, NDJSON events) and the server log go to target/schemathesis/.
set -euo pipefail

cd "$(dirname "$0")/.."
root=$(pwd)

ST_MAX_EXAMPLES=${ST_MAX_EXAMPLES:-50}
ST_MAX_TIME=${ST_MAX_TIME:-300}
ST_PHASES=${ST_PHASES:-examples,coverage,fuzzing,stateful}
ST_CHECKS=${ST_CHECKS:-not_a_server_error,status_code_conformance,content_type_conformance,response_headers_conformance,response_schema_conformance,negative_data_rejection,unsupported_method,allow_header_conformance,use_after_free,ensure_resource_availability}
out="$root/target/schemathesis"
mkdir -p "$out"

# --- schemathesis -----------------------------------------------------------
st_ok() { "$1" --version 2>/dev/null | grep -Eq 'version 4\.'; }
if command -v st >/dev/null 2>&1 && st_ok st; then
    ST=st
else
    venv="$root/target/schemathesis-venv"
    if ! st_ok "$venv/bin/st"; then
        echo "schemathesis.sh: installing schemathesis into $venv" >&2
        python3 -m venv "$venv"
        "$venv/bin/pip" install --quiet --upgrade pip
        "$venv/bin/pip" install --quiet 'schemathesis>=4,<5'
    fi
    ST="$venv/bin/st"
fi
echo "schemathesis.sh: $("$ST" --version)" >&2

# --- server -----------------------------------------------------------------
cargo build --release --bin kinserve

free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}
http_port=$(free_port)
grpc_port=$(free_port)
data_dir=$(mktemp -d "${TMPDIR:-/tmp}/kinserve-st.XXXXXX")
server_log="$out/server.log"

KINSERVE_HTTP_ADDR="127.0.0.1:$http_port" \
KINSERVE_GRPC_ADDR="127.0.0.1:$grpc_port" \
KINSERVE_DATA_DIR="$data_dir" \
KINSERVE_ROBOTS_DIR="$root/robots" \
    "$root/target/release/kinserve" serve >"$server_log" 2>&1 &
server_pid=$!

cleanup() {
    if kill -0 "$server_pid" 2>/dev/null; then
        kill -TERM "$server_pid" 2>/dev/null || true
        wait "$server_pid" 2>/dev/null || true
    fi
    rm -rf "$data_dir"
}
trap cleanup EXIT

base="http://127.0.0.1:$http_port"
ready=0
for _ in $(seq 1 100); do
    if curl -fsS "$base/readyz" >/dev/null 2>&1; then
        ready=1
        break
    fi
    if ! kill -0 "$server_pid" 2>/dev/null; then
        break
    fi
    sleep 0.2
done
if [ "$ready" -ne 1 ]; then
    echo "schemathesis.sh: server did not become ready; log:" >&2
    cat "$server_log" >&2
    exit 1
fi
echo "schemathesis.sh: server ready at $base (pid $server_pid, data $data_dir)" >&2

# --- run --------------------------------------------------------------------
st_args=(
    run "$base/openapi.json"
    --checks "$ST_CHECKS"
    --phases "$ST_PHASES"
    --max-examples "$ST_MAX_EXAMPLES"
    --max-time "$ST_MAX_TIME"
    --request-timeout 30
    --workers 2
    --report junit,ndjson
    --report-dir "$out"
)
if [ -n "${ST_SEED:-}" ]; then
    st_args+=(--seed "$ST_SEED")
fi
set +e
# From $out, so that schemathesis' .schemathesis/ cache stays out of the tree.
(cd "$out" && "$ST" "${st_args[@]}" "$@")
rc=$?
set -e

if grep -q "handler panicked" "$server_log"; then
    echo "schemathesis.sh: the server log shows a panic:" >&2
    grep -n "handler panicked" "$server_log" | head -20 >&2
    rc=1
fi
if ! kill -0 "$server_pid" 2>/dev/null; then
    echo "schemathesis.sh: the server died during the run; log in $server_log" >&2
    rc=1
fi
echo "schemathesis.sh: exit $rc (reports and server log in $out)" >&2
exit "$rc"
