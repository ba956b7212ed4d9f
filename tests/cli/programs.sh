#!/usr/bin/env bash
# Usage: programs.sh BUILD_DIR TMP
# The command line is three programs (src/cli/programs.hpp): the front end `bsms` loads neither
# LibTorch nor libgmsh, `bsms-solver` no LibTorch; the front end hands each command to the
# program that runs it, with its options and exit codes; without its helper it says which one is
# missing (exit 1) rather than failing obscurely.
set -u
build=$1 tmp=$2
status=0
fail() { echo "FAIL: $*"; status=1; }

libs=$(ldd "$build/bsms")
grep -q 'libtorch' <<<"$libs" && fail "bsms links LibTorch"
grep -q 'libgmsh' <<<"$libs" && fail "bsms links libgmsh"
grep -q 'libtorch' <<<"$(ldd "$build/bsms-solver")" && fail "bsms-solver links LibTorch"
grep -q 'libtorch' <<<"$(ldd "$build/bsms-torch")" || fail "bsms-torch does not link LibTorch"

# Handed on: each command's own options come from the program that runs it.
"$build/bsms" simulate --help | grep -q -- '--geo-time-limit' || fail "simulate --help lists no options"
"$build/bsms" train --help | grep -q -- '--resume' || fail "train --help lists no --resume"
"$build/bsms" rollout --threads -1 "$tmp" >/dev/null 2>&1; rc=$?
[ $rc -eq 2 ] || fail "rollout --threads -1: exit $rc, expected 2 (bad input, from bsms-torch)"
# Every command is listed by the front end, and bsms-torch runs every one of them.
for c in convert-checkpoint experiment export generate info preprocess report rollout simulate train; do
  "$build/bsms" --help | grep -q "^  $c " || fail "bsms --help does not list $c"
  "$build/bsms-torch" "$c" --help >/dev/null 2>&1 || fail "bsms-torch $c --help failed"
done

# A front end without its helpers names the one that is missing.
rm -rf "$tmp/alone" && mkdir -p "$tmp/alone" && cp "$build/bsms" "$tmp/alone/"
out=$("$tmp/alone/bsms" train x.json 2>&1); rc=$?
[ $rc -eq 1 ] || fail "train without bsms-torch: exit $rc, expected 1"
grep -q "bsms-torch, which is missing" <<<"$out" || fail "train without bsms-torch: '$out'"
out=$("$tmp/alone/bsms" simulate x.json 2>&1); rc=$?
grep -q "bsms-solver, which is missing" <<<"$out" || fail "simulate without bsms-solver: '$out'"
# What it runs itself still works alone.
"$tmp/alone/bsms" --version | grep -q '^bsms ' || fail "bsms --version alone"
rm -rf "$tmp/alone"
exit $status
