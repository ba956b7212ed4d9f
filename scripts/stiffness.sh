#!/usr/bin/env bash
# Stiffness sweep: where a learned simulator pays off against the solver that made its data. One
# family generated at several Young's moduli (everything else and the seed unchanged), BSMS-GNN
# trained on each for the same wall-clock budget, rolled out on its test split (plain and with
# --project all: walls, cells and contact held after each step), and one table with, per E: the
# solver's ms per frame and the draws it lost to instability, the model's ms per step, the
# speed-up, RMSE-all against constant velocity, inverted cells, nodes outside the walls and the overlap between bodies (model / truth). The solver's cost
# grows with sqrt(E) (its time step follows the wave speed); the model takes one step per frame.
# Usage: scripts/stiffness.sh BUILD_DIR OUT_DIR   (environment: STIFF_FAMILY (disks2d or bodies3d;
# default disks2d), STIFF_E (moduli in Pa, default "1400 14000 140000 1400000" in 2-D and
# "10000 100000 1000000" in 3-D), STIFF_TRAJECTORIES (100), STIFF_TRAIN_SECONDS (360), STIFF_SEED
# (0), STIFF_THREADS (0 = all), STIFF_SET (further generator overrides, space-separated; 2-D
# default "scene.solver.transfer=apic": FLIP loses draws to inverted particles from ~1 MPa, APIC
# holds, and one solver for every E keeps the points comparable), STIFF_COST_E (moduli at which only
# the solver's cost is measured, on STIFF_COST_TRAJECTORIES (6) trajectories each: the solver's
# side of the crossover on a finer grid of E than training allows; default none), STIFF_FRONTIER
# (the solver re-solving each test split: "all" (default) its cheaper default settings and
# another_mesh, "floor" another_mesh only, "off"; another_mesh is the same resolution on another
# background mesh: the data's floor for a model that does not see that mesh)). Resumable: a
# finished point is kept, and so is a point's dataset generated with the same draw.
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
need_args "BUILD_DIR OUT_DIR" 2 2 "$@"
build_dir=$1
out_dir=$2
find_bsms stiffness "$build_dir"
command -v jq >/dev/null || { echo "stiffness: jq not found (make deps installs it)" >&2; exit 2; }
family=${STIFF_FAMILY:-disks2d}
case $family in
  disks2d) moduli=${STIFF_E:-1400 14000 140000 1400000}; sets=${STIFF_SET-scene.solver.transfer=apic} ;;
  bodies3d) moduli=${STIFF_E:-10000 100000 1000000}; sets=${STIFF_SET-} ;;
  *) echo "stiffness: STIFF_FAMILY=$family: expected disks2d or bodies3d" >&2; exit 2 ;;
esac
for e in $moduli ${STIFF_COST_E:-}; do
  [[ $e =~ ^[0-9]+([.][0-9]+)?([eE][+]?[0-9]+)?$ ]] ||
    { echo "stiffness: STIFF_E: '$e' is not a positive modulus in Pa" >&2; exit 2; }
done
frontier_mode=${STIFF_FRONTIER:-all}
case $frontier_mode in
  all) frontier_args=() ;;
  floor) frontier_args=(--setting another_mesh) ;;
  off) ;;
  *) echo "stiffness: STIFF_FRONTIER=$frontier_mode: expected all, floor or off" >&2; exit 2 ;;
esac
trajectories=${STIFF_TRAJECTORIES:-100}
seconds=${STIFF_TRAIN_SECONDS:-360}
seed=${STIFF_SEED:-0}
threads=${STIFF_THREADS:-0}
config=$root/configs/train/$family-bsms.json
levels=$(sed -n 's/.*"levels": *\([0-9][0-9]*\).*/\1/p' "$config")
[[ -n $levels ]] || { echo "stiffness: $config: no integer model.levels" >&2; exit 2; }
set_args=()
for s in $sets; do set_args+=(--set "$s"); done
mkdir -p "$out_dir"

