#!/usr/bin/env bash
# Usage: corrupt_tfrecord.sh MODE SRC_DIR DST_DIR COMMAND...
# Copies the MeshGraphNets folder SRC_DIR to DST_DIR, damages the copy as MODE says, then runs
# COMMAND (e.g. expect_exit.sh 2 - bsms info DST_DIR). Modes: truncate (drop the last 10 bytes of
# train.tfrecord), flip_data (a byte inside record 0's data), flip_length (record 0's length CRC),
# bad_meta (malformed meta.json), varlen (a field declared dynamic_varlen), no_records (meta.json
# only).
set -eu
mode=$1 src=$2 dst=$3
shift 3
rm -rf "$dst"
mkdir -p "$dst"
cp "$src"/meta.json "$src"/*.tfrecord "$dst"/
chmod u+w "$dst"/*
flip() {  # flip the low bit of byte $2 of file $1
  local b
  b=$(od -An -tu1 -j "$2" -N1 "$1" | tr -d ' ')
  printf "\\$(printf %03o $((b ^ 1)))" | dd of="$1" bs=1 seek="$2" conv=notrunc status=none
}
case $mode in
  truncate) truncate -s -10 "$dst"/train.tfrecord ;;
  flip_data) flip "$dst"/train.tfrecord 100 ;;
  flip_length) flip "$dst"/train.tfrecord 9 ;;
  bad_meta) printf '{"field_names": ' >"$dst"/meta.json ;;
  varlen) sed -i 's/"type": "dynamic"/"type": "dynamic_varlen"/' "$dst"/meta.json ;;
  no_records) rm "$dst"/*.tfrecord ;;
  *) echo "unknown mode $mode"; exit 1 ;;
esac
exec "$@"
