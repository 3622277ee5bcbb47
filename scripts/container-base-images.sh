#!/usr/bin/env bash
# Makes the two base images the Dockerfile takes as build arguments, locally,
# for machines that reach no image registry (only Debian's, PyPI's and
# crates.io's package registries):
#
#   runtime base  debootstrap --variant=minbase bookworm, slimmed like
#                 debian:bookworm-slim (no docs, man pages, locales, apt lists),
#                 then `podman import`.
#   builder base  the runtime base + gcc, libc6-dev, ca-certificates and the
#                 host's Rust toolchain (rustc --print sysroot, without share/).
#
# Both are reused when they already exist (--force makes them anew). The
# Debian mirror is read from apt's own configuration at run time.
#
# Usage: scripts/container-base-images.sh [--force]
#   Prints BUILDER_IMAGE=... and RUNTIME_IMAGE=... on its last two lines.
# Also sourced by scripts/container-check.sh, which uses its functions.
#
# Env: KINSERVE_RUNTIME_BASE, KINSERVE_BUILDER_BASE (image names),
#      KINSERVE_CONTAINER_STATE (work directory, default /var/tmp/kinserve-container).
# Runs as root (podman, debootstrap).

set -euo pipefail

KINSERVE_CONTAINER_STATE=${KINSERVE_CONTAINER_STATE:-/var/tmp/kinserve-container}
KINSERVE_SUITE=bookworm

log() { printf '[%s] %s\n' "$(date +%H:%M:%S)" "$*" >&2; }
die() { log "ERROR: $*"; exit 1; }

# --- tools and podman configuration -------------------------------------------

