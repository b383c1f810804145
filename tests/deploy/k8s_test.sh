#!/usr/bin/env bash
# Kubernetes manifests, checked offline (no cluster here): `kubectl kustomize deploy/k8s` renders,
# also with the optional worker-hpa.yaml enabled and with another token; every document passes
# kubernetes-models' schema check (k8s_validate.js) and the cross-document checks of
# k8s_consistency.js, among them that another token rolls out new pods.
# usage: k8s_test.sh NPM_DIR    (NPM_DIR: where kubernetes-models is installed from the pinned
#                               k8s_schema/package-lock.json; reused while the lock is unchanged)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
npm_dir="${1:?usage: k8s_test.sh NPM_DIR}"

fail() { echo "k8s_test: FAIL: $*" >&2; exit 1; }
for tool in kubectl node npm; do
  command -v "$tool" >/dev/null 2>&1 || fail "$tool is not installed (./deploy/install-deps.sh installs it)"
done
work="$(mktemp -d "${TMPDIR:-/tmp}/rtc-k8s.XXXXXX")"
trap 'rm -rf "$work"' EXIT

echo "kubectl: $(kubectl version --client 2>/dev/null | head -n 1)"
timeout 60 kubectl kustomize "$root/deploy/k8s" > "$work/render.yaml" 2> "$work/render.err" ||
  { cat "$work/render.err" >&2; fail "kubectl kustomize deploy/k8s failed"; }
[ ! -s "$work/render.err" ] || { cat "$work/render.err" >&2; fail "kubectl kustomize deploy/k8s printed warnings"; }
echo "rendered deploy/k8s: $(grep -c '^kind:' "$work/render.yaml") documents"

# The optional autoscaler, switched on as kustomization.yaml says.
cp -r "$root/deploy/k8s" "$work/k8s-hpa"
sed -i 's/^  # - worker-hpa.yaml$/  - worker-hpa.yaml/' "$work/k8s-hpa/kustomization.yaml"
grep -q '^  - worker-hpa.yaml$' "$work/k8s-hpa/kustomization.yaml" || fail "kustomization.yaml has no '# - worker-hpa.yaml' line to enable"
timeout 60 kubectl kustomize "$work/k8s-hpa" > "$work/render-hpa.yaml" || fail "kubectl kustomize with worker-hpa.yaml failed"
grep -q '^kind: HorizontalPodAutoscaler$' "$work/render-hpa.yaml" || fail "the render with worker-hpa.yaml has no HorizontalPodAutoscaler"

# Another token: its render must roll both Deployments' pods (k8s_consistency.js compares).
cp -r "$root/deploy/k8s" "$work/k8s-token"
echo "another-token-$$" > "$work/k8s-token/token"
timeout 60 kubectl kustomize "$work/k8s-token" > "$work/render-token.yaml" || fail "kubectl kustomize with another token failed"

# kubernetes-models from the npm registry, pinned by the lock file; installed again only when it changes.
mkdir -p "$npm_dir"
if ! cmp -s "$here/k8s_schema/package-lock.json" "$npm_dir/package-lock.json" || [ ! -d "$npm_dir/node_modules/kubernetes-models" ]; then
  rm -rf "$npm_dir/node_modules" "$npm_dir/package-lock.json"
  cp "$here/k8s_schema/package.json" "$here/k8s_schema/package-lock.json" "$npm_dir/"
  echo "npm ci kubernetes-models into $npm_dir"
  (cd "$npm_dir" && timeout 300 npm ci --no-audit --no-fund --loglevel=error) || fail "npm ci of kubernetes-models failed (is the npm registry reachable?)"
fi

export NODE_PATH="$npm_dir/node_modules"
echo "--- schema check"
timeout 60 node "$here/k8s_validate.js" "$work/render-hpa.yaml" || fail "schema check failed"
echo "--- consistency check"
timeout 60 node "$here/k8s_consistency.js" "$work/render-hpa.yaml" "$work/render-token.yaml" || fail "consistency check failed"
echo "k8s_test: ok"
