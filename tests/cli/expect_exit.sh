#!/usr/bin/env bash
# Usage: expect_exit.sh [--match REGEX] CODE ABSENT_PATH COMMAND...
# Runs COMMAND, checks its exit code is CODE, that it printed exactly one line on stderr (when
# CODE is 2), that this line matches the extended regular expression REGEX (when given: the
# file, key or option the message must name) and that ABSENT_PATH (use - for none) does not
# exist afterwards.
set -u
match=
if [ "${1:-}" = --match ]; then
  match=$2
  shift 2
fi
want=$1 absent=$2
shift 2
err=$(mktemp)
"$@" 2>"$err" >/dev/null
got=$?
lines=$(wc -l <"$err")
status=0
if [ "$got" != "$want" ]; then
  echo "expected exit $want, got $got: $*"; cat "$err"; status=1
fi
if [ "$want" = 2 ] && [ "$lines" != 1 ]; then
  echo "expected one line on stderr, got $lines:"; cat "$err"; status=1
fi
# BSMS_EXPECT_LINE_MAX=N (the bad-input corpus): the one line of an exit 2 must be printable (no
# control character: a newline, an escape sequence from a file's key) and at most N bytes.
if [ -n "${BSMS_EXPECT_LINE_MAX:-}" ] && [ "$want" = 2 ]; then
  if LC_ALL=C grep -q '[[:cntrl:]]' "$err"; then
    echo "stderr holds a raw control character:"; LC_ALL=C od -c "$err" | head -20; status=1
  fi
  bytes=$(($(wc -c <"$err") - 1))
  if [ "$bytes" -gt "$BSMS_EXPECT_LINE_MAX" ]; then
    echo "stderr line of $bytes bytes, more than $BSMS_EXPECT_LINE_MAX:"; head -c 400 "$err"; echo
    status=1
  fi
fi
if [ -n "$match" ] && ! grep -Eq -e "$match" "$err"; then
  echo "stderr does not match /$match/:"; cat "$err"; status=1
fi
if [ "$absent" != - ] && [ -e "$absent" ]; then
  echo "output $absent exists after a failed run"; status=1
fi
[ $status = 0 ] && echo "ok: exit $got: $(cat "$err")"
rm -f "$err"
exit $status
