#!/bin/sh
# Runs every test program given, keeps going after failures, and closes with
# the plain summary line "N passed, N failed" counted over the cmocka tests.
#
# The programs run VESICA_TEST_JOBS at a time (default: the machine's
# cores, at most 2): each lane takes the next program not yet taken
# (mkdir is the lock), so give the longest first. With more than one lane
# each program gets one OpenMP thread unless OMP_NUM_THREADS says otherwise
# (the tests that compare thread counts set theirs: test_model, test_quad,
# test_project, test_geom). On 2 cores two lanes of one thread are the
# fastest layout (docs/contributing.md, "Testing"). The outputs are printed whole, in
# the order given, each as soon as it and those before it are done, with
# its wall time. The programs share nothing but /tmp, where each makes its
# own folder (mkdtemp), and no test's result depends on the thread count,
# so the lanes change no result.
#
# OpenBLAS's kernels: the programs choose them (solver/app/blas_core_impl.h); the
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
jobs=${VESICA_TEST_JOBS:-$(nproc 2>/dev/null || echo 1)}
case "$jobs" in '' | *[!0-9]*) echo "VESICA_TEST_JOBS must be a whole number, not '$jobs'"; exit 2 ;; esac
[ "$jobs" -lt 1 ] && jobs=1
[ -z "${VESICA_TEST_JOBS:-}" ] && [ "$jobs" -gt 2 ] && jobs=2
[ "$jobs" -gt 1 ] && export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}

work=$(mktemp -d /tmp/vesica_tests_XXXXXX) || exit 2
trap 'rm -rf "$work"' EXIT
trap 'exit 130' INT TERM

# one lane: the programs nobody has taken yet, in order
lane() {
  i=0
  for t in "$@"; do
    i=$((i + 1))
    mkdir "$work/taken.$i" 2>/dev/null || continue
    t0=$(date +%s)
    "$t" >"$work/$i.out" 2>&1
    echo "$? $(($(date +%s) - t0))" >"$work/$i.rc.tmp" && mv "$work/$i.rc.tmp" "$work/$i.rc"
  done
}
k=0
while [ $k -lt "$jobs" ]; do
  lane "$@" &
  k=$((k + 1))
done

pass=0; fail=0; skip=0; i=0
for t in "$@"; do
  i=$((i + 1))
  while [ ! -f "$work/$i.rc" ]; do sleep 1; done
  read -r rc secs <"$work/$i.rc"
  out=$(cat "$work/$i.out")
  printf '%s\n' "$out"
  echo "# $t: $secs s"
  p=$(printf '%s\n' "$out" | sed -n 's/^\[  PASSED  \] \([0-9]*\) test.*/\1/p' | tail -1)
  f=$(printf '%s\n' "$out" | sed -n 's/^\[  FAILED  \] \([0-9]*\) test.*/\1/p' | tail -1)
  k=$(printf '%s\n' "$out" | sed -n 's/^\[  SKIPPED \] \([0-9]*\) test.*/\1/p' | tail -1)
  skip=$((skip + ${k:-0}))
  pass=$((pass + ${p:-0})); fail=$((fail + ${f:-0}))
  if [ "$rc" -ne 0 ] && [ -z "$f" ]; then
    echo "$t: exited with status $rc"; fail=$((fail + 1))
  fi
done
wait
echo "$pass passed, $fail failed, $skip skipped"
[ $fail -eq 0 ]
