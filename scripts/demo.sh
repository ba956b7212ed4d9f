#!/usr/bin/env bash
# The end-to-end demo on a scene family (default configs/families/disks2d.json):
# generate a small dataset with the UMLS-MPM solver, preprocess its meshes into bi-stride
# multilevel graphs, train BSMS-GNN and MeshGraphNets for the same wall-clock budget each, roll
# both out on the test split, re-solve the test split at the solver's cheaper settings and on
# another background mesh of the same size (the data's floor for a model that does not see that
# mesh), and write OUT_DIR/report.md with plots.
# Usage: scripts/demo.sh BUILD_DIR OUT_DIR   (environment: DEMO_FAMILY (a family with
# configs/families/F.json and configs/train/F-bsms.json, F-mgn.json: disks2d or bodies3d),
# DEMO_TRAJECTORIES, DEMO_TRAIN_SECONDS, DEMO_THREADS and DEMO_SEED (the dataset's seed: check the
# shipped configs on data they were not tuned on) override the defaults below)
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
need_args "BUILD_DIR OUT_DIR" 2 2 "$@"
build_dir=$1
out_dir=$2
find_bsms demo "$build_dir"
family=${DEMO_FAMILY:-disks2d}
for f in "configs/families/$family.json" "configs/train/$family-bsms.json" "configs/train/$family-mgn.json"; do
  [[ -f "$root/$f" ]] || { echo "demo: DEMO_FAMILY=$family: $f does not exist (shipped demo families: disks2d, bodies3d)" >&2; exit 2; }
done
# The preprocessed graphs must have the level count the BSMS config trains with.
levels=$(sed -n 's/.*"levels": *\([0-9][0-9]*\).*/\1/p' "$root/configs/train/$family-bsms.json")
[[ -n "$levels" ]] || { echo "demo: configs/train/$family-bsms.json: no integer model.levels" >&2; exit 2; }
trajectories=${DEMO_TRAJECTORIES:-100}
train_seconds=${DEMO_TRAIN_SECONDS:-360}
threads=${DEMO_THREADS:-0}
seed=${DEMO_SEED:-0}
data=$out_dir/data
mkdir -p "$out_dir"
start=$(date +%s)
stage() { echo; echo "== [$(( $(date +%s) - start )) s] $*"; }

stage "bsms preprocess: bi-stride multilevel graph of the plate with holes (MinAve seeding)"
"$bsms" preprocess --mesh "$root/configs/geometry/plate_with_holes.geo" \
  --out "$out_dir/plate_multilevel.h5" --seeding minave --levels auto --threads "$threads"

stage "bsms generate: $trajectories $family trajectories (80:10:10) with UMLS-MPM"
"$bsms" generate "$root/configs/families/$family.json" --out "$data" \
  --trajectories "$trajectories" --split 80:10:10 --seed "$seed" --threads "$threads"
"$bsms" info "$data/train.h5"

stage "bsms preprocess --data: multilevel graphs of every mesh in the dataset"
# The seeding and level count of configs/train/$family-bsms.json: training reads these files
# (named as its graph cache names them) instead of building its own.
"$bsms" preprocess --data "$data" --seeding minave --levels "$levels" --threads "$threads"

for model in bsms mgn; do
  stage "bsms train: $model for ${train_seconds} s"
  run=$out_dir/$model
  rm -rf "$run"
  "$bsms" train "$root/configs/train/$family-$model.json" --out "$run" --threads "$threads" \
    --set "data=$data" --set "time_budget_s=$train_seconds" --set steps=100000 --set valid_every=500
  stage "bsms rollout: $model on the test split"
  "$bsms" rollout "$run" --split test --threads "$threads"
done

stage "bsms experiment solver-frontier: the solver at cheaper settings and on another mesh"
rm -rf "$out_dir/frontier"
"$bsms" experiment solver-frontier --data "$data" --out "$out_dir/frontier" --threads "$threads" --quiet

stage "bsms report"
"$bsms" report "$out_dir/bsms" "$out_dir/mgn" --out "$out_dir" --solver-frontier "$out_dir/frontier" \
  --title "bsms demo: BSMS-GNN and MeshGraphNets on $family ($trajectories trajectories, ${train_seconds} s of training each)"
stage "done: $out_dir/report.md"
