#!/usr/bin/env bash
# Crash safety of `bsms train`: kill -9 at pseudo-random moments, then resume.
#
#   crash_resume.sh BSMS SRC WORK [SEED] [KILLS]
#
# Trains a tiny BSMS model on a tiny generated dataset twice: once without interruption (the
# reference) and once in sessions killed with SIGKILL, each session started again with --resume
# when the run folder holds a checkpoint (without it when it does not: a session killed before
# its first checkpoint starts over). The kills (at least KILLS, default 24) are drawn from SEED
# (default 13): some during start-up (data, config.json, log rewrite, multilevel cache), most
# after a random delay in training, some the moment a checkpoint's temporary file appears (inside
# save_checkpoint) and some the moment it is renamed into place (just after the commit). After
# every kill the run folder must be consistent:
#   - the checkpoint (if any) is readable (`bsms info` describes it);
#   - the log's whole rows are the reference's first rows (wall_s aside), at least up to the
#     checkpoint's step (a torn last line, without newline, is allowed: a resume drops it);
#   - temporary files do not pile up: a session removes those of dead sessions first thing, so
#     besides the killed session's one, only one of an earlier session may be left (when the
#     killed one did not get that far); none once the run is complete;
#   - the next session never fails (no "corrupt checkpoint", no other error).
# When the run is complete it must equal the reference: the same model and optimizer state bit
# for bit (digests of `bsms info RUN/checkpoints/latest.h5`), the same log rows and the same
# final losses in train_stats.json. Should the sessions complete the run before KILLS kills, a
# new run is started (a round) and checked the same way.
set -u
bsms=$(cd "$(dirname "$1")" && pwd)/$(basename "$1") src=$(cd "$2" && pwd) work=$3
seed=${4:-13} want_kills=${5:-24}
export OMP_WAIT_POLICY=PASSIVE
config=$src/configs/train/disks2d-bsms.json
steps=150

fail() {
  echo "FAIL: $*"
  exit 1
}
now_ms() { echo $(($(date +%s%N) / 1000000)); }
rng=$seed
rand() { # rand N: a pseudo-random integer in [0, N) in $draw (no subshell: it keeps the state)
  rng=$(((rng * 1103515245 + 12345) % 2147483648))
  draw=$(((rng / 65536) % $1))
}
seconds() { printf '%d.%03d' $(($1 / 1000)) $(($1 % 1000)); }

rm -rf "$work"
mkdir -p "$work"
cd "$work" || exit 1
start=$(now_ms)

# A tiny dataset (3 trajectories of 8 frames, one per split); the crashing runs train on a copy
# without the multilevel cache, so that they build it (and are killed doing so).
"$bsms" generate "$src/configs/families/disks2d.json" --out data --trajectories 3 --split 1:1:1 \
  --set frames=8 --set 'sample.count=[2,2]' --threads 1 >generate.log 2>&1 ||
  { cat generate.log; fail "bsms generate"; }
cp -r data data_crash

train_args() { # train_args DATA: the shared settings (frequent checkpoints: valid_every 3)
  echo "$config" --set "data=$1" --set steps=$steps --set valid_every=3 --set valid_samples=1 \
    --set normalizer_steps=2 --set model.levels=2 --set model.latent=8 \
    --set optimizer.warmup_steps=1 --threads 1
}
log_rows() { # log_rows LOG: whole rows (newline-terminated) without wall_s, header dropped
  if [ -n "$(tail -c1 "$1")" ]; then sed '$d' "$1"; else cat "$1"; fi | tail -n +2 | cut -d, -f1,3-
}
digests() { # digests RUN: step and model/optimizer digests of the run's checkpoint
  "$bsms" info "$1/checkpoints/latest.h5" | awk '/^  step /{print $1, $2} /digest/{print $1, $NF}'
}
stat_of() { # stat_of FILE KEY: a value of train_stats.json
  sed -n "s/^ *\"$2\": *\\([^,]*\\),*\$/\\1/p" "$1"
}
temporaries() { # temporaries RUN DATA: temporary files (NAME.tmp.PID.N) left in the run and cache
  find "$1" "$2/multilevel" -maxdepth 2 -name '*.tmp.*' 2>/dev/null | sort
}

# The reference, uninterrupted; its timing scales the kill delays.
t0=$(now_ms)
# shellcheck disable=SC2046
"$bsms" train $(train_args "$work/data") --out ref >ref.log 2>&1 ||
  { cat ref.log; fail "reference run"; }
