#!/usr/bin/env bash
# Cross-checks subwave's Loop and midpoint subdivision against MeshLab on the closed corpus
# meshes (../shared/peers/subdiv_ref.py), and the modified butterfly edge class by edge class
# (MeshLab's butterfly is the unmodified 8-point rule, our butterfly-original, compared vertex
# by vertex; the modified butterfly agrees with it on regular edges only, see
# scripts/butterfly_vs_meshlab.py). Needs the peers: bash ../shared/peers/setup.sh
# Usage: scripts/crosscheck-meshlab.sh [LEVELS]   (default 2)
set -euo pipefail
cd "$(dirname "$0")/.."
levels=${1:-2}
P=${PEERS_VENV:-/tmp/subwave-peers}/bin/python
corpus=../shared/data/meshes
out=$(mktemp -d)
cargo build --release -q -p subwave-cli
status=0
for mesh in cheburashka fandisk rocker-arm; do
  for scheme in loop midpoint; do
    "$P" ../shared/peers/subdiv_ref.py "$corpus/$mesh.obj" "$scheme" "$levels" "$out/ref.obj" >/dev/null
    target/release/subwave subdivide "$corpus/$mesh.obj" -o "$out/ours.obj" --scheme "$scheme" \
      --levels "$levels" --boundary opensubdiv >/dev/null 2>&1
    printf '%-12s %-9s ' "$mesh" "$scheme"
    "$P" scripts/nn_distance.py "$out/ref.obj" "$out/ours.obj" || status=1
  done
done
for mesh in cheburashka fandisk rocker-arm; do
  "$P" ../shared/peers/subdiv_ref.py "$corpus/$mesh.obj" butterfly "$levels" "$out/ref.obj" >/dev/null
  target/release/subwave subdivide "$corpus/$mesh.obj" -o "$out/ours.obj" \
    --scheme butterfly-original --levels "$levels" >/dev/null 2>&1
  printf '%-12s %-9s ' "$mesh" "butterfly-original"
  "$P" scripts/nn_distance.py "$out/ref.obj" "$out/ours.obj" || status=1
done
for mesh in cheburashka fandisk rocker-arm woody; do
  "$P" ../shared/peers/subdiv_ref.py "$corpus/$mesh.obj" butterfly 1 "$out/ref.obj" >/dev/null
  target/release/subwave subdivide "$corpus/$mesh.obj" -o "$out/ours.obj" --scheme butterfly \
    --levels 1 >/dev/null 2>&1
  "$P" scripts/butterfly_vs_meshlab.py "$corpus/$mesh.obj" "$out/ref.obj" "$out/ours.obj" || status=1
done
rm -rf "$out"
exit $status