runs=()
for e in $moduli; do
  point=$out_dir/E$e
  run=$point/bsms-E$e
  runs+=("$run")
  if [[ -f $run/rollout_walls+cells+contact/metrics.json ]]; then continue; fi  # finished earlier
  # A dataset already generated with the same draw is kept (generation is the long part at high E).
  key="$family trajectories=$trajectories seed=$seed E=$e sets=$sets"
  if [[ -f $point/data/train.h5 && -f $point/data/valid.h5 && -f $point/data/test.h5 &&
        -f $point/generate.log && $(cat "$point/generate.key" 2>/dev/null) == "$key" ]]; then
    echo "== E = $e Pa: dataset kept; preprocess, train ${seconds} s, roll out"
    rm -rf "$run"
  else
    echo "== E = $e Pa: generate, preprocess, train ${seconds} s, roll out"
    rm -rf "$point"
    mkdir -p "$point"
    "$bsms" generate "$root/configs/families/$family.json" --out "$point/data" \
      --trajectories "$trajectories" --split 80:10:10 --seed "$seed" --threads "$threads" \
      --set "sample.material.youngs_modulus=$e" "${set_args[@]}" 2>&1 | tee "$point/generate.log"
    echo "$key" >"$point/generate.key"
  fi
  "$bsms" preprocess --data "$point/data" --seeding minave --levels "$levels" --threads "$threads"
  "$bsms" train "$config" --out "$run" --threads "$threads" --set "data=$point/data" \
    --set "time_budget_s=$seconds" --set steps=1000000 --set valid_every=500
  "$bsms" rollout "$run" --split test --threads "$threads"
  "$bsms" rollout "$run" --split test --threads "$threads" --project all
done

# The solver on each test split at other settings (after the training, which it would slow).
# Kept when done with the same settings: a regenerated point starts without it.
if [[ $frontier_mode != off ]]; then
  for e in $moduli; do
    point=$out_dir/E$e
    [[ -f $point/frontier/metrics.json && $(cat "$point/frontier.key" 2>/dev/null) == "$frontier_mode" ]] &&
      continue
    rm -rf "$point/frontier"
    "$bsms" experiment solver-frontier --data "$point/data" --out "$point/frontier" \
      --threads "$threads" --quiet "${frontier_args[@]}"
    echo "$frontier_mode" >"$point/frontier.key"
  done
fi

# The table: one row per modulus, figures from each run's metrics.json.
table=$out_dir/stiffness.md
{
  echo "# Stiffness sweep: $family, $trajectories trajectories (seed $seed), ${seconds} s of BSMS-GNN training each"
  echo
  echo "Generator overrides besides E: ${sets:-none}. Solver: single-threaded, ms per stored frame"
  echo "(median over the test split, timed while generating); model: $(jq -r .threads "${runs[0]}/rollout/metrics.json") thread(s), ms per step."
  echo "RMSE-all in m; ratio: RMSE-all / constant velocity (lower is better, 1 = no better than"
  echo "extrapolating the velocity). Validity: worst step; overlap as a fraction of the bodies' cells."
  echo
  echo "| E (Pa) | solver ms/frame | draws redrawn | model ms/step | speed-up | RMSE-all | const. velocity | ratio | inverted (max) | outside walls (max, m) | overlap model / truth | with --project all: ratio, inverted (max), overlap model / truth, ms/step |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
  for e in $moduli; do
    point=$out_dir/E$e
    m=$point/bsms-E$e/rollout/metrics.json
    w=$point/bsms-E$e/rollout_walls+cells+contact/metrics.json
    redrawn=$(sed -n 's/.* \([0-9][0-9]*\) unstable draws replaced.*/\1/p' "$point/generate.log" | tail -1)
    jq -r --arg e "$e" --arg redrawn "${redrawn:-?}" --slurpfile w "$w" '
      def f(p): if . == null then "n/a" else (. * pow(10; p) | round / pow(10; p) | tostring) end;
      def e3: if . == null then "n/a" else (. * 1e3 | round / 1e3 | tostring) end;
      "| \($e) | \(.solver_ms_per_frame | f(1)) | \($redrawn) | \(.infer_ms_per_step | f(2)) | \(.speedup_vs_solver | f(2)) | \(.rmse_all.world_pos | f(4)) | \(.rmse_all_constant_velocity | f(4)) | \(.rmse_all.world_pos / .rmse_all_constant_velocity | e3) | \(.inverted_cells_max * 100 | f(2)) % | \(.validity.model.outside_walls.max | f(4)) | \(.validity.model.overlap.max | f(5)) / \(.validity.truth.overlap.max | f(5)) | \($w[0].rmse_all.world_pos / $w[0].rmse_all_constant_velocity | e3), \($w[0].inverted_cells_max * 100 | f(2)) %, \($w[0].validity.model.overlap.max | f(5)) / \($w[0].validity.truth.overlap.max | f(5)), \($w[0].infer_ms_per_step | f(2)) |"' "$m"
  done
  if [[ $frontier_mode != off ]]; then
    echo
    echo "The solver at other settings on the same test split (\`bsms experiment solver-frontier\`,"
    echo "single-threaded solves, $(jq -r .threads "$out_dir/E${moduli%% *}/frontier/metrics.json") at once; its ground-truth row timed in the same run). another_mesh: the same"
    echo "resolution on another background mesh, the data's floor for a model that does not see that mesh."
    echo
    echo "| E (Pa) | setting | ms/frame | ratio | unstable | model ratio / setting's |"
    echo "|---|---|---|---|---|---|"
    for e in $moduli; do
      model=$(jq '.rmse_all.world_pos / .rmse_all_constant_velocity' "$out_dir/E$e/bsms-E$e/rollout/metrics.json")
      jq -r --arg e "$e" --argjson model "$model" '
        def f(p): if . == null then "n/a" else (. * pow(10; p) | round / pow(10; p) | tostring) end;
        ([.ground_truth] + .settings)[] |
        "| \($e) | \(.name) | \(.ms_per_frame | f(1)) | \(.rmse_all_over_constant_velocity | f(4)) | \(.unstable) | \(if (.rmse_all_over_constant_velocity // 0) > 0 then ($model / .rmse_all_over_constant_velocity | f(2)) else "–" end) |"' \
        "$out_dir/E$e/frontier/metrics.json"
    done
  fi
} >"$table.tmp"
mv "$table.tmp" "$table"