ref_ms=$(($(now_ms) - t0))
ref_digests=$(digests ref)
log_rows ref/train_log.csv >ref_rows.txt
[ "$(wc -l <ref_rows.txt)" = $steps ] || fail "reference log has $(wc -l <ref_rows.txt) rows"
train_ms=$(awk -F, -v n=$steps '$1 == n { printf "%d", $2 * 1000 }' ref/train_log.csv)
startup_ms=$((ref_ms - train_ms))
[ $startup_ms -ge 50 ] || startup_ms=50
# Training delays: up to 2 / KILLS of the run's training time past its start-up, so that most of
# the KILLS kills fall in one run.
window_ms=$((2 * train_ms / want_kills + 20))
echo "reference: $steps steps in $(seconds $ref_ms) s (start-up ~$(seconds $startup_ms) s," \
  "training $(seconds "$train_ms") s); $ref_digests" | tr '\n' ' '
echo

# Compares a finished crash run with the reference.
check_complete() {
  local run=$1 got
  got=$(digests "$run")
  [ "$got" = "$ref_digests" ] || fail "round $round: parameters differ from the reference:
$got
reference:
$ref_digests"
  log_rows "$run/train_log.csv" >rows.txt
  cmp -s rows.txt ref_rows.txt ||
    fail "round $round: log differs from the reference's: $(diff rows.txt ref_rows.txt | head -5)"
  for key in steps final_loss final_valid_loss final_valid_zero_prediction num_parameters; do
    [ "$(stat_of "$run/train_stats.json" $key)" = "$(stat_of ref/train_stats.json $key)" ] ||
      fail "round $round: train_stats.json $key: $(stat_of "$run/train_stats.json" $key)," \
        "reference $(stat_of ref/train_stats.json $key)"
  done
  [ -z "$(temporaries "$run" data_crash)" ] ||
    fail "temporary files left: $(temporaries "$run" data_crash)"
  echo "round $round complete after $round_kills kill(s): parameters, optimizer state, log and" \
    "train_stats.json equal the reference's"
}

