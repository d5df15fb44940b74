#!/bin/sh
# Runs every test program given, keeps going after failures, and closes with
# the plain summary line "N passed, N failed" counted over the cmocka tests.
# OpenBLAS's kernels: the programs choose them (solver/blas_core_impl.h); the
# test programs get the same choice from here (never under valgrind, whose
# CPU has no AVX-512: tests/valgrind.sh does not use this script)
if [ -z "${OPENBLAS_CORETYPE:-}" ]; then
  fl=$(grep -m1 '^flags' /proc/cpuinfo 2>/dev/null)
  case "$fl" in
    *avx512f*avx512dq*) [ -n "$(printf '%s' "$fl" | grep -w avx512bw | grep -w avx512vl)" ] &&
      export OPENBLAS_CORETYPE=SkylakeX ;;
  esac
  [ -z "${OPENBLAS_CORETYPE:-}" ] && case "$fl" in *avx2*) printf '%s' "$fl" | grep -qw fma &&
      export OPENBLAS_CORETYPE=Haswell ;; esac
fi
pass=0; fail=0; skip=0; crashed=0
for t in "$@"; do
  out=$("$t" 2>&1); rc=$?
  printf '%s\n' "$out"
  p=$(printf '%s\n' "$out" | sed -n 's/^\[  PASSED  \] \([0-9]*\) test.*/\1/p' | tail -1)
  f=$(printf '%s\n' "$out" | sed -n 's/^\[  FAILED  \] \([0-9]*\) test.*/\1/p' | tail -1)
  k=$(printf '%s\n' "$out" | sed -n 's/^\[  SKIPPED \] \([0-9]*\) test.*/\1/p' | tail -1)
  skip=$((skip + ${k:-0}))
  pass=$((pass + ${p:-0})); fail=$((fail + ${f:-0}))
  if [ $rc -ne 0 ] && [ -z "$f" ]; then
    echo "$t: exited with status $rc"; crashed=$((crashed + 1)); fail=$((fail + 1))
  fi
done
echo "$pass passed, $fail failed, $skip skipped"
[ $fail -eq 0 ]
