#!/usr/bin/env bash
# Data-parallel training over c10d/Gloo on loopback, in bounded time.
#
#   distributed.sh BSMS CHECKPOINT_DIFF SRC WORK
#
# 1. Equivalence: 2 ranks with batch size 1 give the same model as 1 rank with batch size 2
#    after 20 steps from the same seed (float tolerance); 1 rank with batch size 1 does not (the
#    comparison can fail).
# 2. Resume: a 2-rank run stopped at step 10 (--until) and resumed with 2 ranks ends bit for bit
#    where the uninterrupted 2-rank run ends; resumed with 1 rank it continues and says that the
#    sample sequence changed.
# 3. Faults: rank 1 killed (SIGKILL) mid-run, then rank 1 stopped (SIGSTOP, a hang): the run stops
#    within the timeout with lines naming rank 1 and the step; the checkpoint stays readable and
#    --resume continues from it.
# 4. Rendezvous: a port already in use and an unreachable master give exit 2 and one line.
set -u
bsms=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
diff_tool=$(cd "$(dirname "$2")" && pwd)/$(basename "$2")
src=$(cd "$3" && pwd) work=$4
export OMP_WAIT_POLICY=PASSIVE
unset WORLD_SIZE RANK LOCAL_RANK MASTER_ADDR MASTER_PORT NODE_RANK

fail() {
  echo "FAIL: $*"
  exit 1
}
rm -rf "$work"
mkdir -p "$work"
cd "$work" || exit 1

"$bsms" generate "$src/configs/families/disks2d.json" --out data --trajectories 3 --split 1:1:1 \
  --set frames=8 --set 'sample.count=[2,2]' --threads 1 >generate.log 2>&1 ||
  { cat generate.log; fail "bsms generate"; }
[ "$("$bsms" info data | grep -c ': bsms dataset')" = 3 ] ||
  fail "bsms info DATA_FOLDER does not describe the 3 splits"

common=("$src/configs/train/disks2d-bsms.json" --set data=data --set valid_every=5
  --set valid_samples=1 --set normalizer_steps=2 --set model.levels=2 --set model.latent=16
  --set optimizer.warmup_steps=1 --threads 1)
digest() { "$bsms" info "$1/checkpoints/latest.h5" | grep -i digest; }

# 1. Equivalence --------------------------------------------------------------------------------
"$bsms" train "${common[@]}" --set steps=20 --set optimizer.batch_size=2 --out one_b2 \
  >one_b2.log 2>&1 || { cat one_b2.log; fail "1 rank x 2"; }
"$bsms" train "${common[@]}" --set steps=20 --set optimizer.batch_size=1 --out two_b1 --nproc 2 \
  --timeout 20 >two_b1.log 2>&1 || { cat two_b1.log; fail "2 ranks x 1"; }
"$bsms" train "${common[@]}" --set steps=20 --set optimizer.batch_size=1 --out one_b1 \
  >one_b1.log 2>&1 || { cat one_b1.log; fail "1 rank x 1"; }
"$diff_tool" one_b2/checkpoints/latest.h5 two_b1/checkpoints/latest.h5 1e-3 ||
  fail "2 ranks x batch 1 differ from 1 rank x batch 2"
"$diff_tool" one_b2/checkpoints/latest.h5 one_b1/checkpoints/latest.h5 1e-3 >/dev/null &&
  fail "1 rank x batch 1 equals 1 rank x batch 2: the comparison cannot fail"
grep -q '"world_size": 2' two_b1/config.json || fail "config.json lacks world_size 2"
[ "$(wc -l <two_b1/train_log.csv)" = 21 ] || fail "rank 0's log should hold 20 rows"

# 2. Resume -------------------------------------------------------------------------------------
"$bsms" train "${common[@]}" --set steps=20 --set optimizer.batch_size=1 --out resumed \
  --nproc 2 --timeout 20 --until 10 >resumed.log 2>&1 || { cat resumed.log; fail "2 ranks until 10"; }
cp -r resumed resumed_n1
"$bsms" train "${common[@]}" --set steps=20 --set optimizer.batch_size=1 --out resumed \
  --nproc 2 --timeout 20 --resume >>resumed.log 2>&1 || { cat resumed.log; fail "2 ranks resume"; }
[ "$(digest resumed)" = "$(digest two_b1)" ] || fail "resumed 2-rank run differs from the uninterrupted one"
"$bsms" train "${common[@]}" --set steps=20 --set optimizer.batch_size=1 --out resumed_n1 \
  --resume >resumed_n1.log 2>&1 || { cat resumed_n1.log; fail "resume with 1 rank"; }
