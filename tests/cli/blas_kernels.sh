#!/usr/bin/env bash
# Usage: blas_kernels.sh BSMS
# The bsms executable runs OpenBLAS's vector kernels wherever the CPU has them (core/runtime.hpp
# blas_core_override): `bsms --version` names the BLAS build and kernel set; on a CPU with AVX2
# and FMA that set must be an AVX2 or AVX-512 one, whatever OpenBLAS's own detection says
# (Debian 12's 0.3.21 says Prescott on CPU models it does not know). OPENBLAS_CORETYPE set by
# the user is kept as given.
set -u
bsms=$1
status=0
core_of() { sed -n 's/^BLAS: OpenBLAS .* \([A-Za-z0-9]*\) MAX_THREADS=.*/\1/p'; }  # the kernel set's name
lower() { tr '[:upper:]' '[:lower:]'; }

out=$(env -u OPENBLAS_CORETYPE -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT "$bsms" --version)
if ! grep -q '^BLAS: OpenBLAS' <<<"$out"; then
  echo "bsms --version names no OpenBLAS (make deps installs it):"; echo "$out"; exit 1
fi
flags=$(grep -m1 '^flags' /proc/cpuinfo)
if grep -qw avx2 <<<"$flags" && grep -qw fma <<<"$flags"; then
  # OpenBLAS's own names of its AVX2 and AVX-512 kernel sets, as this build spells them (0.3.21
  # says "Cooperlake" where others say "CooperLake"): each set this CPU can run is requested
  # through OPENBLAS_CORETYPE and its name read back. A set this build does not have falls back
  # to OpenBLAS's detection, whose answer is then not taken for a vector set.
  candidates="Haswell Zen"
  avx512=yes
  for f in avx512f avx512bw avx512dq avx512vl avx512cd; do grep -qw $f <<<"$flags" || avx512=no; done
  [ $avx512 = yes ] && candidates="$candidates SkylakeX Cooperlake SapphireRapids"
  vector_cores=()
  for c in $candidates; do
    got=$(OPENBLAS_CORETYPE=$c "$bsms" --version 2>/dev/null | core_of)
    [ "$(lower <<<"$got")" = "$(lower <<<"$c")" ] && vector_cores+=("$got")
  done
  [ ${#vector_cores[@]} -gt 0 ] || { echo "OpenBLAS runs none of the vector sets ($candidates)"; exit 1; }
  echo "OpenBLAS's vector kernel sets on this CPU: ${vector_cores[*]}"
  # Once with both variables to set (one re-exec for both), once with the wait policy given.
  for unset_omp in yes no; do
    if [ $unset_omp = yes ]; then
      out=$(env -u OPENBLAS_CORETYPE -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT "$bsms" --version)
    else
      out=$(env -u OPENBLAS_CORETYPE OMP_WAIT_POLICY=PASSIVE "$bsms" --version)
    fi
    core=$(core_of <<<"$out")
    if ! printf '%s\n' "${vector_cores[@]}" | grep -qx -- "$core"; then
      echo "CPU has AVX2 and FMA but OpenBLAS runs '$core' kernels (wait policy unset: $unset_omp):"
      echo "$out"; status=1
    fi
  done
else
  echo "CPU without AVX2 + FMA: only the user's choice is checked"
fi
out=$(OPENBLAS_CORETYPE=Prescott "$bsms" --version)
core=$(core_of <<<"$out")
if [ "$core" != Prescott ]; then
  echo "OPENBLAS_CORETYPE=Prescott given, but OpenBLAS runs '$core':"; echo "$out"; status=1
fi
exit $status
