#!/usr/bin/env bash
# The hard-case experiments (thesis §4.4.3-4.4.4), each scripted and reproducible, collected into
# OUT_DIR/report.md with their figures:
#   1. spatial-proximity failure: 1D steady heat transfer on two sticks head to tail, bi-stride
#      against a proximity-based coarsening (thesis Fig. 4.6);
#   2. zero-shot inference on meshes at least 4x larger than any training mesh;
#   3. seeding sensitivity at test time: MinAve, CloseCenter, random (thesis Table 4.8);
#   4. long rollouts over 10x the training horizon, and stability on hard scenes, plain and with
#      every predicted step projected onto the walls, cell and contact constraints
#      (--project all).
# Experiments 2-4 use the BSMS-GNN and MeshGraphNets runs MODELS_DIR/bsms and MODELS_DIR/mgn
# (default runs/demo, the demo's; runs/long after the long recipe). When a folder named demo
# lacks them the demo runs first; any other folder without them is exit 2.
# Usage: scripts/hardcases.sh BUILD_DIR OUT_DIR [MODELS_DIR]
#   (environment: HARDCASES_THREADS, HARDCASES_TRAJECTORIES, HARDCASES_SEEDING_TRAJECTORIES
#   override the defaults below)
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
need_args "BUILD_DIR OUT_DIR [MODELS_DIR]" 2 3 "$@"
build_dir=$1
out_dir=$2
models=${3:-runs/demo}
find_bsms hardcases "$build_dir"
threads=${HARDCASES_THREADS:-0}
count=${HARDCASES_TRAJECTORIES:-3}
seeding_count=${HARDCASES_SEEDING_TRAJECTORIES:-20}
family=$root/configs/families/disks2d.json
mkdir -p "$out_dir"
start=$(date +%s)
stage() { echo; echo "== [$(( $(date +%s) - start )) s] $*"; }

if [[ ! -f $models/bsms/rollout/metrics.json || ! -f $models/mgn/rollout/metrics.json ]]; then
  if [[ $(basename "$models") != demo ]]; then
    echo "hardcases: no trained runs in $models (expected $models/bsms and $models/mgn, each" \
      "rolled out: rollout/metrics.json); train them first (make train-long writes runs/long)" >&2
    exit 2
  fi
  stage "no trained runs in $models: running the demo first"
  "$root/scripts/demo.sh" "$build_dir" "$models"
fi

stage "1. spatial-proximity failure: heat transfer on two sticks (bi-stride vs proximity)"
"$bsms" experiment heat-sticks --out "$out_dir/heat_sticks" --threads "$threads"

runs=("$models/bsms" "$models/mgn")

# Test-only datasets from the default family (--split 0:0:100), each with fixed seeds.
generate() {  # NAME SEED N --set ...
  local name=$1 seed=$2 n=$3
  shift 3
  rm -rf "$out_dir/$name"
  "$bsms" generate "$family" --out "$out_dir/$name" --trajectories "$n" --split 0:0:100 \
    --seed "$seed" --threads "$threads" "$@"
}

stage "2. zero-shot: larger meshes (2.4 m box, 6-8 disks of radius 0.26-0.32 m at the same resolution)"
generate data_large 101 "$count" --set 'scene.background.max=[2.4,2.4]' \
  --set 'sample.count=[6,8]' --set 'sample.radius=[0.26,0.32]'
"$bsms" experiment zero-shot "${runs[@]}" --data "$out_dir/data_large" \
  --out "$out_dir/zero_shot" --threads "$threads"

stage "3. seeding sensitivity at test time (on more test trajectories than the demo's split)"
generate data_seeding 404 "$seeding_count"
"$bsms" experiment seeding "${runs[0]}" --data "$out_dir/data_seeding" --out "$out_dir/seeding" \
  --threads "$threads"

stage "4. long rollouts (500 frames = 10x the 50-frame training horizon) and hard scenes"
generate data_long 202 "$count" --set frames=500
# Hard scenes: impacts 2-3x faster and disks 2.3-4.7x softer (E 300-600 Pa against 1400) than training.
generate data_hard 303 "$count" --set 'sample.speed=[1.0,1.5]' \
  --set 'sample.material.youngs_modulus=[300.0,600.0]'
"$bsms" experiment long-rollout "${runs[@]}" --data "$out_dir/data_long" \
  --hard-scenes "$out_dir/data_hard" --out "$out_dir/long_rollout" --threads "$threads"
stage "4b. the same, every predicted step projected (walls, cells, contact)"
"$bsms" experiment long-rollout "${runs[@]}" --data "$out_dir/data_long" \
  --hard-scenes "$out_dir/data_hard" --out "$out_dir/long_rollout_projected" --threads "$threads" \
  --project all

stage "report"
{
  echo "# bsms hard cases"
  echo
  echo "Reproduce: \`scripts/hardcases.sh $build_dir $out_dir $models\` (\`make hardcases\`)."
  echo "Models: \`$models/bsms\` (BSMS-GNN) and \`$models/mgn\` (MeshGraphNets)."
  echo
  for section in heat_sticks/heat_sticks zero_shot/zero_shot seeding/seeding \
    long_rollout/long_rollout long_rollout_projected/long_rollout; do
    dir=${section%%/*}
    # Section images are relative to their own folder.
    sed "s#](plots/#](${dir}/plots/#g" "$out_dir/$section.md"
    echo
  done
} >"$out_dir/report.md.tmp"
mv "$out_dir/report.md.tmp" "$out_dir/report.md"
stage "done: $out_dir/report.md"
