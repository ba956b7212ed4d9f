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
  truncate_half run_ckpt_trunc/checkpoints/latest.pt
  truncate_half run_ckpt_trunc2/checkpoints/latest.pt
  truncate_half run_resume_trunc/checkpoints/latest.pt
  printf 'this is not a checkpoint\n' >run_ckpt_garbage/checkpoints/latest.pt
  printf 'this is not a checkpoint\n' >run_ckpt_garbage2/checkpoints/latest.pt
  # A byte deep inside the archive (a tensor's data or the zip's directory).
  flip run_ckpt_flip/checkpoints/latest.pt $(($(stat -c %s run_ckpt_flip/checkpoints/latest.pt) - 30))
  rm run_no_ckpt/checkpoints/latest.pt
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

  chmod -R a-w "$tmp"/run "$tmp"/data 2>/dev/null || true  # (root ignores it; documents intent)
  cd "$work"
  rm -rf "$in"
  mv "$tmp" "$in"
  # The configs and runs name $tmp; the final paths are $in (fixed above where it matters).
  grep -rl --include=config.json "$tmp" "$in" | xargs -r sed -i "s#$tmp#$in#g"
  echo "bad-input corpus: inputs ready in $in"
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
  OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-PASSIVE} "$here/expect_exit.sh" --match "$regex" "$code" "$absent" "$@"
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