# The crossover plot: speed-up over the solver and accuracy against E (log axis).
dat=$out_dir/stiffness.dat
for e in $moduli; do
  jq -r --arg e "$e" '"\($e) \(.speedup_vs_solver // "NaN") \(.rmse_all.world_pos / .rmse_all_constant_velocity) \(.solver_ms_per_frame // "NaN") \(.infer_ms_per_step)"' \
    "$out_dir/E$e/bsms-E$e/rollout/metrics.json"
done >"$dat"
if command -v gnuplot >/dev/null; then
  gnuplot <<EOF || echo "stiffness: gnuplot failed; the table is complete" >&2
set terminal pngcairo size 900,420 noenhanced
set output "$out_dir/stiffness.png.tmp"
set multiplot layout 1,2 title "$family: BSMS-GNN against the UMLS-MPM solver"
set logscale x
set xlabel "Young's modulus E (Pa)"
set logscale y
set ylabel "ms per frame"
set key top left
plot "$dat" using 1:4 with linespoints title "solver", "$dat" using 1:5 with linespoints title "BSMS-GNN"
unset logscale y
set ylabel "RMSE-all / constant velocity"
set yrange [0:*]
plot "$dat" using 1:3 with linespoints title "BSMS-GNN", 0.25 with lines dashtype 2 title "0.25"
unset multiplot
EOF
  [[ -f $out_dir/stiffness.png.tmp ]] && mv "$out_dir/stiffness.png.tmp" "$out_dir/stiffness.png"
fi
# The solver's cost alone at further moduli (no training): ms per frame and the draws it lost.
if [[ -n ${STIFF_COST_E:-} ]]; then
  cost_trajectories=${STIFF_COST_TRAJECTORIES:-6}
  {
    echo
    echo "## The solver's cost alone ($cost_trajectories trajectories per E, seed $seed)"
    echo
    echo "| E (Pa) | solver ms/frame (median) | unstable draws redrawn |"
    echo "|---|---|---|"
  } >>"$table"
  for e in $STIFF_COST_E; do
    cost=$out_dir/cost/E$e
    if [[ ! -f $cost/test.h5 ]]; then
      rm -rf "$cost"
      "$bsms" generate "$root/configs/families/$family.json" --out "$cost" \
        --trajectories "$cost_trajectories" --split 0:0:1 --seed "$seed" --threads "$threads" \
        --set "sample.material.youngs_modulus=$e" "${set_args[@]}"
    fi
    summary=$("$bsms" info "$cost/test.h5")
    ms=$(sed -n 's/.*solver: \([^ ]*\) ms per frame.*/\1/p' <<<"$summary")
    redrawn=$(sed -n 's/.*unstable draws redrawn: \([0-9]*\).*/\1/p' <<<"$summary")
    echo "| $e | ${ms:-n/a} | ${redrawn:-n/a} |" >>"$table"
  done
fi

"$bsms" report "${runs[@]}" --out "$out_dir/report" \
  --title "Stiffness sweep: $family at E = ${moduli// /, } Pa (${seconds} s of training each)"
echo "stiffness: wrote $table, $out_dir/stiffness.png and $out_dir/report/report.md"
