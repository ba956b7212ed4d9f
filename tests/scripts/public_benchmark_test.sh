#!/usr/bin/env bash
# scripts/public_benchmark.sh in CI size on a MeshGraphNets fixture: a few training steps of tiny
# models on the shipped configs, both rolled out on the test split, the report with a row per
# model; a rerun resumes (train --resume, rollouts kept), one with more steps continues training
# and redoes the rollouts; a folder without meta.json or a split, or a PUBLIC_DATASET that names
# no dataset, fails with exit 2, one line on stderr and nothing written.
# Usage: public_benchmark_test.sh BUILD_DIR SOURCE_DIR WORK [FIXTURE (cylinder_flow)]
# The fixture is copied into WORK: training writes its multilevel graphs beside the data.
set -u
build_dir=$(cd "$1" && pwd) src=$(cd "$2" && pwd) work=$3 fixture=${4:-cylinder_flow}
script=$src/scripts/public_benchmark.sh
fail() {
  echo "FAIL: $*"
  exit 1
}
export OMP_WAIT_POLICY=PASSIVE
# CI size: the shipped configs (levels, batch sizes, message passing, noise) with a few steps of
# tiny models; every knob is in the script's header. The fixtures' test split is one trajectory.
export PUBLIC_STEPS=10 PUBLIC_LATENT=8 PUBLIC_NORMALIZER_STEPS=2 PUBLIC_VALID_EVERY=5 \
  PUBLIC_VALID_SAMPLES=2 PUBLIC_THREADS=${PUBLIC_THREADS:-2}
unset PUBLIC_DATASET PUBLIC_SECONDS PUBLIC_LEVELS PUBLIC_MGN_MP PUBLIC_BATCH PUBLIC_ROLLOUT_TRAJECTORIES
rm -rf "$work"
mkdir -p "$work/data"
cp -r "$src/tests/fixtures/meshgraphnets/$fixture" "$work/data/$fixture" || fail "no fixture $fixture"
chmod -R u+w "$work/data"
data=$work/data/$fixture
out=$work/out
case $fixture in
  cylinder_flow) short=cylinder ;;
  flag_simple) short=flag ;;
  deforming_plate) short=plate ;;
  *) short=$fixture ;;
esac

# expect_refusal NAME REGEX DATASET_DIR: exit 2, one stderr line matching REGEX, no OUT_DIR.
expect_refusal() {
  local name=$1 regex=$2 dir=$3 err=$work/$1.err
  "$script" "$build_dir" "$dir" "$work/$name.out" >/dev/null 2>"$err"
  local code=$?
  [[ $code == 2 ]] || fail "$name: exit $code, expected 2: $(cat "$err")"
  [[ $(wc -l <"$err") == 1 ]] || fail "$name: not one line on stderr: $(cat "$err")"
  grep -Eq -e "$regex" "$err" || fail "$name: stderr does not name /$regex/: $(cat "$err")"
  [[ ! -e $work/$name.out ]] || fail "$name: $work/$name.out written"
  echo "ok: $name: $(cat "$err")"
}
for missing in meta.json test.tfrecord; do
  mkdir -p "$work/no_$missing"
  cp "$data"/* "$work/no_$missing/"
  rm "$work/no_$missing/$missing"
  expect_refusal "no_$missing" "$missing" "$work/no_$missing"
done
PUBLIC_DATASET=cloth expect_refusal bad_kind PUBLIC_DATASET "$data"

"$script" "$build_dir" "$data" "$out" >"$work/first.log" 2>&1 || { cat "$work/first.log"; fail "first run"; }
grep -q "public benchmark: $fixture" "$work/first.log" || { cat "$work/first.log"; fail "not recognised as $fixture"; }
for model in bsms mgn; do
  jq -e '.rmse_trajectory_mean | has("1") and has("all")' "$out/$model/rollout/metrics.json" >/dev/null ||
    fail "$out/$model/rollout/metrics.json: no rmse_trajectory_mean with horizons 1 and all"
  [[ $(jq -r .data "$out/configs/$model.json") == "$data" ]] || fail "$out/configs/$model.json: data is not $data"
  # Only data and the knobs differ from the shipped config: its features (noise, output), learning
  # rate and model (levels, message passing) besides the latent width.
  jq -e -n --slurpfile a "$src/configs/train/$short-$model.json" --slurpfile b "$out/configs/$model.json" \
    '$a[0].features == $b[0].features and $a[0].optimizer == $b[0].optimizer and
     ($a[0].model | del(.latent)) == ($b[0].model | del(.latent))' >/dev/null ||
    fail "$out/configs/$model.json: differs from configs/train/$short-$model.json beyond data and the knobs"
done
report=$out/report/report.md
[[ -f $report ]] || fail "no $report"
for row in '^\| bsms \|' '^\| mgn \|' 'RMSE-1 \|' 'RMSE-all \|' "^\| $fixture \|"; do
  grep -Eq -e "$row" "$report" || { cat "$report"; fail "$report: no /$row/"; }
done

# Rerun: both trainings resume from their checkpoints, both rollouts are kept.
"$script" "$build_dir" "$data" "$out" >"$work/second.log" 2>&1 || { cat "$work/second.log"; fail "rerun"; }
for model in bsms mgn; do
  grep -q "bsms train: $model (resumed)" "$work/second.log" || { cat "$work/second.log"; fail "rerun: $model not resumed"; }
  grep -q "bsms rollout: $model: .* kept" "$work/second.log" || { cat "$work/second.log"; fail "rerun: $model rollout redone"; }
done
# More steps: training continues from step 10 and the rollouts are redone.
PUBLIC_STEPS=12 "$script" "$build_dir" "$data" "$out" >"$work/third.log" 2>&1 ||
  { cat "$work/third.log"; fail "rerun with PUBLIC_STEPS=12"; }
for model in bsms mgn; do
  [[ $(jq -r .train_steps "$out/$model/rollout/metrics.json") == 12 ]] ||
    { cat "$work/third.log"; fail "PUBLIC_STEPS=12: $model rollout not of the 12-step model"; }
done
echo "ok: $fixture: report $report; rerun resumed"
