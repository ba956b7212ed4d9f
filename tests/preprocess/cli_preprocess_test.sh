#!/usr/bin/env bash
# End-to-end checks of `bsms preprocess`: CASE is one of the names below.
# Usage: cli_preprocess_test.sh BSMS_EXE SOURCE_DIR CASE
# Bad input must give exit code 2, exactly one line on stderr naming the problem, and no output
# file (nor temporary) left behind.
set -uo pipefail

bsms=$1
source_dir=$2
case_name=$3
work=$(mktemp -d "${TMPDIR:-/tmp}/bsms-cli-preprocess.XXXXXX")
trap 'rm -rf "$work"' EXIT
out_dir=$work/out
mkdir -p "$out_dir"
out=$out_dir/graph.h5

fail() {
  echo "FAIL [$case_name]: $*" >&2
  exit 1
}

# A unit square as two triangles, .msh 2.2 ASCII; $1 replaces the node block, $2 the elements.
write_msh() {
  local nodes=${2:-$'4\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0'}
  local elements=${3:-$'2\n1 2 2 0 1 1 2 3\n2 2 2 0 1 1 3 4'}
  printf '$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%s\n$EndNodes\n$Elements\n%s\n$EndElements\n' \
    "$nodes" "$elements" >"$1"
}

# Runs bsms preprocess with the given arguments and checks the bad-input contract.
expect_bad_input() {
  local expected_text=$1
  shift
  "$bsms" preprocess "$@" >"$work/stdout" 2>"$work/stderr"
  local rc=$?
  [[ $rc -eq 2 ]] || fail "exit code $rc, expected 2 ($(cat "$work/stderr"))"
  [[ $(wc -l <"$work/stderr") -eq 1 ]] || fail "stderr is not one line: $(cat "$work/stderr")"
  grep -qi -- "$expected_text" "$work/stderr" || fail "stderr lacks '$expected_text': $(cat "$work/stderr")"
  [[ -z $(ls -A "$out_dir") ]] || fail "left behind: $(ls -A "$out_dir")"
  echo "ok [$case_name]: $(cat "$work/stderr")"
}

geometry=$source_dir/configs/geometry/plate_with_holes.geo
write_msh "$work/square.msh"

