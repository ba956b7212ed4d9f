#!/usr/bin/env bash
# Data-parallel training throughput on this machine.
#
#   scripts/bench_distributed.sh BUILD_DIR [STEPS=150] [ROUNDS=2]
#
# Trains the default BSMS config (configs/train/disks2d-bsms.json: latent 32, 4 levels) and the
# same with latent 128 on a small disks2d dataset (generated once into
# runs/bench-distributed/data, ~355 nodes per mesh) for STEPS steps in each layout:
#   1 rank x 2 threads (batch 1 and batch 2), 2 ranks x 1 thread, 2 ranks x 2 threads (batch 1
#   per rank),
# ROUNDS times, alternating, and prints the median ms per step of each run (train_stats.json,
# rank 0's clock), steps/s, samples/s and rank 0's time in the gradient all-reduce per step
# (waiting for the slower rank included). Then the all-reduce alone against model size
# (bench_allreduce: 2 ranks on loopback).
set -euo pipefail
build=${1:?usage: $0 BUILD_DIR [STEPS] [ROUNDS]}
steps=${2:-150}
rounds=${3:-2}
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bsms=$root/$build/bsms
[[ -x $bsms ]] || bsms=$build/bsms
[[ -x $bsms ]] || { echo "bench_distributed: $build/bsms not found; build first (make build)" >&2; exit 2; }
work=$root/runs/bench-distributed
mkdir -p "$work"
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), $(nproc) cores; load: $(cut -d' ' -f1-3 /proc/loadavg)"
if [[ ! -f $work/data/train.h5 ]]; then
  "$bsms" generate "$root/configs/families/disks2d.json" --out "$work/data" --trajectories 8 \
    --split 6:1:1 --set frames=24 --threads 2 >"$work/generate.log" 2>&1
fi

run() { # run NAME NPROC THREADS BATCH LATENT
  local name=$1 nproc=$2 threads=$3 batch=$4 latent=$5
  rm -rf "${work:?}/$name"
  "$bsms" train "$root/configs/train/disks2d-bsms.json" --set data="$work/data" \
    --set steps="$steps" --set valid_every="$steps" --set valid_samples=1 \
    --set normalizer_steps=5 --set optimizer.batch_size="$batch" --set time_budget_s=0 --set model.latent="$latent" \
    --threads "$threads" --nproc "$nproc" --out "$work/$name" >"$work/$name.log" 2>&1 ||
    { cat "$work/$name.log"; exit 1; }
  local stats=$work/$name/train_stats.json
  field() { sed -n "s/.*\"$1\": *\([0-9.eE+-]*\).*/\1/p" "$stats" | head -1; }
  local ms ar params
  ms=$(field train_ms_per_step)
  ar=$(field allreduce_ms_per_step)
  params=$(field num_parameters)
  awk -v l="$latent" -v p="$params" -v n="$nproc" -v t="$threads" -v b="$batch" -v ms="$ms" \
    -v ar="${ar:--}" 'BEGIN {
    printf "| %d (%d) | %d x %d | %d | %d | %.1f | %.2f | %.2f | %s |\n", l, p, n, t, b, n * b, ms,
      1000 / ms, 1000 * n * b / ms, (ar == "-" ? "-" : sprintf("%.1f", ar)) }'
}

echo "BSMS, $steps steps per run, median of rank 0's step time per run"
echo "| latent (parameters) | ranks x threads | batch per rank | samples/step | ms/step | steps/s | samples/s | all-reduce ms/step |"
echo "|---|---|---|---|---|---|---|---|"
for round in $(seq "$rounds"); do
  for latent in 32 128; do
    run r${round}_l${latent}_1x2_b1 1 2 1 "$latent"
    run r${round}_l${latent}_1x2_b2 1 2 2 "$latent"
    run r${round}_l${latent}_2x1_b1 2 1 1 "$latent"
    run r${round}_l${latent}_2x2_b1 2 2 1 "$latent"
  done
done
echo
OMP_WAIT_POLICY=PASSIVE "$root/$build/bench/bench_allreduce" 2 60