kills=0 round=1 round_kills=0 sessions=0 in_checkpoint=0 in_other_write=0 before_first=0
run=crash1
declare -A landed
while :; do
  sessions=$((sessions + 1))
  [ $sessions -le $((want_kills * 4)) ] || fail "too many sessions ($sessions)"
  if [ -f $run/checkpoints/latest.h5 ]; then mode=resume; else mode=fresh; fi
  # Done once there are enough kills and one of them landed inside a checkpoint write (which
  # kinds the draws give depends on timing: a draw for a checkpoint write in a fresh session
  # becomes a start-up kill).
  enough=$([ $kills -ge "$want_kills" ] && echo 1 || echo 0)
  finish=$([ $enough = 1 ] && [ $in_checkpoint -ge 1 ] && echo 1 || echo 0)
  resume_flag=()
  [ $mode = resume ] && resume_flag=(--resume)
  # shellcheck disable=SC2046
  "$bsms" train $(train_args "$work/data_crash") --out $run "${resume_flag[@]}" \
    >session.log 2>&1 &
  pid=$!
  kind=-
  if [ "$finish" = 0 ]; then
    rand 100
    if [ $enough = 1 ]; then # enough kills but none inside a checkpoint write yet: aim for one
      kind=checkpoint delay=1
    # During start-up (half the fresh sessions: kills before the first checkpoint).
    elif [ $draw -lt 15 ] || { [ $mode = fresh ] && [ $draw -lt 50 ]; }; then
      rand $((startup_ms + 1))
      kind=startup delay=$draw
    elif [ $draw -lt 30 ]; then # the moment the K-th checkpoint write of the session begins
      rand 3
      kind=checkpoint delay=$((1 + draw))
    elif [ $draw -lt 40 ]; then # the moment the K-th checkpoint write is committed (renamed)
      rand 3
      kind=committed delay=$((1 + draw))
    else # somewhere in training
      rand "$window_ms"
      kind=training delay=$((startup_ms + draw))
    fi
    if [ $kind = checkpoint ] || [ $kind = committed ]; then
      seen=0 last='' deadline=$((SECONDS + 30))
      shopt -s nullglob
      while kill -0 $pid 2>/dev/null && [ $SECONDS -le $deadline ]; do # (no fork in the loop)
        tmp=("$run/checkpoints/latest.h5.tmp.$pid."*)
        if [ ${#tmp[@]} -gt 0 ] && [ "${tmp[0]}" != "$last" ]; then
          last=${tmp[0]} seen=$((seen + 1))
          [ $seen -ge $delay ] && break
        fi
      done
      if [ $kind = committed ]; then
        while [ -e "$last" ] && kill -0 $pid 2>/dev/null && [ $SECONDS -le $deadline ]; do :; done
      fi
      shopt -u nullglob
    else
      sleep "$(seconds "$delay")"
    fi
    kill -9 $pid 2>/dev/null
  fi
  wait $pid 2>/dev/null # (no "Killed" line)
  status=$?
  if [ $status = 137 ]; then
    kills=$((kills + 1)) round_kills=$((round_kills + 1))
    # Where it landed: a temporary file of the killed session names the write it was in.
    where=training-between-writes
    grep -q 'thread(s) ->' session.log || where='start-up'
    if compgen -G "$run/checkpoints/latest.h5.tmp.$pid.*" >/dev/null; then
      where=in-checkpoint-write in_checkpoint=$((in_checkpoint + 1))
    elif other=$(temporaries $run data_crash | grep "\.tmp\.$pid\."); then
      where="in-write:$(basename "$other" | sed 's/\.tmp\..*//')" # config, log, stats, cache
      in_other_write=$((in_other_write + 1))
    fi
    if [ ! -f $run/checkpoints/latest.h5 ]; then
      where+=",before-first-checkpoint" before_first=$((before_first + 1))
    fi
    landed[$where]=$((${landed[$where]:-0} + 1))
    # The folder after the kill.
    ckpt_step=0
    if [ -f $run/checkpoints/latest.h5 ]; then
      "$bsms" info $run/checkpoints/latest.h5 >info.log 2>&1 ||
        fail "kill $kills: checkpoint unreadable: $(cat info.log)"
      ckpt_step=$(awk '/^  step /{print $2 + 0}' info.log)
    fi
    rows=0
    if [ -f $run/train_log.csv ]; then
      log_rows $run/train_log.csv >rows.txt
      rows=$(wc -l <rows.txt)
      head -n "$rows" ref_rows.txt >ref_head.txt
      cmp -s ref_head.txt rows.txt ||
        fail "kill $kills: log rows are not the reference's: $(diff rows.txt ref_head.txt | head -5)"
    fi
    [ "$rows" -ge "$ckpt_step" ] || fail "kill $kills: log has $rows rows, checkpoint step $ckpt_step"
    # Each session removes those of dead sessions when it starts: besides the killed session's
    # (one write at a time), those of one earlier session at most (if this one was killed before
    # it got to that), never a pile.
    stale=$(temporaries $run data_crash | grep -v "\.tmp\.$pid\.")
    [ "$(temporaries $run data_crash | grep -c "\.tmp\.$pid\.")" -le 1 ] ||
      fail "kill $kills: several temporary files of the killed session:" \
        "$(temporaries $run data_crash)"
    [ "$(printf '%s' "$stale" | grep -c .)" -le 1 ] ||
      fail "kill $kills: temporary files of earlier sessions pile up: $stale"
    case $kind in
      checkpoint) when="as its checkpoint write $delay begins" ;;
      committed) when="as its checkpoint write $delay is renamed into place" ;;
      *) when="$kind, $delay ms" ;;
    esac
    printf 'kill %2d (%s session, %s): %s; checkpoint step %d, %d log rows\n' $kills $mode \
      "$when" "$where" "$ckpt_step" "$rows"
  elif [ $status = 0 ]; then
    [ "$(stat_of $run/train_stats.json steps)" = $steps ] || fail "session ended early"
    check_complete $run
    [ $kills -ge "$want_kills" ] && [ $in_checkpoint -ge 1 ] && break
    round=$((round + 1)) round_kills=0 run=crash$round
  else
    cat session.log
    fail "a $mode session failed (exit $status) after kill $kills"
  fi
done

summary=""
for k in "${!landed[@]}"; do summary+=" $k: ${landed[$k]},"; done
echo "$kills kills in $sessions sessions, $round round(s):${summary%,}"
[ $in_checkpoint -ge 1 ] || fail "no kill landed inside a checkpoint write"
echo "PASS: $in_checkpoint kill(s) inside checkpoint writes, $in_other_write inside other writes," \
  "$before_first before the first checkpoint; $(seconds $(($(now_ms) - start))) s"
