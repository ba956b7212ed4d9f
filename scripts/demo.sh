#!/usr/bin/env bash
# The end-to-end demo on the default geometry. Usage: scripts/demo.sh BUILD_DIR OUT_DIR
# Stage 1 (now): mesh configs/geometry/plate_with_holes.geo with gmsh (inside bsms) and build its
# bi-stride multilevel graph, printing the per-level table.
set -euo pipefail

if [[ $# -ne 2 ]]; then
  echo "usage: $0 BUILD_DIR OUT_DIR" >&2
  exit 2
fi
build_dir=$1
out_dir=$2
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bsms=$build_dir/bsms
[[ -x $bsms ]] || { echo "demo: $bsms not found; build first (make build)" >&2; exit 2; }
mkdir -p "$out_dir"

echo "== bsms preprocess: bi-stride multilevel graph of the default plate (MinAve seeding)"
"$bsms" preprocess --mesh "$root/configs/geometry/plate_with_holes.geo" \
  --out "$out_dir/plate_multilevel.h5" --seeding minave --levels auto
echo "demo: wrote $out_dir/plate_multilevel.h5"
