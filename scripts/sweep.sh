#!/usr/bin/env bash
# Model-size sweep on the default scene ("model only what a scene needs"): BSMS-GNN at
# latent 32/64/128 (4 levels) and 3/5 levels (latent 32), MeshGraphNets at latent 32/128, each
# trained for the same wall-clock budget on one dataset, rolled out on its test split, and one
# report whose speed-against-error plot holds every point.
# Usage: scripts/sweep.sh BUILD_DIR DATA_DIR OUT_DIR   (environment: SWEEP_SECONDS (180),
# SWEEP_THREADS (0 = all), SWEEP_POINTS (names of the points to run, default all: bsms-l32 bsms-l64
# bsms-l128 bsms-l32-3lev bsms-l32-5lev mgn-l32 mgn-l128)). DATA_DIR: a disks2d dataset, e.g.
# runs/demo/data after `make demo`.
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
need_args "BUILD_DIR DATA_DIR OUT_DIR" 3 3 "$@"
build_dir=$1
data=$2
out_dir=$3
find_bsms sweep "$build_dir"
[[ -f $data/train.h5 ]] || { echo "sweep: $data/train.h5 not found (run make demo first)" >&2; exit 2; }
seconds=${SWEEP_SECONDS:-180}
threads=${SWEEP_THREADS:-0}
mkdir -p "$out_dir"

# name model latent levels
points=("bsms-l32 bsms 32 4" "bsms-l64 bsms 64 4" "bsms-l128 bsms 128 4" "bsms-l32-3lev bsms 32 3"
        "bsms-l32-5lev bsms 32 5" "mgn-l32 mgn 32 0" "mgn-l128 mgn 128 0")
if [[ -n ${SWEEP_POINTS:-} ]]; then
  chosen=()
  for want in $SWEEP_POINTS; do
    found=
    for point in "${points[@]}"; do [[ ${point%% *} == "$want" ]] && chosen+=("$point") && found=1; done
    [[ -n $found ]] || { echo "sweep: unknown point '$want' in SWEEP_POINTS" >&2; exit 2; }
  done
  points=("${chosen[@]}")
fi
runs=()
for point in "${points[@]}"; do
  read -r name model latent levels <<<"$point"
  run=$out_dir/$name
  runs+=("$run")
  if [[ -f $run/rollout/metrics.json ]]; then continue; fi  # finished earlier: resumable
  rm -rf "$run"
  extra=(--set "model.latent=$latent")
  [[ $model == bsms ]] && extra+=(--set "model.levels=$levels")
  "$bsms" train "$root/configs/train/disks2d-$model.json" --out "$run" --threads "$threads" \
    --set "data=$data" --set "time_budget_s=$seconds" --set steps=10000000 --set valid_every=1000 \
    "${extra[@]}"
  "$bsms" rollout "$run" --split test --threads "$threads"
done
"$bsms" report "${runs[@]}" --out "$out_dir" \
  --title "bsms sweep: latent width and levels on disks2d, ${seconds} s of training each"
echo "sweep: $out_dir/report.md"