case $case_name in
  good_geo)
    "$bsms" preprocess --mesh "$geometry" --out "$out" --threads 2 >"$work/stdout" 2>"$work/stderr" ||
      fail "exit code $? ($(cat "$work/stderr"))"
    [[ -s $out ]] || fail "no output file"
    grep -q "level" "$work/stdout" || fail "no level table"
    [[ $(ls -A "$out_dir") == graph.h5 ]] || fail "extra files: $(ls -A "$out_dir")"
    cat "$work/stdout"
    ;;
  good_options)
    for seeding in closecenter minave random; do
      rm -f "$out"
      "$bsms" preprocess --mesh "$geometry" --out "$out" --seeding $seeding --levels 4 --seed 3 \
        --threads 1 >"$work/stdout" 2>"$work/stderr" || fail "$seeding: exit $? ($(cat "$work/stderr"))"
      [[ $(grep -cE '^ +[0-9]+ +[0-9]+ ' "$work/stdout") -eq 4 ]] || fail "$seeding: not 4 levels"
    done
    "$bsms" preprocess --mesh "$work/square.msh" --out "$out" --levels 1 >/dev/null ||
      fail "a two-triangle mesh with one level failed"
    "$bsms" preprocess --help | grep -q -- "--levels" || fail "--help lacks --levels"
    # Thinned coarse levels: the default with --levels auto, on request with a level count.
    rm -f "$out"
    "$bsms" preprocess --mesh "$geometry" --out "$out" >"$work/stdout" 2>&1 ||
      fail "auto levels: exit $?"
    grep -q "coarse levels thinned" "$work/stdout" || fail "auto levels are not thinned"
    "$bsms" preprocess --mesh "$geometry" --out "$out" --levels 4 >"$work/stdout" 2>&1 ||
      fail "4 levels: exit $?"
    grep -q "coarse levels exact A^2" "$work/stdout" || fail "a level count is not exact A^2"
    "$bsms" preprocess --mesh "$geometry" --out "$out" --levels 4 --thinning on \
      >"$work/stdout" 2>&1 || fail "4 thinned levels: exit $?"
    grep -q "4 levels (requested), coarse levels thinned" "$work/stdout" ||
      fail "--thinning on with 4 levels: $(cat "$work/stdout")"
    # The scale benchmark's geometry at its default (coarse) element size.
    "$bsms" preprocess --mesh "$source_dir/configs/geometry/plate_hole.geo" --out "$out" \
      >"$work/stdout" 2>&1 || fail "plate_hole.geo: exit $? ($(cat "$work/stdout"))"
    ;;
  good_data)
    # Every mesh topology of a dataset folder, one file each, named as training's graph cache
    # (GraphStore) names them; a second run reuses them.
    "$bsms" generate "$source_dir/configs/families/disks2d.json" --out "$work/data" \
      --trajectories 3 --split 1:1:1 --set frames=3 --set 'sample.count=[2,2]' --threads 1 \
      >/dev/null 2>&1 || fail "generate: exit $?"
    cache=$work/data/multilevel
    "$bsms" preprocess --data "$work/data" --levels 3 --threads 2 >"$work/stdout" 2>"$work/stderr" ||
      fail "exit code $? ($(cat "$work/stderr"))"
    [[ ! -s $work/stderr ]] || fail "stderr: $(cat "$work/stderr")"
    topologies=$(sed -nE 's/^([0-9]+) topologies, 3 levels, seeding closecenter, .*/\1/p' \
      "$work/stdout")
    [[ -n $topologies && $topologies -ge 1 ]] || fail "no summary line: $(cat "$work/stdout")"
    files=$(ls "$cache" | grep -cE '^closecenter-L3-[0-9a-f]{16}\.h5$')
    [[ $files -eq $topologies && $(ls "$cache" | wc -l) -eq $files ]] ||
      fail "$topologies topologies, files: $(ls "$cache")"
    for file in "$cache"/*.h5; do
      "$bsms" info "$file" >/dev/null 2>&1 || fail "bsms info $file: exit $?"
    done
    "$bsms" preprocess --data "$work/data" --levels 3 >"$work/stdout" 2>&1 || fail "rerun: exit $?"
    [[ $(grep -cE ' cached$' "$work/stdout") -eq $topologies ]] ||
      fail "rerun rebuilt entries: $(cat "$work/stdout")"
    "$bsms" preprocess --data "$work/data" --out "$out_dir/cache" --levels 2 --seeding random \
      --seed 5 >"$work/stdout" 2>&1 || fail "--out, random seeding: exit $? ($(cat "$work/stdout"))"
    [[ $(ls "$out_dir/cache" | grep -cE '^random-s5-L2-[0-9a-f]{16}\.h5$') -eq $topologies ]] ||
      fail "--out, random seeding: $(ls "$out_dir/cache")"
    cat "$work/stdout"
    ;;
  missing_mesh) expect_bad_input "not found" --mesh "$work/none.msh" --out "$out" ;;
  empty_file)
    : >"$work/empty.msh"
    expect_bad_input "empty.msh" --mesh "$work/empty.msh" --out "$out"
    ;;
  truncated_mesh)
    head -c 120 "$work/square.msh" >"$work/cut.msh"
    expect_bad_input "cut.msh" --mesh "$work/cut.msh" --out "$out"
    ;;
  garbage_mesh)
    printf 'this is not a mesh\n' >"$work/garbage.msh"
    expect_bad_input "garbage.msh" --mesh "$work/garbage.msh" --out "$out"
    ;;
  nan_coordinates)
    write_msh "$work/nan.msh" $'4\n1 0 0 0\n2 1 0 0\n3 nan 1 0\n4 0 1 0'
    expect_bad_input "nan.msh" --mesh "$work/nan.msh" --out "$out"
    ;;
  mixed_cells)
    write_msh "$work/mixed.msh" $'5\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 2 0 0' \
      $'2\n1 2 2 0 1 1 2 3\n2 3 2 0 1 2 5 3 1'
    expect_bad_input "mixed.msh" --mesh "$work/mixed.msh" --out "$out"
    ;;
  quad_cells)
    write_msh "$work/quads.msh" "" $'1\n1 3 2 0 1 1 2 3 4'
    expect_bad_input "quads.msh" --mesh "$work/quads.msh" --out "$out"
    ;;
  no_cells)
    write_msh "$work/nocells.msh" "" $'0'
    expect_bad_input "nocells.msh" --mesh "$work/nocells.msh" --out "$out"
    ;;
  unknown_option) expect_bad_input "bogus" --mesh "$work/square.msh" --out "$out" --bogus 1 ;;
  missing_out) expect_bad_input "out" --mesh "$work/square.msh" ;;
  levels_zero) expect_bad_input "levels" --mesh "$work/square.msh" --out "$out" --levels 0 ;;
  levels_text) expect_bad_input "levels" --mesh "$work/square.msh" --out "$out" --levels many ;;
  bad_seeding) expect_bad_input "seeding" --mesh "$work/square.msh" --out "$out" --seeding best ;;
  bad_thinning)
    expect_bad_input "thinning" --mesh "$work/square.msh" --out "$out" --thinning maybe ;;
  bad_threads) expect_bad_input "threads" --mesh "$work/square.msh" --out "$out" --threads -3 ;;
  unwritable_out)
    : >"$work/plain"
    expect_bad_input "plain" --mesh "$work/square.msh" --out "$work/plain/graph.h5"
    ;;
  out_is_folder)
    mkdir -p "$work/folder.h5"
    expect_bad_input "folder" --mesh "$work/square.msh" --out "$work/folder.h5"
    ;;
  *) fail "unknown case" ;;
esac