grep -q "sample sequence changed" resumed_n1.log || { cat resumed_n1.log; fail "no word on the changed sample sequence"; }

# 3. Faults -------------------------------------------------------------------------------------
# fault NAME SIGNAL: start a long 2-rank run, wait for its first checkpoint, signal rank 1.
fault() {
  local name=$1 sig=$2
  "$bsms" train "${common[@]}" --set steps=100000 --set optimizer.batch_size=1 --out "$name" \
    --nproc 2 --timeout 5 >"$name.log" 2>&1 &
  local launcher=$!
  for _ in $(seq 600); do
    [ -f "$name/checkpoints/latest.h5" ] && break
    sleep 0.1
  done
  [ -f "$name/checkpoints/latest.h5" ] || { cat "$name.log"; fail "$name: no checkpoint"; }
  local rank1
  rank1=$(pgrep -P $launcher | sort -n | tail -1)
  [ -n "$rank1" ] || fail "$name: rank 1 not found"
  local start=$SECONDS
  kill -s "$sig" "$rank1"
  wait $launcher
  local code=$?
  kill -9 "$rank1" 2>/dev/null
  local took=$((SECONDS - start))
  [ $code -ne 0 ] || fail "$name: the run succeeded after rank 1 was signalled"
  [ $took -le 40 ] || fail "$name: the others took ${took} s to stop (timeout 5 s)"
  grep -q "rank 0, step [0-9]*: all-reduce" "$name.log" || { cat "$name.log"; fail "$name: no line naming rank 0's step"; }
  grep -q "rank 1" "$name.log" || { cat "$name.log"; fail "$name: no line naming rank 1"; }
  "$bsms" info "$name/checkpoints/latest.h5" >/dev/null || fail "$name: checkpoint unreadable"
  local at
  at=$("$bsms" info "$name/checkpoints/latest.h5" | sed -n 's/.*step \([0-9]*\).*/\1/p' | head -1)
  [ -n "$at" ] || fail "$name: no step in bsms info"
  "$bsms" train "${common[@]}" --set steps=$((at + 3)) --set optimizer.batch_size=1 \
    --out "$name" --nproc 2 --timeout 20 --resume >"$name.resume.log" 2>&1 ||
    { cat "$name.resume.log"; fail "$name: resume"; }
  echo "$name: stopped ${took} s after the signal; resumed from step $at"
}
fault killed KILL
fault hung STOP

# 4. Rendezvous ---------------------------------------------------------------------------------
port=$((20000 + RANDOM % 20000))
MASTER_PORT=$port WORLD_SIZE=2 RANK=0 "$bsms" train "${common[@]}" --set steps=5 --out holder \
  --timeout 30 >holder.log 2>&1 &
holder=$!
# Wait until the holder listens on the port (/proc/net/tcp*, state 0A = LISTEN).
hex=$(printf '%04X' $port)
for _ in $(seq 600); do
  grep -q ":$hex [0-9A-F:]* 0A " /proc/net/tcp /proc/net/tcp6 2>/dev/null && break
  sleep 0.1
done
grep -q ":$hex [0-9A-F:]* 0A " /proc/net/tcp /proc/net/tcp6 2>/dev/null ||
  { cat holder.log; fail "the port holder never listened on $port"; }
start=$SECONDS
MASTER_PORT=$port WORLD_SIZE=2 RANK=0 "$bsms" train "${common[@]}" --set steps=5 --out taken \
  --timeout 5 >taken.log 2>&1
code=$?
kill $holder 2>/dev/null
wait $holder 2>/dev/null
[ $code = 2 ] || { cat taken.log; fail "port in use: exit $code, expected 2"; }
[ "$(wc -l <taken.log)" = 1 ] && grep -q "MASTER_PORT=$port.*in use" taken.log ||
  { cat taken.log; fail "port in use: expected one line naming MASTER_PORT"; }
[ -e taken ] && fail "port in use: left a run folder"
MASTER_PORT=$port WORLD_SIZE=2 RANK=1 "$bsms" train "${common[@]}" --set steps=5 --out unreached \
  --timeout 3 >unreached.log 2>&1
code=$?
[ $code = 2 ] || { cat unreached.log; fail "unreachable master: exit $code, expected 2"; }
[ "$(wc -l <unreached.log)" = 1 ] && grep -q "cannot reach the master" unreached.log ||
  { cat unreached.log; fail "unreachable master: expected one line"; }
[ $((SECONDS - start)) -le 60 ] || fail "rendezvous errors took $((SECONDS - start)) s"
echo "distributed: all checks passed in ${SECONDS} s"
