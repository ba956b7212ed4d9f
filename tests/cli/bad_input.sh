#!/usr/bin/env bash
# The bad-input corpus (tests/cli/bad_input/cases.txt), one ctest per case (cli.bad.<name>).
#
#   bad_input.sh setup BSMS SRC WORK         make the inputs every case reads, under WORK/in
#   bad_input.sh case  BSMS SRC WORK NAME    run one case of the table
#   bad_input.sh list  SRC                   the case names, one a line
#   bad_input.sh check SRC                   the table itself: >= 40 cases, unique names, every
#                                            subcommand covered
#
# A case line is `name | exit | regex | absent | command`: the command (shell words, placeholders
# below) must exit with `exit`, print exactly one line on stderr (for exit 2) matching the
# extended regex `regex` (the file, key or option it names), and leave `absent` (a path, or -)
# nonexistent. Placeholders: @BSMS@ the executable, @SRC@ the repository, @CONFIGS@ SRC/configs,
# @FIXTURES@ SRC/tests/fixtures, @IN@ the inputs made by `setup`, @OUT@ a fresh per-case path
# (removed before the case runs). Lines starting with # and blank lines are ignored.
set -u
here=$(cd "$(dirname "$0")" && pwd)
table=$here/bad_input/cases.txt

trim() { local s=$1; s=${s#"${s%%[![:space:]]*}"}; s=${s%"${s##*[![:space:]]}"}; printf '%s' "$s"; }

# Lines of the table that are cases.
cases() { grep -Ev '^[[:space:]]*(#|$)' "$table"; }

subst() {  # subst TEXT: the placeholders replaced
  local s=$1
  s=${s//@BSMS@/$bsms}
  s=${s//@CONFIGS@/$src/configs}
  s=${s//@FIXTURES@/$src/tests/fixtures}
  s=${s//@SRC@/$src}
  s=${s//@IN@/$work/in}
  s=${s//@OUT@/$out}
  printf '%s' "$s"
}

flip() {  # flip the low bit of byte $2 of file $1
  local b
  b=$(od -An -tu1 -j "$2" -N1 "$1" | tr -d ' ')
  printf "\\$(printf %03o $((b ^ 1)))" | dd of="$1" bs=1 seek="$2" conv=notrunc status=none
}

truncate_half() { truncate -s $(($(stat -c %s "$1") / 2)) "$1"; }

# gmsh scripts (.geo), for the cases under "gmsh scripts" in the table: commands bsms refuses
# (the SystemCall would make $in/geo_pwned, which the cases require absent), a loop that never
# ends, a transfinite curve of 3e7 points, a syntax error, an Include of a script with a command.
setup_geo() {
  printf 'Point(1) = {0, 0, 0, 0.1};\nExit;\n' >geo_exit.geo
  printf 'Point(1) = {0, 0, 0, 0.1};\nSystemCall "touch %s/geo_pwned";\n' "$in" >geo_systemcall.geo
  printf 'For i In {1:1e12}\n  x = i;\nEndFor\n' >geo_loop.geo
  cat >geo_transfinite.geo <<'EOF'
Point(1) = {0, 0, 0}; Point(2) = {1, 0, 0}; Point(3) = {1, 1, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 1};
Curve Loop(1) = {1, 2, 3}; Plane Surface(1) = {1};
Transfinite Curve{1} = 3e7;
EOF
  printf 'Point(1) = {0, 0, 0, 0.1};\nPoint(2) = {1, 0, 0, 0.1;\n' >geo_syntax.geo
  printf 'lc = 0.1;\nInclude "geo_included.geo";\n' >geo_include.geo
  printf 'SystemCall "touch %s/geo_pwned";\n' "$in" >geo_included.geo
  sed 's/nan.msh/geo_systemcall.geo/' scene_nan_mesh.json >scene_geo_systemcall.json
  sed 's/nan.msh/geo_loop.geo/' scene_nan_mesh.json >scene_geo_loop.json
}

# --- datasets: damaged values and meshes in otherwise whole datasets, an interrupted generate
# with a damaged part, outputs that would replace inputs. Runs in the setup's folder, after the
# dataset `data` exists. Values are set with the dataset_tamper test helper (BSMS_DATASET_TAMPER,
# set by ctest; else beside the executable's build).
setup_datasets() {
  local tamper=${BSMS_DATASET_TAMPER:-$(dirname "$bsms")/tests/cli/dataset_tamper} n d s
  if [ ! -x "$tamper" ]; then
    echo "setup_datasets: $tamper not built (ninja dataset_tamper): its cases will fail" >&2
    return 0
  fi
  for d in data_inf_vel data_nan_pos data_huge_pos data_bad_mesh data_bad_type; do
    mkdir "$d" && cp data/*.h5 data/generate.json "$d"/
  done
  # velocity [T, N, 2] of frame 2, node 7, component 1; world_pos NaN at frame 3, node 5.
  for s in train test; do
    # Nodes of the split's one trajectory (`bsms info` prints the mean over trajectories).
    n=$("$bsms" info data/$s.h5 | sed -n 's/.* frames, \([0-9]*\)\.0 nodes.*/\1/p')
    "$tamper" data_inf_vel/$s.h5 /trajectories/000000/velocity $((2 * n * 2 + 7 * 2 + 1)) inf
    "$tamper" data_huge_pos/$s.h5 /trajectories/000000/world_pos $((4 * n * 2 + 1)) 3e38
  done
  n=$("$bsms" info data/train.h5 | sed -n 's/.* frames, \([0-9]*\)\.0 nodes.*/\1/p')
  "$tamper" data_nan_pos/train.h5 /trajectories/000000/world_pos $((3 * n * 2 + 5 * 2)) nan
  # Cell 0 repeats node 0; node 4 has a node type outside bsms's 0..3.
  "$tamper" data_bad_mesh/train.h5 /trajectories/000000/cells 0 0
  "$tamper" data_bad_mesh/train.h5 /trajectories/000000/cells 1 0
  "$tamper" data_bad_type/test.h5 /trajectories/000000/node_type 4 7
  # A dataset in the HDF5 format of older bsms versions (no checksums), with the signature of the
  # local heap holding the link name "000000" of /trajectories damaged: the name lookup returns
  # -1 (formerly used as a length: a crash, exit 1).
  "$tamper" --legacy-copy data/test.h5 heap_flip.h5
  local name_at heap_at
  name_at=$(grep -obUa 000000 heap_flip.h5 | head -1 | cut -d: -f1)
  heap_at=$(grep -obUa HEAP heap_flip.h5 | awk -F: -v n="$name_at" '$1 < n { o = $1 } END { print o }')
  flip heap_flip.h5 "$heap_at"
  # A generate folder with two of its three splits (a partial copy, an older bsms).
  mkdir data_no_test && cp data/train.h5 data/valid.h5 data/generate.json data_no_test/
  # Two shard runs into one folder: all three parts, not merged; the test trajectory's part is
  # then cut short, as a full disk or a bad copy would leave it.
  for k in 1 2; do
    "$bsms" generate "$src/configs/families/disks2d.json" --out gen_damaged --trajectories 3 \
      --split 1:1:1 --set frames=6 --set 'sample.count=[2,2]' --threads 1 --shard $k/2 >/dev/null 2>&1
  done
  truncate_half gen_damaged/.parts/traj_000002.h5
}

setup() {
  set -e
  local in=$work/in tmp=$work/in.tmp
  rm -rf "$tmp" "$work/out"
  mkdir -p "$tmp" "$work/out"
  cd "$tmp"
  export OMP_WAIT_POLICY=PASSIVE
  # A tiny dataset (3 trajectories of 6 frames, one per split) and a run trained 3 steps on it.
  "$bsms" generate "$src/configs/families/disks2d.json" --out data --trajectories 3 --split 1:1:1 \
    --set frames=6 --set 'sample.count=[2,2]' --threads 1 >/dev/null 2>&1
  # run.json names the data by its final path; training here reads it where it is now.
  printf '{"data": "%s", "steps": 3, "valid_every": 2, "valid_samples": 2, "normalizer_steps": 2, "model": {"type": "bsms", "latent": 8, "levels": 2}, "optimizer": {"warmup_steps": 1}}\n' \
    "$in/data" >run.json
  "$bsms" train run.json --out run --set data="$tmp/data" --threads 1 >/dev/null 2>&1
  # The same family under a slanted gravity: no reflection or axis swap keeps the scene.
  "$bsms" generate "$src/configs/families/disks2d.json" --out data_slanted --trajectories 3 \
    --split 1:1:1 --set frames=4 --set 'sample.count=[2,2]' --set 'scene.gravity=[1,2]' \
    --threads 1 >/dev/null 2>&1
  cp -r run run_rolled
  "$bsms" rollout run_rolled --threads 1 >/dev/null 2>&1
  cp -r run_rolled run_bad_log
  printf '99,soon,0.5,,,0.001\n' >>run_bad_log/train_log.csv
  rm -rf data/multilevel

  # Damaged datasets.
  mkdir data_trunc data_badvalid data_novalid data_empty data_garbage
  cp data/*.h5 data_trunc/ && truncate_half data_trunc/train.h5 && truncate_half data_trunc/test.h5
  cp data/*.h5 data_badvalid/ && truncate_half data_badvalid/valid.h5
  cp data/train.h5 data/test.h5 data_novalid/
  printf 'not an HDF5 file\n' >data_garbage/train.h5
  printf 'not an HDF5 file\n' >data_garbage/test.h5
  cp data/test.h5 trunc_test.h5 && truncate_half trunc_test.h5
  printf 'plain text\n' >a_file  # a file where a folder is expected: unwritable paths under it
  setup_datasets

  # Damaged runs (each case that could write into its run gets its own copy).
  for r in run_ckpt_trunc run_ckpt_trunc2 run_ckpt_garbage run_ckpt_garbage2 run_ckpt_flip \
           run_no_ckpt run_bad_config run_no_config_data run_other_model run_resume_trunc \
           run_resume_lr run_data_gone; do
    cp -r run "$r"
  done
  truncate_half run_ckpt_trunc/checkpoints/latest.h5
  truncate_half run_ckpt_trunc2/checkpoints/latest.h5
  truncate_half run_resume_trunc/checkpoints/latest.h5
  printf 'this is not a checkpoint\n' >run_ckpt_garbage/checkpoints/latest.h5
  printf 'this is not a checkpoint\n' >run_ckpt_garbage2/checkpoints/latest.h5
  # A byte near the end of the file (HDF5 metadata written last, or a tensor's values).
  flip run_ckpt_flip/checkpoints/latest.h5 $(($(stat -c %s run_ckpt_flip/checkpoints/latest.h5) - 30))
  rm run_no_ckpt/checkpoints/latest.h5
  printf '{"data": ' >run_bad_config/config.json
  sed -i 's#"data": *"[^"]*"#"data": "'"$in"'/no_such_data"#' run_no_config_data/config.json
  sed -i 's#"data": *"[^"]*"#"data": "'"$in"'/data_gone"#' run_data_gone/config.json
  mkdir -p run_bad_metrics/rollout
  cp run/config.json run/train_stats.json run/train_log.csv run_bad_metrics/
  printf '{"rmse_all": ' >run_bad_metrics/rollout/metrics.json

  # Configs and scenes.
  printf '{"dim": 2, "background": ' >scene_broken.json
  cat >nan.msh <<'EOF'
$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
4
1 0 0 0
2 1 0 0
3 nan 1 0
4 0 1 0
$EndNodes
$Elements
2
1 2 2 0 1 1 2 3
2 2 2 0 1 1 3 4
$EndElements
EOF
  head -c 60 nan.msh >truncated.msh
  sed 's/nan/1/' nan.msh >good.msh
  awk 'NR==12{print "1 2 2 0 1 1 2 9"; next} {print}' good.msh >bad_index.msh
  cat >scene_nan_mesh.json <<'EOF'
{
  "dim": 2,
  "background": {"type": "box", "min": [0.0, 0.0], "max": [2.0, 2.0], "element_size": 0.1},
  "bodies": [{"shape": {"type": "mesh", "path": "nan.msh"}, "spacing": 0.1,
              "material": {"model": "neo_hookean", "youngs_modulus": 1000.0, "poisson_ratio": 0.3, "density": 1.0}}],
  "solver": {"end_time": 0.01}
}
EOF
  sed 's/"element_size": 0.1}/"element_size": 0.1}, "colour": "red"/' scene_nan_mesh.json \
    | sed 's/nan.msh/good.msh/' >scene_unknown_key.json
  sed 's/nan.msh/no_such_mesh.msh/' scene_nan_mesh.json >scene_missing_mesh.json
  sed 's/"end_time": 0.01/"end_time": -1/; s/nan.msh/good.msh/' scene_nan_mesh.json >scene_negative_time.json
  setup_geo
  # Training configs, each with one defect.
  local base='"steps": 3, "valid_every": 2, "valid_samples": 2, "normalizer_steps": 2, "model": {"type": "bsms", "latent": 8, "levels": 2}'
  printf '{"data": "%s", %s, "seed": -1}\n' "$in/data" "$base" >train_seed_negative.json
  printf '{"data": "%s", %s}\n' "$in/data" "$base" >train_ok.json
  printf '{"data": "%s", %s, "optimizer": {"lr": "fast"}}\n' "$in/data" "$base" >train_wrong_type.json
  printf '{"data": "%s", %s, "optimizer": {"lr": 0.001, "lr_final": 0.001, "batchsize": 2}}\n' \
    "$in/data" "$base" >train_typo_key.json
  printf '{"data": "%s", %s, "features": {"noise_std": -0.1}}\n' "$in/data" "$base" >train_negative_noise.json
  printf '{"data": "%s", "steps": 3, "model": {"type": "transformer"}}\n' "$in/data" >train_bad_model.json
  printf '{"data": "%s", "steps": 3, "model": {"type": "bsms", "seeding": "best"}}\n' "$in/data" >train_bad_seeding.json
  printf '{"data": "%s", "steps": 3, "model": {"type": "bsms", "levels": 40}}\n' "$in/data" >train_too_many_levels.json
  printf '{"steps": 3, "model": {"type": "bsms"}}\n' >train_no_data.json
  # A family with a defect.
  sed 's/"frame_dt": 0.04/"frame_dt": -0.04/' "$src/configs/families/disks2d.json" >family_negative_dt.json
  printf '{"family": "disks", ' >family_broken.json
  sed 's/"family": "disks"/"family": "teapots"/' "$src/configs/families/disks2d.json" >family_unknown.json

  setup_json
  setup_checkpoints

  chmod -R a-w "$tmp"/run "$tmp"/data 2>/dev/null || true  # (root ignores it; documents intent)
  cd "$work"
  rm -rf "$in"
  mv "$tmp" "$in"
  # The configs and runs name $tmp; the final paths are $in (fixed above where it matters).
  grep -rl --include=config.json "$tmp" "$in" | xargs -r sed -i "s#$tmp#$in#g"
  echo "bad-input corpus: inputs ready in $in"
}

# --- JSON intake, regular files, one-line messages (setup_json) ---
# Inputs of the json_* cases: JSON nested 100,000 deep (a config, a run's config.json, a run's
# metrics.json), a 500,000-element list where an object or an integer is expected, a duplicate
# key, a FIFO as config, control characters in a key and in a dtype, a negative RMSE, and runs to
# resume whose train_stats.json or train_log.csv is damaged.
setup_json() {
  local open close base list
  open=$(head -c 100000 /dev/zero | tr '\0' '[')
  close=$(head -c 100000 /dev/zero | tr '\0' ']')
  printf '{"data": %s%s}\n' "$open" "$close" >json_deep.json
  base='"steps": 3, "valid_every": 2, "valid_samples": 2, "normalizer_steps": 2'
  list=$(yes 0 | head -n 500000 | paste -sd, -)
  printf '{"data": "%s", %s, "model": [%s]}\n' "$in/data" "$base" "$list" >json_list_object.json
  printf '{"data": "%s", %s, "model": {"type": "bsms", "latent": [%s]}}\n' "$in/data" "$base" \
    "$list" >json_list_integer.json
  printf '{"data": "%s", %s, "model": {"type": "bsms", "latent": 8, "type": "mgn"}}\n' \
    "$in/data" "$base" >json_duplicate_key.json
  printf '{"data": "%s", %s, "model": {"type": "bsms", "latent": 8, "levels": 2}, "col\\u001b[31mour\\n": 1}\n' \
    "$in/data" "$base" >json_control_key.json
  mkfifo json_fifo.json
  cp -r "$src/tests/fixtures/meshgraphnets/cylinder_flow" mgn_control_dtype
  sed -i 's/"dtype": "float32"/"dtype": "float\\u001b[2Jbad\\r\\n32"/' mgn_control_dtype/meta.json
  # Runs: a deep config.json; a deep and a negative metrics.json; damaged files to resume from.
  cp -r run json_run_deep_config
  cp json_deep.json json_run_deep_config/config.json
  cp -r run_rolled json_run_deep_metrics
  { printf '{"rmse_all": '; printf '%s%s' "$open" "$close"; printf '}\n'; } \
    >json_run_deep_metrics/rollout/metrics.json
  cp -r run_rolled json_run_negative_rmse
  sed -i -E '/"rmse_all": \{/,/\}/ s/("world_pos": )[0-9.eE+-]+/\1-0.5/' \
    json_run_negative_rmse/rollout/metrics.json
  grep -q '"world_pos": -0.5' json_run_negative_rmse/rollout/metrics.json
  cp -r run json_run_resume_stats
  truncate_half json_run_resume_stats/train_stats.json
  cp -r run json_run_resume_log
  sed -i '2i 1,not-a-time,0.5,,,0.001' json_run_resume_log/train_log.csv
}

# --- checkpoints ---
# Damaged checkpoints (RUN/checkpoints/latest.h5) for rollout, info and train --resume: each
# defect D in ckpt_D (read by rollout and info) and ckpt_D_r (train --resume). The defects the
# file's checksums and digests do not reveal are written by checkpoint_edit (its path in
# $BSMS_CHECKPOINT_EDIT, set by ctest). A run of another model configuration (latent 16) gives
# the foreign checkpoint; an older run has only latest.pt (a LibTorch archive: never read).
setup_checkpoints() {
  local edit=${BSMS_CHECKPOINT_EDIT:?set BSMS_CHECKPOINT_EDIT to the checkpoint_edit tool}
  local ckpt=run/checkpoints/latest.h5 d r
  "$bsms" train run.json --out run_latent16 --set model.latent=16 --set data="$tmp/data" \
    --threads 1 >/dev/null 2>&1
  for d in trunc flip shape drop nan other legacy; do
    for r in ckpt_$d ckpt_${d}_r; do
      cp -r run "$r"
      case $d in
        trunc) truncate_half "$r/checkpoints/latest.h5" ;;
        flip) flip "$r/checkpoints/latest.h5" $(($(stat -c %s $ckpt) / 2)) ;;
        shape) "$edit" $ckpt "$r/checkpoints/latest.h5" reshape model.encoder.first.bias ;;
        drop) "$edit" $ckpt "$r/checkpoints/latest.h5" drop input_normalizer.sum ;;
        nan) "$edit" $ckpt "$r/checkpoints/latest.h5" nan model.encoder.first.weight ;;
        other) cp run_latent16/checkpoints/latest.h5 "$r/checkpoints/latest.h5" ;;
        legacy) mv "$r/checkpoints/latest.h5" "$r/checkpoints/latest.pt" ;;
      esac
    done
  done
  cp -r ckpt_legacy ckpt_legacy_c
  rm -rf run_latent16
}

run_case() {
  local name=$1 line code regex absent cmd
  line=$(cases | awk -F'|' -v n="$name" '{ k=$1; gsub(/[ \t]/, "", k); if (k == n) print }')
  if [ -z "$line" ]; then echo "no case '$name' in $table"; return 1; fi
  if [ "$(printf '%s\n' "$line" | wc -l)" != 1 ]; then echo "case '$name' defined twice"; return 1; fi
  IFS='|' read -r _ code regex absent cmd <<<"$line"
  out=$work/out/$name
  rm -rf "$out"
  mkdir -p "$work/out"
  code=$(trim "$code")
  regex=$(trim "$regex")
  absent=$(subst "$(trim "$absent")")
  cmd=$(subst "$(trim "$cmd")")
  eval "set -- $cmd"
  echo "case $name: $*"
  cd "$work/out" || return 1
  # Every case: within a time limit (a case that blocks, e.g. on a FIFO, or that starts the work
  # it should have refused, fails instead of hanging), and its one line printable (no raw control
  # character) and at most 1000 bytes long.
  OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-PASSIVE} BSMS_EXPECT_LINE_MAX=1000 \
    "$here/expect_exit.sh" --match "$regex" "$code" "$absent" \
    timeout -k 5 "${BSMS_CASE_TIMEOUT:-25}" "$@"
}

check_table() {
  local status=0 n names dup sub
  names=$(cases | awk -F'|' '{ k=$1; gsub(/[ \t]/, "", k); print k }')
  n=$(printf '%s\n' "$names" | wc -l)
  dup=$(printf '%s\n' "$names" | sort | uniq -d)
  [ -n "$dup" ] && { echo "duplicate case names: $dup"; status=1; }
  [ "$n" -ge 40 ] || { echo "only $n cases (want >= 40)"; status=1; }
  if cases | awk -F'|' 'NF != 5' | grep -q .; then
    echo "lines without 5 fields:"; cases | awk -F'|' 'NF != 5'; status=1
  fi
  for sub in simulate generate preprocess train rollout report info export experiment; do
    cases | awk -F'|' '{print $5}' | grep -Eq "@BSMS@ +$sub( |$)" ||
      { echo "no case for bsms $sub"; status=1; }
  done
  [ $status = 0 ] && echo "$n cases, every subcommand covered"
  return $status
}

mode=${1:-}
case $mode in
  setup) bsms=$2 src=$3 work=$4; setup ;;
  case) bsms=$2 src=$3 work=$4; run_case "$5" ;;
  list) cases | awk -F'|' '{ k=$1; gsub(/[ \t]/, "", k); print k }' ;;
  check) check_table ;;
  *) echo "usage: $0 setup|case|list|check ..."; exit 1 ;;
esac