apt_install() {
    # apt_install PKG...: installs those that are missing.
    local missing=() p
    for p in "$@"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
    done
    [ ${#missing[@]} -eq 0 ] && return 0
    log "installing Debian packages: ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

ensure_podman() {
    [ "$(id -u)" -eq 0 ] || die "must run as root (podman, debootstrap)"
    apt_install podman buildah runc debootstrap ca-certificates
    # crun and podman's default ulimits fail on these machines: runc, cgroupfs,
    # a file event log and explicit ulimits.
    local conf=/etc/containers/containers.conf
    local want
    want=$(cat <<'EOF'
# Written by kinserve scripts/container-base-images.sh: crun and podman's
# default ulimits fail on these machines.
[containers]
default_ulimits = ["nofile=20000:20000", "nproc=32768:32768"]

[engine]
runtime = "runc"
cgroup_manager = "cgroupfs"
events_logger = "file"
EOF
)
    if [ ! -f "$conf" ] || [ "$(cat "$conf")" != "$want" ]; then
        if [ -f "$conf" ] && ! grep -q 'Written by kinserve' "$conf"; then
            cp -p "$conf" "$conf.before-kinserve"
            log "kept the previous $conf as $conf.before-kinserve"
        fi
        mkdir -p /etc/containers
        printf '%s\n' "$want" > "$conf"
        log "wrote $conf"
    fi
    podman info >/dev/null 2>&1 || die "podman does not work: $(podman info 2>&1 | tail -3)"
}

# --- image names ---------------------------------------------------------------

host_rust_version() {
    command -v rustc >/dev/null || die "no rustc on the host (its toolchain goes into the builder base)"
    rustc --version | awk '{print $2}'
}

base_image_names() {
    KINSERVE_RUNTIME_BASE=${KINSERVE_RUNTIME_BASE:-localhost/kinserve-base/debian:${KINSERVE_SUITE}-minbase}
    KINSERVE_BUILDER_BASE=${KINSERVE_BUILDER_BASE:-localhost/kinserve-base/rust:$(host_rust_version)-${KINSERVE_SUITE}}
}

# --- runtime base ----------------------------------------------------------------

debian_mirror() {
    # The mirror apt on this host uses for the suite, from apt's configuration.
    local m
    # shellcheck disable=SC2016 # apt's own placeholders
    m=$(apt-get indextargets --format '$(REPO_URI) $(RELEASE)' 2>/dev/null \
        | awk -v s="$KINSERVE_SUITE" '$2 == s {print $1; exit}')
    if [ -z "$m" ]; then
        # Older apt or no index targets yet: read the sources files directly.
        m=$(grep -hE '^(deb |URIs:)' /etc/apt/sources.list /etc/apt/sources.list.d/*.list \
                /etc/apt/sources.list.d/*.sources 2>/dev/null \
            | grep -v security | sed -E 's/^deb (\[[^]]*\] )?//; s/^URIs: *//' | awk '{print $1; exit}')
    fi
    [ -n "$m" ] || die "no Debian mirror found in apt's sources"
    printf '%s\n' "$m"
}

make_runtime_base() {
    local name=$1 dir="$KINSERVE_CONTAINER_STATE/rootfs" mirror
    mirror=$(debian_mirror)
    log "runtime base: debootstrap --variant=minbase $KINSERVE_SUITE (mirror from apt's sources)"
    rm -rf "$dir"
    mkdir -p "$KINSERVE_CONTAINER_STATE"
    if ! debootstrap --variant=minbase "$KINSERVE_SUITE" "$dir" "$mirror" \
            > "$KINSERVE_CONTAINER_STATE/debootstrap.log" 2>&1; then
        tail -20 "$KINSERVE_CONTAINER_STATE/debootstrap.log" >&2
        die "debootstrap failed (log: $KINSERVE_CONTAINER_STATE/debootstrap.log)"
    fi
    # Slim it like debian:bookworm-slim: later installs skip docs, man pages and
    # locales too; apt keeps no caches or lists.
    mkdir -p "$dir/etc/dpkg/dpkg.cfg.d" "$dir/etc/apt/apt.conf.d"
    cat > "$dir/etc/dpkg/dpkg.cfg.d/docker-slim" <<'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/info/*
path-exclude /usr/share/locale/*
path-include /usr/share/locale/locale.alias
path-exclude /usr/share/lintian/*
path-exclude /usr/share/groff/*
EOF
    cat > "$dir/etc/apt/apt.conf.d/docker-clean" <<'EOF'
DPkg::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
APT::Update::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
Dir::Cache::pkgcache "";
Dir::Cache::srcpkgcache "";
Acquire::GzipIndexes "true";
APT::Install-Recommends "false";
EOF
    rm -rf "$dir"/var/cache/apt/archives/*.deb "$dir"/var/cache/apt/*.bin \
           "$dir"/var/lib/apt/lists/* "$dir"/var/cache/debconf/*-old \
           "$dir"/usr/share/man/* "$dir"/usr/share/info/* "$dir"/usr/share/lintian/* \
           "$dir"/var/log/*.log "$dir"/var/log/apt/* "$dir"/var/lib/dpkg/*-old \
           "$dir"/etc/machine-id "$dir"/etc/hostname "$dir"/etc/resolv.conf
    find "$dir/usr/share/locale" -mindepth 1 -maxdepth 1 ! -name locale.alias -exec rm -rf {} +
    find "$dir/usr/share/doc" -mindepth 1 ! -type d ! -name copyright -delete
    find "$dir/usr/share/doc" -mindepth 1 -type d -empty -delete
    : > "$dir/etc/machine-id"
    tar --numeric-owner -C "$dir" -c . \
        | podman import -q --change 'CMD ["/bin/bash"]' \
            --message "debootstrap --variant=minbase $KINSERVE_SUITE, slimmed" - "$name" >/dev/null
    rm -rf "$dir"
    log "runtime base: $name ($(podman image inspect --format '{{.Size}}' "$name" | awk '{printf "%.1f MB", $1/1e6}'))"
}

# --- builder base ------------------------------------------------------------------

make_builder_base() {
    local name=$1 runtime=$2 ctx="$KINSERVE_CONTAINER_STATE/builder-context" sysroot d
    sysroot=$(rustc --print sysroot)
    log "builder base: $runtime + gcc, libc6-dev, ca-certificates + Rust $(host_rust_version) from $sysroot"
    rm -rf "$ctx"
    mkdir -p "$ctx/rust"
    for d in "$sysroot"/*; do
        [ "$(basename "$d")" = share ] && continue # docs, man pages: not needed to build
        # Hard links when on the same file system (fast, no space), copies otherwise.
        cp -al "$d" "$ctx/rust/" 2>/dev/null || cp -a "$d" "$ctx/rust/"
    done
    cat > "$ctx/Containerfile" <<'EOF'
ARG BASE
FROM ${BASE}
RUN apt-get update \
 && apt-get install -y --no-install-recommends gcc libc6-dev ca-certificates \
 && rm -rf /var/lib/apt/lists/*
COPY rust/ /usr/local/rust/
ENV CARGO_HOME=/usr/local/cargo \
    PATH=/usr/local/cargo/bin:/usr/local/rust/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
RUN mkdir -p /usr/local/cargo/bin && rustc --version && cargo --version
EOF
    # No CA mount here: apt fetches over http and verifies signatures, and
    # ca-certificates' postinst must write /etc/ssl/certs.
    if ! podman build --pull=never --format docker --build-arg "BASE=$runtime" \
            -t "$name" "$ctx" > "$KINSERVE_CONTAINER_STATE/builder-base.log" 2>&1; then
        tail -20 "$KINSERVE_CONTAINER_STATE/builder-base.log" >&2
        die "builder base build failed (log: $KINSERVE_CONTAINER_STATE/builder-base.log)"
    fi
    rm -rf "$ctx"
    log "builder base: $name ($(podman image inspect --format '{{.Size}}' "$name" | awk '{printf "%.0f MB", $1/1e6}'))"
}

ensure_base_images() {
    # ensure_base_images [--force]: sets KINSERVE_RUNTIME_BASE and KINSERVE_BUILDER_BASE.
    local force=${1:-}
    base_image_names
    if [ "$force" = --force ] || ! podman image exists "$KINSERVE_RUNTIME_BASE"; then
        make_runtime_base "$KINSERVE_RUNTIME_BASE"
        podman rmi -f "$KINSERVE_BUILDER_BASE" >/dev/null 2>&1 || true # made from the old one
    else
        log "runtime base: reusing $KINSERVE_RUNTIME_BASE"
    fi
    if [ "$force" = --force ] || ! podman image exists "$KINSERVE_BUILDER_BASE"; then
        make_builder_base "$KINSERVE_BUILDER_BASE" "$KINSERVE_RUNTIME_BASE"
    else
        log "builder base: reusing $KINSERVE_BUILDER_BASE"
    fi
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
    ensure_podman
    ensure_base_images "${1:-}"
    echo "BUILDER_IMAGE=$KINSERVE_BUILDER_BASE"
    echo "RUNTIME_IMAGE=$KINSERVE_RUNTIME_BASE"
fi
