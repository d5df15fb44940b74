#!/usr/bin/env bash
# Cost per accuracy of the discretization settings on a relaxation run: for each
# setting, one `vesica run` of PROBLEM at EPS, timed in CPU seconds, and one TSV
# row on stdout:
#   problem  eps  settings  nodes  cpu_s  peak_MB  E_final  E_final-E_sharp  steps
# (problem: the file's name without .ini, so that rows of several problems
# share one table).
# A setting is a space-separated list of geometry KEY=V overrides ("default":
# none beyond the problem file). Runs go one at a time, single-threaded, at
# nice 5 above the caller's, so that CPU seconds compare across settings on a
# shared machine.
# Results and their reading: docs/results.md, "Convergence in ε and h".
# Needs /usr/bin/time (Debian package time).
#
# usage: bench/pareto.sh PROBLEM EPS E_SHARP 'SETTING' ['SETTING' ...]
#   env VESICA (default build/vesica), OUTDIR (default /tmp/pareto/runs),
#   EXTRA (further --set arguments for every run, e.g. "--set constraints.area=1")
# example:
#   bench/pareto.sh problems/oblate.ini 0.01 7.652042 default 'h_band=0.6' \
#     'band=3 support_tol=1e-5'
set -euo pipefail
[ $# -ge 4 ] || { sed -n '2,17p' "$0"; exit 2; }
problem=$1 eps=$2 esharp=$3
shift 3
vesica=${VESICA:-build/vesica}
outdir=${OUTDIR:-/tmp/pareto/runs}
timebin=/usr/bin/time
mkdir -p "$outdir"
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1

pname=$(basename "$problem" .ini)
printf 'problem\teps\tsettings\tnodes\tcpu_s\tpeak_MB\tE_final\tE_minus_sharp\tsteps\n'
for setting in "$@"; do
  args=()
  tag=eps${eps}
  if [ "$setting" != default ]; then
    for kv in $setting; do
      args+=(--set "geometry.$kv")
      tag+="_${kv//=/}"
    done
  fi
  out=$outdir/${pname}_$tag.h5
  tfile=$outdir/$(basename "$out" .h5).time
  # a run that does not finish (exit != 0: failed, refused, its file in use
  # by another run) gives no row: its file may not be its own
  rc=0
  # shellcheck disable=SC2086
  nice -n 5 "$timebin" -o "$tfile" -f '%U %S %M' "$vesica" run "$problem" \
    --set geometry.epsilon="$eps" "${args[@]}" ${EXTRA:-} \
    --out "$out" --force --quiet || rc=$?
  if [ "$rc" != 0 ]; then
    echo "pareto.sh: $setting: vesica run exit $rc: no row (run it alone to see why)" >&2
    continue
  fi
  read -r usr sys rss < <(tail -n 1 "$tfile")
  "$vesica" info "$out" | awk -v prob="$pname" -v eps="$eps" -v set="$setting" -v es="$esharp" \
    -v usr="$usr" -v sys="$sys" -v rss="$rss" -F ' = ' '
    { v[$1] = $2 }
    END {
      st = (v["status"] == "finished") ? "" : " [" v["status"] "]"
      printf "%s\t%s\t%s%s\t%d\t%.1f\t%.0f\t%.6f\t%+.2e\t%d\n", prob, eps, set, st, v["nodes"],
        usr + sys, rss / 1024, v["energy_final"], v["energy_final"] - es, v["steps"]
    }'
done
