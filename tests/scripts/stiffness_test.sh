#!/usr/bin/env bash
# scripts/stiffness.sh in CI size (disks2d, one modulus, 10 trajectories, seconds of training):
# the table has its row and the solver's floor (another_mesh) beside the model; a rerun keeps the
# finished point and its frontier; a point whose rollouts are gone keeps its dataset (not
# regenerated) and is trained and rolled out again; another seed regenerates; a modulus or a
# frontier mode that is not known fails with exit 2 and one line.
# Usage: stiffness_test.sh BUILD_DIR SOURCE_DIR WORK
set -u
build_dir=$(cd "$1" && pwd) src=$(cd "$2" && pwd) work=$3
script=$src/scripts/stiffness.sh
fail() {
  echo "FAIL: $*"
  exit 1
}
export OMP_WAIT_POLICY=PASSIVE STIFF_FAMILY=disks2d STIFF_E=1400 STIFF_TRAJECTORIES=10 \
  STIFF_TRAIN_SECONDS=2 STIFF_THREADS=2 STIFF_SEED=3 STIFF_FRONTIER=floor
unset STIFF_SET STIFF_COST_E
rm -rf "$work"
mkdir -p "$work"
out=$work/out
point=$out/E1400
"$script" "$build_dir" "$out" >"$work/first.log" 2>&1 || fail "first run: $(tail -3 "$work/first.log")"
grep -q "^| 1400 |" "$out/stiffness.md" || fail "no row for E = 1400 in $out/stiffness.md"
grep -q "generate: " "$work/first.log" || fail "the first run generated nothing"
# The floor's rows: the ground truth re-solved exactly, another mesh of the same size not, and the
# model's ratio as a multiple of the floor's.
grep -q "^| 1400 | ground_truth | [0-9.]* | 0 | 0 | – |" "$out/stiffness.md" ||
  fail "no ground-truth re-solve row: $(grep '| 1400 |' "$out/stiffness.md")"
grep -Eq "^\| 1400 \| another_mesh \| [0-9.]+ \| 0\.[0-9]*[1-9][0-9]* \| 0 \| [0-9.]+ \|" "$out/stiffness.md" ||
  fail "no another_mesh row with a non-zero ratio: $(grep '| 1400 |' "$out/stiffness.md")"
data_id=$(stat -c %i:%Y "$point/data/train.h5")

"$script" "$build_dir" "$out" >"$work/kept.log" 2>&1 || fail "rerun: $(tail -3 "$work/kept.log")"
grep -q "== E = 1400" "$work/kept.log" && fail "a finished point was redone: $(head -3 "$work/kept.log")"
grep -q "^solver-frontier" "$work/kept.log" && fail "a finished frontier was redone"

rm -rf "$point/bsms-E1400/rollout_walls+cells+contact"
"$script" "$build_dir" "$out" >"$work/again.log" 2>&1 || fail "rerun: $(tail -3 "$work/again.log")"
grep -q "== E = 1400 Pa: dataset kept" "$work/again.log" || fail "dataset not kept: $(head -3 "$work/again.log")"
[[ $(stat -c %i:%Y "$point/data/train.h5") == "$data_id" ]] || fail "the kept dataset was rewritten"
[[ -f $point/bsms-E1400/rollout_walls+cells+contact/metrics.json ]] || fail "no projected rollout after the rerun"

rm -rf "$point/bsms-E1400/rollout_walls+cells+contact"
STIFF_SEED=4 "$script" "$build_dir" "$out" >"$work/seed.log" 2>&1 || fail "seed 4: $(tail -3 "$work/seed.log")"
grep -q "== E = 1400 Pa: generate" "$work/seed.log" || fail "another seed did not regenerate"

STIFF_E="1e4 soft" "$script" "$build_dir" "$work/bad" >/dev/null 2>"$work/bad.err"
code=$?
[[ $code == 2 && $(wc -l <"$work/bad.err") == 1 ]] || fail "bad modulus: exit $code: $(cat "$work/bad.err")"
grep -q "'soft' is not a positive modulus" "$work/bad.err" || fail "bad modulus: $(cat "$work/bad.err")"
[[ ! -e $work/bad ]] || fail "a refused run wrote $work/bad"
STIFF_FRONTIER=some "$script" "$build_dir" "$work/bad" >/dev/null 2>"$work/bad.err"
code=$?
[[ $code == 2 && $(wc -l <"$work/bad.err") == 1 ]] || fail "bad frontier mode: exit $code: $(cat "$work/bad.err")"
grep -q "STIFF_FRONTIER=some: expected all, floor or off" "$work/bad.err" || fail "bad frontier mode: $(cat "$work/bad.err")"
[[ ! -e $work/bad ]] || fail "a refused run wrote $work/bad"
echo "stiffness script: table, floor, kept point and frontier, kept dataset, new seed, bad modulus and bad frontier mode all as expected"
