#!/usr/bin/env bash
# Scene choice for the default family ("a default scene that can be learned and is still
# hard"): the same disks2d family generated with one solver or output setting changed at a time
# (transfer FLIP / APIC, PIC damping through flip_ratio, frame interval), BSMS-GNN trained on each
# for the same number of steps, rolled out on a test split of 50 trajectories, and one table of
# the one-step validation loss against predicting zero and the rollout RMSE-all against constant
# velocity. Both are ratios to what no model achieves on that scene, so scenes compare.
# Usage: scripts/scene_choice.sh BUILD_DIR OUT_DIR   (environment: SCENE_STEPS (12000),
# SCENE_THREADS (0 = all), SCENE_SEED (0), SCENE_VARIANTS (all: "flip apic pic95 dt02")).
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
need_args "BUILD_DIR OUT_DIR" 2 2 "$@"
build_dir=$1
out_dir=$2
find_bsms scene_choice "$build_dir"
command -v jq >/dev/null || { echo "scene_choice: jq not found (make deps installs it)" >&2; exit 2; }
steps=${SCENE_STEPS:-12000}
threads=${SCENE_THREADS:-0}
seed=${SCENE_SEED:-0}
variants=(${SCENE_VARIANTS:-flip apic pic95 dt02})
mkdir -p "$out_dir"

# Per variant: the generator's overrides and the training noise (m). The noise keeps its ratio to
# the per-frame acceleration: at half the frame interval the acceleration per frame² is ~1/4.
settings() {
  case $1 in
    flip) gen=(); noise=0.002 ;;
    apic) gen=(--set scene.solver.transfer=apic); noise=0.002 ;;
    pic95) gen=(--set scene.solver.flip_ratio=0.95); noise=0.002 ;;
    dt02) gen=(--set frame_dt=0.02 --set frames=100); noise=0.0005 ;;
    *) echo "scene_choice: unknown variant '$1' (expected flip, apic, pic95 or dt02)" >&2; exit 2 ;;
  esac
}

for v in "${variants[@]}"; do
  settings "$v"
  data=$out_dir/$v/data
  run=$out_dir/$v/bsms
  if [[ ! -f $data/generate.json ]]; then
    rm -rf "$data"
    "$bsms" generate "$root/configs/families/disks2d.json" --out "$data" --trajectories 140 \
      --split 80:10:50 --seed "$seed" --threads "$threads" "${gen[@]}"
    "$bsms" preprocess --data "$data" --seeding minave --levels 4 --threads "$threads"
  fi
  if [[ ! -f $run/rollout/metrics.json ]]; then
    rm -rf "$run"
    "$bsms" train "$root/configs/train/disks2d-bsms.json" --out "$run" --threads "$threads" \
      --set "data=$data" --set "steps=$steps" --set valid_every=1000 \
      --set "features.noise_std=$noise"
    "$bsms" rollout "$run" --split test --threads "$threads"
  fi
done

table=$out_dir/scene_choice.md
{
  echo "| scene | valid / zero (mean of last 3 checks) | RMSE-1 (m) | RMSE-all (m) | constant velocity (m) | / constant velocity | centre / rotation / deformation (m) | rigid bodies' deformation (m) | inverted cells max | ms/step |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
  for v in "${variants[@]}"; do
    run=$out_dir/$v/bsms
    ratio=$(awk -F, 'NR > 1 && $4 != "" { v[n] = $4; z[n] = $5; n++ }
      END { s = 0; t = 0; for (i = n - 3; i < n; i++) { s += v[i]; t += z[i] }
            printf "%.3f / %.3f = %.3f", s / 3, t / 3, s / t }' "$run/train_log.csv")
    jq -r --arg v "$v" --arg r "$ratio" '"| \($v) | \($r) | \(.rmse_1.world_pos | . * 1e6 | round / 1e6) | \(.rmse_all.world_pos | . * 1e4 | round / 1e4) | \(.rmse_all_constant_velocity | . * 1e4 | round / 1e4) | \(.rmse_all.world_pos / .rmse_all_constant_velocity | . * 1000 | round / 1000) | \(.rmse_all_parts | [.centre, .rotation, .deformation] | map(. * 1e4 | round / 1e4 | tostring) | join(" / ")) | \(.rmse_all_deformation_rigid | . * 1e4 | round / 1e4) | \(.inverted_cells_max * 100 | . * 1000 | round / 1000) % | \(.train_ms_per_step | round) |"' \
      "$run/rollout/metrics.json"
  done
} >"$table.tmp"
mv "$table.tmp" "$table"
cat "$table"
