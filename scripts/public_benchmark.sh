#!/usr/bin/env bash
# The thesis protocol on one of DeepMind's MeshGraphNets datasets (cylinder_flow, airfoil,
# flag_simple, deforming_plate): BSMS-GNN and MeshGraphNets trained with the shipped configs
# (configs/train/<short>-{bsms,mgn}.json, "data" set to DATASET_DIR), each rolled out on the test
# split, and a report whose tables give RMSE-1, RMSE-50 and RMSE-all per model (each test
# trajectory's RMSE averaged over the trajectories, the references' convention).
# Usage: scripts/public_benchmark.sh BUILD_DIR DATASET_DIR OUT_DIR
# DATASET_DIR holds meta.json and {train,valid,test}.tfrecord as downloaded. The dataset is
# recognised from meta.json's fields (velocity and density: airfoil; velocity and pressure:
# cylinder_flow; world_pos and stress: deforming_plate; world_pos alone: flag_simple).
# Environment (unset = the thesis protocol, the shipped configs unchanged apart from data):
#   PUBLIC_DATASET           cylinder_flow, airfoil, flag_simple or deforming_plate (or cylinder,
#                            flag, plate): overrides the recognition
#   PUBLIC_STEPS             training steps of each model (config: 1,000,000)
#   PUBLIC_SECONDS           wall-clock budget of each model's training in s (0 = none)
#   PUBLIC_LATENT            latent width of both models (config: 128)
#   PUBLIC_LEVELS            BSMS levels including the mesh (config: Table 4.1's, or auto)
#   PUBLIC_MGN_MP            MeshGraphNets message-passing steps (config: 15)
#   PUBLIC_BATCH             batch size of both models (config: Table 4.4's)
#   PUBLIC_NORMALIZER_STEPS  batches the normalisers are fitted on first (config: 100)
#   PUBLIC_VALID_EVERY       steps between validations and checkpoints (config: 5000)
#   PUBLIC_VALID_SAMPLES     validation samples (config: 64)
#   PUBLIC_ROLLOUT_TRAJECTORIES  test trajectories rolled out (0 = all, the default)
#   PUBLIC_THREADS           worker threads (0 = all hardware threads, the default)
# Writes OUT_DIR/configs/{bsms,mgn}.json (the configs trained), OUT_DIR/{bsms,mgn} (runs, each
# with rollout/metrics.json) and OUT_DIR/report/report.md. Resumable: rerun the same command and
# each model continues from its latest checkpoint; a rollout newer than its checkpoint (of as many
# trajectories) is kept. Of the knobs that go into the configs only PUBLIC_STEPS and
# PUBLIC_SECONDS may change between runs; `bsms train --resume` refuses any other change (remove
# OUT_DIR/bsms and OUT_DIR/mgn to start over).
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
need_args "BUILD_DIR DATASET_DIR OUT_DIR" 3 3 "$@"
build_dir=$1
dataset_dir=$2
out_dir=$3
find_bsms public-benchmark "$build_dir"
fail() { echo "public-benchmark: $*" >&2; exit 2; }

[[ -d $dataset_dir ]] || fail "$dataset_dir: no such folder (expected meta.json and {train,valid,test}.tfrecord)"
for f in meta.json train.tfrecord valid.tfrecord test.tfrecord; do
  [[ -f $dataset_dir/$f ]] ||
    fail "$dataset_dir/$f: missing (a MeshGraphNets dataset folder holds meta.json and {train,valid,test}.tfrecord)"
done
command -v jq >/dev/null || fail "jq not found (make deps installs it)"
data=$(cd "$dataset_dir" && pwd)

# The kind of dataset: the configs differ in levels, batch sizes, noise and output.
if [[ -n ${PUBLIC_DATASET:-} ]]; then
  kind=$PUBLIC_DATASET
else
  fields=$(jq -r '.features | keys | join(" ")' "$data/meta.json" 2>/dev/null) ||
    fail "$data/meta.json: not JSON with a \"features\" object"
  has() { [[ " $fields " == *" $1 "* ]]; }
  if has velocity && has density; then kind=airfoil
  elif has velocity && has pressure; then kind=cylinder_flow
  elif has world_pos && has stress; then kind=deforming_plate
  elif has world_pos; then kind=flag_simple
  else fail "$data/meta.json: fields ($fields) are none of cylinder_flow, airfoil, flag_simple, deforming_plate; set PUBLIC_DATASET"
  fi
fi
case $kind in
  cylinder_flow | cylinder) kind=cylinder_flow short=cylinder ;;
  airfoil) short=airfoil ;;
  flag_simple | flag) kind=flag_simple short=flag ;;
  deforming_plate | plate) kind=deforming_plate short=plate ;;
  *) fail "PUBLIC_DATASET=$kind: expected cylinder_flow, airfoil, flag_simple or deforming_plate" ;;
esac

# The knobs, checked before anything is written.
knobs=(PUBLIC_STEPS PUBLIC_SECONDS PUBLIC_LATENT PUBLIC_LEVELS PUBLIC_MGN_MP PUBLIC_BATCH
  PUBLIC_NORMALIZER_STEPS PUBLIC_VALID_EVERY PUBLIC_VALID_SAMPLES PUBLIC_ROLLOUT_TRAJECTORIES
  PUBLIC_THREADS)
