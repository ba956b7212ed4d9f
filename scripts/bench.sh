#!/usr/bin/env bash
# Benchmarks (Google Benchmark; medians reported). Usage: scripts/bench.sh BUILD_DIR [THREADS] [WHICH]
# WHICH: preprocess | models | mpm | startup | all (default all). Prints the machine, threads and inputs
# with the figures; JSON copies go to runs/bench/bench_<which>.json.
set -euo pipefail

if [[ $# -lt 1 ]]; then
  echo "usage: $0 BUILD_DIR [THREADS] [preprocess|models|mpm|startup|all]" >&2
  exit 2
fi
build_dir=$1
threads=${2:-$(nproc)}
which=${3:-all}
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
mkdir -p "$root/runs/bench"
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), $(nproc) cores; threads: $threads; load: $(cut -d' ' -f1-3 /proc/loadavg)"

run() {
  local name=$1
  shift
  local exe=$build_dir/bench/bench_$name
  [[ -x $exe ]] || { echo "bench: $exe not found; build first (make build)" >&2; exit 2; }
  # The wait policy the bsms executable sets for itself (core/runtime.hpp).
  OMP_NUM_THREADS=$threads OMP_WAIT_POLICY=PASSIVE GOMP_SPINCOUNT=100000 \
    BSMS_BENCH_THREADS=$threads "$exe" \
    --benchmark_out="$root/runs/bench/bench_$name.json" --benchmark_out_format=json \
    --benchmark_counters_tabular=true "$@"
}

if [[ $which == preprocess || $which == all ]]; then
  echo "== preprocess: structured triangulated squares (CloseCenter, --levels auto) of 10K..1M nodes;"
  echo "   a 1M-node square written by gmsh (.msh 4.1) read + built; exact MinAve on 50K nodes;"
  echo "   original Python (docs/design.md, CloseCenter 2D): 22K nodes 0.39 s, 243K nodes 6.4 s"
  run preprocess | grep -E 'median|Benchmark|^-'
fi
if [[ $which == models || $which == all ]]; then
  echo "== models: BSMS-GNN and MeshGraphNets, latent 128, train step (forward+backward+Adam) and"
  echo "   inference step on 2.6K-node (5 levels) and 22K-node (7 levels) triangle meshes;"
  echo "   original PyTorch BSMS-GNN (tuned): 2.6K 0.60-0.71 s train, 0.18-0.21 s infer; 22K 12.3 s / 2.56 s"
  run models | grep -E 'median|Benchmark|^-'
fi
if [[ $which == mpm || $which == all ]]; then
  echo "== mpm: particle-steps per second, UMLS vs regular-grid quadratic B-spline, 2D and 3D"
  run mpm | grep -E 'median|Benchmark|^-|mean'
fi
if [[ $which == startup || $which == all ]]; then
  echo "== start-up: median wall time of 10 runs of each command, environment as a user's (no"
  echo "   OMP_* or OPENBLAS_* set); info reads a small multilevel file. The front end runs info,"
  echo "   report, export, preprocess itself; simulate/generate go on to bsms-solver (libgmsh),"
  echo "   train/rollout/experiment to bsms-torch (LibTorch) (src/cli/programs.hpp)"
  bsms=$build_dir/bsms
  small=$root/runs/bench/startup_plate.h5
  [[ -f $small ]] || "$bsms" preprocess --mesh "$root/configs/geometry/plate_hole.geo" --out "$small" >/dev/null
  startup() {
    local times=() start end
    for _ in 1 2 3 4 5 6 7 8 9 10; do
      start=$(date +%s%N)
      env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT -u OPENBLAS_CORETYPE "$bsms" "$@" >/dev/null 2>&1
      end=$(date +%s%N)
      times+=($(((end - start) / 1000)))
    done
    local median
    median=$(printf '%s\n' "${times[@]}" | sort -n | sed -n '5,6p' | awk '{s += $1} END {printf "%.1f", s / 2 / 1000}')
    printf '  %-28s %8s ms\n' "bsms $*" "$median"
  }
  startup --version
  startup --help
  startup info "$small"
  startup preprocess --help
  startup simulate --help
  startup generate --help
  startup train --help
fi
