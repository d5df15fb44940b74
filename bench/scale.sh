#!/bin/sh
# The cost of a run against the interface width and the thread count: one
# table of bench_scale rows (sizes; setup and its parts; one evaluation,
# Hessian, K, MUMPS analysis and KKT factorization; the mean wall time of the
# first NSTEPS newton steps; process CPU time; peak memory), one process per
# (eps, threads) so each row's peak_MB is its own. OMP_NUM_THREADS and
# OPENBLAS_NUM_THREADS are both set to the thread count of the row.
#
#   sh bench/scale.sh                                  eps 0.04 0.02 0.01 x threads 1 2
#   EPS_LIST=0.04 THREADS_LIST="1 2" sh bench/scale.sh  (eps 0.04: ~1 min a row)
#   make bench BENCH_ONLY=scale   (also the log-log plot: bench/scale_plot.sh)
#
# Environment: BENCH_SCALE (build/bench/bench_scale), PROBLEM
# (problems/oblate.ini), EPS_LIST, THREADS_LIST, NSTEPS (3). A failed row is
# reported on stderr and the table goes on; the exit status is then 1.
set -u
B=${BENCH_SCALE:-build/bench/bench_scale}
PROBLEM=${PROBLEM:-problems/oblate.ini}
EPS_LIST=${EPS_LIST:-0.04 0.02 0.01}
THREADS_LIST=${THREADS_LIST:-1 2}
NSTEPS=${NSTEPS:-3}
[ -x "$B" ] || { echo "scale.sh: $B not built (make $B)" >&2; exit 1; }
echo "# bench_scale $PROBLEM, $NSTEPS steps, $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
header=1 rc=0
for eps in $EPS_LIST; do
  for thr in $THREADS_LIST; do
    if BENCH_HEADER=$header OMP_NUM_THREADS=$thr OPENBLAS_NUM_THREADS=$thr \
       "$B" "$PROBLEM" "$eps" "$NSTEPS"; then
      header=0
    else
      echo "scale.sh: eps $eps, $thr thread(s): failed" >&2
      rc=1
    fi
  done
done
exit $rc