settings=
for knob in "${knobs[@]}"; do
  value=${!knob:-}
  [[ -z $value ]] && continue
  case $knob in
    PUBLIC_SECONDS) pattern='^[0-9]+([.][0-9]*)?$' what="seconds (0 = no budget)" ;;
    PUBLIC_LEVELS) pattern='^([0-9]+|auto)$' what="a level count or auto" ;;
    *) pattern='^[0-9]+$' what="a whole number" ;;
  esac
  [[ $value =~ $pattern ]] || fail "$knob=$value: expected $what"
  settings+=" $knob=$value"
done
threads=${PUBLIC_THREADS:-0}
rollout_trajectories=${PUBLIC_ROLLOUT_TRAJECTORIES:-0}
mkdir -p "$out_dir/configs"
start=$(date +%s)
stage() { echo; echo "== [$(( $(date +%s) - start )) s] $*"; }

# derive MODEL: OUT_DIR/configs/MODEL.json, the shipped config with data and the knobs that are
# set. Written again on every run from the same knobs, so that a resume sees the same config.
derive() {
  local model=$1 filter='.data = $data' args=(--arg data "$data")
  add() { filter+=" | $1 = (\$$2 | tonumber)"; args+=(--arg "$2" "$3"); }
  [[ -n ${PUBLIC_STEPS:-} ]] && add .steps steps "$PUBLIC_STEPS"
  [[ -n ${PUBLIC_SECONDS:-} ]] && add .time_budget_s seconds "$PUBLIC_SECONDS"
  [[ -n ${PUBLIC_LATENT:-} ]] && add .model.latent latent "$PUBLIC_LATENT"
  [[ -n ${PUBLIC_BATCH:-} ]] && add .optimizer.batch_size batch "$PUBLIC_BATCH"
  [[ -n ${PUBLIC_NORMALIZER_STEPS:-} ]] && add .normalizer_steps normalizer "$PUBLIC_NORMALIZER_STEPS"
  [[ -n ${PUBLIC_VALID_EVERY:-} ]] && add .valid_every valid_every "$PUBLIC_VALID_EVERY"
  [[ -n ${PUBLIC_VALID_SAMPLES:-} ]] && add .valid_samples valid_samples "$PUBLIC_VALID_SAMPLES"
  if [[ $model == bsms && -n ${PUBLIC_LEVELS:-} ]]; then
    # "auto" stays a string; a count is a number.
    if [[ $PUBLIC_LEVELS == auto ]]; then filter+=' | .model.levels = "auto"'
    else add .model.levels levels "$PUBLIC_LEVELS"; fi
  fi
  [[ $model == mgn && -n ${PUBLIC_MGN_MP:-} ]] && add .model.message_passing_steps mp "$PUBLIC_MGN_MP"
  local config=$out_dir/configs/$model.json
  jq "${args[@]}" "$filter" "$root/configs/train/$short-$model.json" >"$config.tmp" ||
    fail "$root/configs/train/$short-$model.json: could not derive $config"
  mv "$config.tmp" "$config"
}

stage "public benchmark: $kind ($data), configs/train/$short-{bsms,mgn}.json${settings:+ with$settings}"
for model in bsms mgn; do derive "$model"; done
levels=$(jq -r '.model.levels' "$out_dir/configs/bsms.json")

# BSMS's multilevel graphs of every mesh before training, as training would build them on first
# use, so that a time budget (PUBLIC_SECONDS) counts training only. Where training looks:
# DATA/multilevel when the folder can be written, else the run's own RUN/multilevel.
cache=$data/multilevel
if ! { mkdir -p "$cache" && [[ -w $cache ]]; } 2>/dev/null; then cache=$out_dir/bsms/multilevel; fi
stage "bsms preprocess --data: multilevel graphs of every mesh (minave, $levels levels) -> $cache"
"$bsms" preprocess --data "$data" --out "$cache" --seeding minave --levels "$levels" --threads "$threads"

for model in bsms mgn; do
  run=$out_dir/$model
  resume=()
  # (An older run's latest.pt alone also resumes: train then says how to convert it.)
  [[ -f $run/checkpoints/latest.h5 || -f $run/checkpoints/latest.pt ]] && resume=(--resume)
  stage "bsms train: $model${resume:+ (resumed)}"
  "$bsms" train "$out_dir/configs/$model.json" --out "$run" --threads "$threads" "${resume[@]}"

  # A rollout is redone when training went on after it (its checkpoint is newer) or it covered
  # another number of trajectories.
  metrics=$run/rollout/metrics.json
  stamp=$run/rollout/.trajectories
  if [[ -f $metrics && $metrics -nt $run/checkpoints/latest.h5 && -f $stamp &&
        $(<"$stamp") == "$rollout_trajectories" ]]; then
    stage "bsms rollout: $model: $metrics is newer than the checkpoint, kept"
    continue
  fi
  stage "bsms rollout: $model on the test split"
  "$bsms" rollout "$run" --split test --max-trajectories "$rollout_trajectories" --threads "$threads"
  echo "$rollout_trajectories" >"$stamp"
done

stage "bsms report"
"$bsms" report "$out_dir/bsms" "$out_dir/mgn" --out "$out_dir/report" \
  --title "bsms public benchmark: BSMS-GNN and MeshGraphNets on $kind"
stage "done: $out_dir/report/report.md"
