#!/usr/bin/env bash
# The layers, checked three ways; fails if any check fails (all run).
#  1. Crate graph: each crate's normal (non-dev) dependency tree must not
#     contain the crates it is forbidden to depend on. Fails naming the crate
#     and the forbidden dependency. A crate not (yet) in the workspace is
#     skipped with a note.
#  2. The same for the crates of the issue-21 layout (kinserve-api;
#     kinserve-load without the server), kept apart so a failure there is
#     told from one in the established layers.
#  3. Module circles inside every workspace crate (scripts/module_cycles.py;
#     its header states what counts as an edge). Fails naming each circle.
# Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

members=$(cargo metadata --no-deps --format-version 1 --locked |
    python3 -c 'import json, sys; print("\n".join(p["name"] for p in json.load(sys.stdin)["packages"]))')

check() {
    local crate=$1
    shift
    if ! grep -qx "$crate" <<<"$members"; then
        echo "check-layers: $crate is not in the workspace (yet): skipped"
        return 0
    fi
    local tree
    tree=$(cargo tree --locked -p "$crate" -e normal --prefix none --format '{p}' | awk '{print $1}' | sort -u)
    local bad=0
    for forbidden in "$@"; do
        if grep -qx "$forbidden" <<<"$tree"; then
            echo "check-layers: $crate depends on $forbidden (forbidden)" >&2
            bad=1
        fi
    done
    [ "$bad" -eq 0 ] && echo "check-layers: $crate ok (none of: $*)"
    return "$bad"
}

status=0
echo "check-layers: crate dependencies"
check kinserve-kinematics serde tokio axum tonic prost hyper tower utoipa kinserve-model kinserve || status=1
check kinserve-model tokio axum tonic prost hyper tower reqwest kinserve || status=1
check kinserve hdrhistogram reqwest criterion proptest kinserve-load kinserve-testkit || status=1

echo "check-layers: crate dependencies of the API crate layout (issue 21)"
# The wire types and their conversions, without the server or its transports.
check kinserve-api axum tokio-postgres kinserve || status=1
# The load generator talks to a server; it does not link one.
check kinserve-load kinserve axum || status=1
# The benchmarks' floor is the same stack without the server's layers: it
# must not link them (else it would measure them too).
check kinserve-floor kinserve kinserve-load || status=1

echo "check-layers: module circles"
python3 scripts/module_cycles.py --workspace || status=1
exit "$status"
