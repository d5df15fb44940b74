#!/bin/sh
# The small cases under valgrind (memcheck): the program's setup, steps with
# every backend (NLopt's on CHOLMOD's factor, ~20 s), resets of the reference,
# HDF5 output, a restart after a reset, info, spectrum. A case passes when valgrind
# reports no error and no definite leak and the program exits as expected.
# Closes with "N passed, N failed"; exit 1 on a failure.
#
#   sh tests/valgrind.sh [build/vesica]        (make valgrind)
set -u
V=${1:-build/vesica}
command -v valgrind >/dev/null 2>&1 || {
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends valgrind
  else
    echo "valgrind is missing: apt-get install -y --no-install-recommends valgrind"; exit 1
  fi
}
# OpenBLAS's SSE kernels: valgrind emulates them ~5x faster than the AVX2
# ones OpenBLAS picks for valgrind's virtual CPU (dgemm 100 x 100 x 36:
# 0.2 against < 0.05 GFLOP/s under memcheck; the case "newton, resets every
# step" 80 s against 272 s), and the model's Hessians are dgemms
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 OPENBLAS_CORETYPE=Prescott
D=$(mktemp -d "${TMPDIR:-/tmp}/vesica_vg_XXXXXX")
trap 'rm -rf "$D"' EXIT
# the small vesicle of tests/cli_test_impl.h (TINY): 331 nodes, ~0.3 s a step
TINY="--set geometry.epsilon=0.2 --set geometry.box_r=2 --set geometry.box_z=2
 --set geometry.band=2 --set geometry.h_band=0.7 --set geometry.h_far=0.3
 --set shape.mode=2 --set shape.delta=0.15 --set time.dt_initial=5e-3"
VG="valgrind -q --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=definite"
pass=0; fail=0
case_() { # name, then the command's arguments
  name=$1; shift
  t0=$(date +%s)
  $VG "$V" "$@" >"$D/out" 2>"$D/err"; rc=$?
  if [ $rc -eq 0 ]; then
    pass=$((pass + 1)); echo "ok   $name ($(($(date +%s) - t0)) s)"
  else
    fail=$((fail + 1)); echo "FAIL $name (exit $rc)"; tail -30 "$D/err"
  fi
}
P=problems/sphere.ini
case_ check check $P $TINY
case_ "newton, resets every step" run $P $TINY --set reconnect.every=1 --max-steps 2 --quiet \
  --out "$D/a.h5"
case_ "restart after the resets" run --restart "$D/a.h5" --max-steps 3 --quiet
case_ info info "$D/a.h5"
case_ "spectrum after the resets" spectrum "$D/a.h5" --modes 2 --lanczos 10 --vectors "$D/m.tsv"
case_ ipopt run $P $TINY --backend ipopt --max-steps 1 --quiet --out "$D/b.h5"
case_ euler run $P $TINY --backend euler --max-steps 2 --quiet --out "$D/c.h5"
case_ nlopt run $P $TINY --backend nlopt --max-steps 1 --quiet --out "$D/d.h5"
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
