#!/usr/bin/env bash
# The crate graph enforces the layers: each crate's normal (non-dev)
# dependency tree must not contain the crates it is forbidden to depend on.
# Fails naming the crate and the forbidden dependency. Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

check() {
    local crate=$1
    shift
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
check kinserve-kinematics serde tokio axum tonic prost hyper tower utoipa kinserve-model kinserve || status=1
check kinserve-model tokio axum tonic prost hyper tower reqwest kinserve || status=1
check kinserve hdrhistogram reqwest criterion proptest kinserve-load kinserve-testkit || status=1
exit "$status"
