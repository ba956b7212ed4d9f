#!/usr/bin/env bash
# Training on a full-size MeshGraphNets split without the real data: writes synthetic splits of
# CylinderFlow's size in the published format (1,000 trajectories x 600 frames x ~1,900 nodes,
# ~13.7 GB, one mesh per trajectory) and of 20 trajectories, builds their graph hierarchies, and
# trains configs/train/cylinder-bsms.json on each with its normaliser phase (100 batches of 32)
# and with 1000 batches. Prints, per run, train_stats.json's seconds to the first optimizer step,
# median ms per step, peak RSS and graph-cache counts. The page cache is dropped before each run
# when this runs as root (a cold start), else the runs say they were warm.
# Usage: scripts/full_size_benchmark.sh BUILD_DIR OUT_DIR   (environment: FULL_TRAJECTORIES
# (1000), FULL_FRAMES (600), FULL_NODES (1900), FULL_STEPS (30), FULL_THREADS (2))
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
need_args "BUILD_DIR OUT_DIR" 2 2 "$@"
build_dir=$1
out_dir=$2
find_bsms full-size "$build_dir"
writer=$build_dir/bench/synthetic_public
[[ -x $writer ]] || { echo "full-size: $writer not found (make build)" >&2; exit 2; }
trajectories=${FULL_TRAJECTORIES:-1000}
frames=${FULL_FRAMES:-600}
nodes=${FULL_NODES:-1900}
steps=${FULL_STEPS:-30}
threads=${FULL_THREADS:-2}
mkdir -p "$out_dir"
start=$(date +%s)
stage() { echo; echo "== [$(( $(date +%s) - start )) s] $*"; }

for split in big small; do
  n=$trajectories
  [[ $split == small ]] && n=20
  if [[ ! -f $out_dir/$split/train.tfrecord ]]; then
    stage "synthetic split $split: $n trajectories x $frames frames x ~$nodes nodes"
    "$writer" "$out_dir/$split" --trajectories "$n" --frames "$frames" --nodes "$nodes"
    "$writer" "$out_dir/$split" --split valid --trajectories 16 --frames "$frames" --nodes "$nodes"
  fi
  stage "bsms preprocess --data $out_dir/$split"
  "$bsms" preprocess --data "$out_dir/$split" --seeding minave --levels 7 --threads "$threads" |
    tail -1
done

cold=warm
run() {  # NAME SPLIT STEPS NORMALIZER_STEPS
  local run=$out_dir/run_$1
  rm -rf "$run"
  if [[ -w /proc/sys/vm/drop_caches ]]; then
    sync
    echo 3 > /proc/sys/vm/drop_caches
    cold=cold
  fi
  "$bsms" train "$root/configs/train/cylinder-bsms.json" --out "$run" --threads "$threads" \
    --set "data=$out_dir/$2" --set valid_samples=8 --set "steps=$3" --set "valid_every=$3" \
    --set "normalizer_steps=$4" > "$run.log" 2>&1
  jq -r --arg name "$1" --arg cache "$cold" '"\($name) (\($cache) page cache): " +
    "\(.seconds_to_first_step | . * 10 | round / 10) s to step 1, " +
    "\(.train_ms_per_step | round) ms/step (median), peak RSS \(.peak_rss_mb_train | round) MB, " +
    "graphs made \(.graphs_made), evicted \(.graphs_evicted), " +
    "cache peak \(.graph_cache_peak_mb | round) MB"' "$run/train_stats.json"
}
stage "bsms train: the config's normaliser phase (100 batches of 32), $steps steps"
run small_n100 small "$steps" 100
run big_n100 big "$steps" 100
stage "bsms train: 1000 normaliser batches, 2 steps"
run small_n1000 small 2 1000
run big_n1000 big 2 1000
