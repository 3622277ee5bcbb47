# kinserve container image.
#
#   docker build -t kinserve .
#   docker run --rm -p 8080:8080 -p 50051:50051 -v kinserve-data:/var/lib/kinserve \
#       -e KINSERVE_API_TOKEN=change-me kinserve
#
# Both base images are build arguments, so the same file builds against a
# public registry (the defaults) and against locally made images
# (scripts/container-check.sh passes its own with --build-arg).
# The builder only needs cargo/rustc >= the project's MSRV, gcc and libc6-dev;
# protoc comes from the protoc-bin-vendored crate.
ARG BUILDER_IMAGE=rust:1.95-slim-bookworm
ARG RUNTIME_IMAGE=debian:bookworm-slim

# ---------------------------------------------------------------------------
FROM ${BUILDER_IMAGE} AS builder

ENV CARGO_INCREMENTAL=0 \
    CARGO_NET_RETRY=10 \
    CARGO_TERM_COLOR=never \
    CARGO_PROFILE_RELEASE_STRIP=symbols
WORKDIR /build

# 1) Dependency layer: only the manifests (the root package and every member
#    crate under crates/), with stub sources in place of the real ones; rebuilt only when Cargo.toml or Cargo.lock change. Every
#    [[bin]]/[[bench]]/[[test]]/[[example]] a manifest names (at its
#    explicit or default path) is listed in .stub-targets and gets a stub,
#    so cargo accepts the manifest as it is without benches/ or tests/ in
#    the build context. The crate downloads live in a cache mount, shared by
#    later builds, not in the layer.
COPY Cargo.toml Cargo.lock ./
COPY crates/kinserve-kinematics/Cargo.toml crates/kinserve-kinematics/
COPY crates/kinserve-model/Cargo.toml crates/kinserve-model/
COPY crates/kinserve-api/Cargo.toml crates/kinserve-api/
COPY crates/kinserve-load/Cargo.toml crates/kinserve-load/
COPY crates/kinserve-testkit/Cargo.toml crates/kinserve-testkit/
COPY crates/kinserve-floor/Cargo.toml crates/kinserve-floor/
RUN --mount=type=cache,id=kinserve-cargo-registry,target=/usr/local/cargo/registry,sharing=locked \
    set -eu; \
    for m in Cargo.toml crates/*/Cargo.toml; do awk -v pre="${m%Cargo.toml}" ' \
      function flush() { if (kind != "") print pre (path != "" ? path : dir[kind] name ".rs"); kind = ""; name = ""; path = "" } \
      BEGIN { dir["bin"] = "src/bin/"; dir["bench"] = "benches/"; dir["test"] = "tests/"; dir["example"] = "examples/" } \
      /^[ \t]*\[\[(bin|bench|test|example)\]\]/ { flush(); kind = $0; gsub(/[][ \t]/, "", kind); next } \
      /^[ \t]*\[/ { flush(); next } \
      kind != "" && /^[ \t]*(name|path)[ \t]*=/ { key = $0; sub(/^[ \t]*/, "", key); sub(/[ \t]*=.*/, "", key); \
        val = $0; sub(/^[^"]*"/, "", val); sub(/".*/, "", val); if (key == "name") name = val; else path = val } \
      END { flush() }' "$m"; done > .stub-targets; \
    mkdir -p src; \
    for d in crates/*/; do mkdir -p "${d}src"; : > "${d}src/lib.rs"; done; \
    echo 'fn main() {}' > crates/kinserve-load/src/main.rs; \
    echo 'fn main() {}' > src/main.rs; \
    : > src/lib.rs; \
    echo 'fn main() {}' > build.rs; \
    while read -r f; do \
      if [ ! -e "$f" ]; then mkdir -p "$(dirname "$f")"; echo 'fn main() {}' > "$f"; fi; \
    done < .stub-targets; \
    cargo build --release --locked -p kinserve --bin kinserve; \
    rm -rf src benches tests examples build.rs crates/*/src crates/*/benches \
      target/release/.fingerprint/kinserve* target/release/build/kinserve* \
      target/release/deps/kinserve* target/release/deps/libkinserve* \
      target/release/kinserve*

# 2) The real sources: only the kinserve binary and the crates it depends on
#    (kinserve-kinematics, kinserve-model, kinserve-api) are compiled here; the load
#    generator and the test kit are workspace members but not built.
#    Targets whose sources stay out of the context (benches, tests) get their
#    stubs again; real files (src/bin/*.rs) are left alone.
COPY build.rs ./
COPY proto ./proto
# robots/ too: build.rs embeds the built-in robots in the binary.
COPY robots ./robots
COPY crates ./crates
COPY src ./src
RUN --mount=type=cache,id=kinserve-cargo-registry,target=/usr/local/cargo/registry,sharing=locked \
    set -eu; \
    while read -r f; do \
      if [ ! -e "$f" ]; then mkdir -p "$(dirname "$f")"; echo 'fn main() {}' > "$f"; fi; \
    done < .stub-targets; \
    cargo build --release --locked -p kinserve --bin kinserve; \
    install -D -m 0755 target/release/kinserve /out/kinserve; \
    /out/kinserve --version

# ---------------------------------------------------------------------------
FROM ${RUNTIME_IMAGE} AS runtime

ARG KINSERVE_UID=10001
ARG KINSERVE_GID=10001

# The service user (fixed uid/gid, no login, no home) and its data directory.
# (--no-log-init: no sparse lastlog/faillog entry for the high uid.)
RUN groupadd --gid "${KINSERVE_GID}" kinserve \
 && useradd --no-log-init --uid "${KINSERVE_UID}" --gid "${KINSERVE_GID}" \
      --home-dir /var/lib/kinserve --no-create-home --shell /usr/sbin/nologin kinserve \
 && mkdir -p /var/lib/kinserve \
 && chown "${KINSERVE_UID}:${KINSERVE_GID}" /var/lib/kinserve \
 && chmod 0750 /var/lib/kinserve

# The binary (built-in robots included) is owned by root: the service can run it, not change it.
COPY --from=builder /out/kinserve /usr/local/bin/kinserve

# Configuration is env only (every `kinserve serve` flag has a KINSERVE_* twin).
# KINSERVE_API_TOKEN has no default: set it at run time to protect mutating calls.
ENV KINSERVE_HTTP_ADDR=0.0.0.0:8080 \
    KINSERVE_GRPC_ADDR=0.0.0.0:50051 \
    KINSERVE_DATA_DIR=/var/lib/kinserve \
    KINSERVE_LOG_FORMAT=json \
    KINSERVE_HEALTHCHECK_ADDR=127.0.0.1:8080

LABEL org.opencontainers.image.title="kinserve" \
      org.opencontainers.image.description="Forward-kinematics microservice (REST and gRPC)"

WORKDIR /var/lib/kinserve
VOLUME ["/var/lib/kinserve"]
EXPOSE 8080 50051
USER ${KINSERVE_UID}:${KINSERVE_GID}
STOPSIGNAL SIGTERM
HEALTHCHECK --interval=10s --timeout=3s --start-period=10s --retries=3 \
    CMD ["/usr/local/bin/kinserve", "healthcheck"]
ENTRYPOINT ["/usr/local/bin/kinserve"]
CMD ["serve"]
