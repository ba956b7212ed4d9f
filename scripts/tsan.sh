#!/usr/bin/env bash
# ThreadSanitizer pass over the OpenMP-parallel kernels (make sanitize-thread).
# Usage: scripts/tsan.sh BUILD_DIR TEST_BINARY...
#
# The binaries are built with clang, -fsanitize=thread and LLVM's OpenMP runtime. The runtime itself
# is not instrumented; its Archer tool (OMP_TOOL_LIBRARIES) tells TSan about OpenMP's barriers,
# reductions and task dependencies, so that only real races in our code are reported. With GCC's
# libgomp the same run reports every barrier as a race. Each binary runs with 2 OpenMP threads;
# the solver tests run a subset (the full solver suite takes hours under TSan) chosen to cover each
# parallel kernel: particle-to-grid scatter, grid update, grid-to-particle gather, the contact
# and seeding kernels, and the thread-count invariance checks.
set -euo pipefail
build=$1
shift
archer=$(ls /usr/lib/llvm-*/lib/libarcher.so 2>/dev/null | sort -V | tail -1)
[ -n "$archer" ] || { echo "tsan.sh: libarcher.so not found (install libomp-14-dev)" >&2; exit 2; }
export OMP_TOOL_LIBRARIES=$archer OMP_NUM_THREADS=2 OMP_WAIT_POLICY=PASSIVE
export ARCHER_OPTIONS="verbose=0"
# ignore_noninstrumented_modules: the OpenMP runtime itself is not instrumented (its own locks
# would be reported as races); our code is, so a race in it is still found.
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 report_signal_unsafe=0 ignore_noninstrumented_modules=1"

declare -A filter=(
  [test_mpm]='RotatingSquare.ThreadCountDoesNotChangeTheResult:UmlsKernel.*:BsplineKernel.*:BackgroundMesh.*:VibratingBar.CentreOfMass*:SolverStress.ParticleLeaving*:HenckyJ2.*:Slope.SceneParses*'
)
status=0
for t in "$@"; do
  exe=$(find "$(cd "$build" && pwd)/tests" -name "$t" -type f -perm -u+x | head -1)
  [ -n "$exe" ] || { echo "tsan.sh: $t not built in $build" >&2; exit 2; }
  args=()
  [ -n "${filter[$t]:-}" ] && args+=("--gtest_filter=${filter[$t]}")
  echo "== $t ${args[*]:-}"
  start=$(date +%s)
  if (cd "$(dirname "$exe")" && "$exe" "${args[@]}" >"/tmp/tsan_$t.log" 2>&1); then
    echo "   clean: $(grep -c '^\[       OK \]' "/tmp/tsan_$t.log") tests, $(( $(date +%s) - start )) s"
  else
    status=1
    grep -A40 -m1 "WARNING: ThreadSanitizer" "/tmp/tsan_$t.log" || tail -40 "/tmp/tsan_$t.log"
    echo "   FAILED (log /tmp/tsan_$t.log)"
  fi
done
exit $status
