#!/usr/bin/env bash
# Preprocessor benchmarks (medians of 3). Usage: scripts/bench.sh BUILD_DIR [THREADS]
# Prints the machine, thread count and inputs with the figures; a JSON copy goes to
# runs/bench/bench_preprocess.json.
set -euo pipefail

if [[ $# -lt 1 ]]; then
  echo "usage: $0 BUILD_DIR [THREADS]" >&2
  exit 2
fi
build_dir=$1
threads=${2:-$(nproc)}
exe=$build_dir/bench/bench_preprocess
[[ -x $exe ]] || { echo "bench: $exe not found; build first (make build)" >&2; exit 2; }
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
mkdir -p "$root/runs/bench"

echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), $(nproc) cores; threads: $threads"
echo "inputs: structured triangulated squares (CloseCenter, --levels auto) of 10K..1M nodes;"
echo "        a 1M-node square meshed and written by gmsh (.msh 4.1 ASCII), read + built;"
echo "        exact MinAve seed and MinAve build on a 50K-node square;"
echo "        contact enhancement of a 316-pair contact line through all levels of a 100K square."
echo "original Python (DESIGN.md, CloseCenter 2D): 22K nodes 0.39 s, 243K nodes 6.4 s"
OMP_NUM_THREADS=$threads OMP_WAIT_POLICY=PASSIVE "$exe" \
  --benchmark_out="$root/runs/bench/bench_preprocess.json" --benchmark_out_format=json \
  --benchmark_counters_tabular=true "${@:3}" | grep -E 'median|Benchmark|^-|Run on|CPU'
