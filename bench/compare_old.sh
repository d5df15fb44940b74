#!/bin/sh
# Old build against new: builds an older commit (default 62fcb5a) in a
# temporary folder and runs its vesica and the current build/vesica
# alternately (ABBA: the order flips every repeat, so a drift in the
# machine's load does not favour one side) on the same two commands,
#
#   check PROBLEM --set geometry.epsilon=EPS
#   run   PROBLEM --set geometry.epsilon=EPS --max-steps STEPS --quiet --out T/X.h5 --series T/X.tsv
#
# R times each, recording wall time, user + sys CPU time and peak memory
# (/usr/bin/time), setup_seconds (printed by check; from `vesica info` of
# the run's file), the mean per-step solve seconds (the series text's
# solve_seconds, "seconds" in an older text) and the Newton iterations
# (iterations, or "iter"; summed: the same work on both sides);
# then prints one table of old, new and old/new ratio, each the median over
# the R repeats.
#
# Environment: both programs get the same one. OPENBLAS_NUM_THREADS and
# OMP_NUM_THREADS are pinned to THREADS, and OPENBLAS_CORETYPE is UNSET for
# both: the environment a user has. The new vesica then re-executes itself
# with OPENBLAS_CORETYPE set when OpenBLAS fell back to its generic kernels
# (solver/app/blas_core_impl.h) while the old one keeps the generic kernels, so
# the ratios include that kernel choice: this is the honest user-facing
# comparison. CORETYPE=SkylakeX (or Haswell, ...) sets OPENBLAS_CORETYPE for
# both instead, which separates the code changes from the kernel choice.
#
# Usage: sh bench/compare_old.sh [COMMIT]      (from anywhere in the repository)
#   EPS (0.04), STEPS (2), R (3), THREADS (1), PROBLEM (problems/oblate.ini),
#   VESICA (build/vesica: the new program, copied before the first run so a
#   rebuild meanwhile does not change it), OLD_VESICA (a prebuilt old program:
#   skips the build), CORETYPE (empty: unset), KEEP=1 keeps the temporary
#   folder (printed). At eps 0.04 one repeat of both commands on both sides
#   takes ~3 min on 2 cores (plus ~3 min for building the old commit).
set -u
OLD=${1:-62fcb5a}
EPS=${EPS:-0.04}
STEPS=${STEPS:-2}
R=${R:-3}
THREADS=${THREADS:-1}
PROBLEM=${PROBLEM:-problems/oblate.ini}
CORETYPE=${CORETYPE:-}
KEEP=${KEEP:-0}
cd "$(git rev-parse --show-toplevel)" || exit 1
NEWSRC=${VESICA:-build/vesica}
[ -x "$NEWSRC" ] || { echo "compare_old.sh: $NEWSRC not built (make build/vesica)" >&2; exit 1; }
[ -x /usr/bin/time ] || { echo "compare_old.sh: needs /usr/bin/time (Debian package time)" >&2; exit 1; }

tmp=$(mktemp -d "${TMPDIR:-/tmp}/vesica_compare.XXXXXX") || exit 1
# shellcheck disable=SC2317 # (called by the trap)
cleanup() { if [ "$KEEP" = 1 ]; then echo "# kept $tmp" >&2; else rm -rf "$tmp"; fi; }
trap cleanup EXIT
trap 'exit 130' INT TERM

cp "$NEWSRC" "$tmp/vesica_new" || exit 1
NEW=$tmp/vesica_new
if [ -n "${OLD_VESICA:-}" ]; then
  OLDBIN=$OLD_VESICA
else
  echo "# building $OLD in $tmp/old (log: $tmp/build.log)" >&2
  git rev-parse --verify -q "$OLD^{commit}" >/dev/null || {
    echo "compare_old.sh: '$OLD' is not a commit" >&2; exit 1; }
  mkdir "$tmp/old" || exit 1
  git archive "$OLD" | tar -x -C "$tmp/old" || {
    echo "compare_old.sh: git archive $OLD failed" >&2; exit 1; }
  make -C "$tmp/old" -j2 build/vesica >"$tmp/build.log" 2>&1 || {
    tail -20 "$tmp/build.log" >&2; echo "compare_old.sh: building $OLD failed" >&2; exit 1; }
  OLDBIN=$tmp/old/build/vesica
fi

# the one environment of every run
if [ -n "$CORETYPE" ]; then
  ENVSET="OPENBLAS_CORETYPE=$CORETYPE"
else
  ENVSET="-u OPENBLAS_CORETYPE"
fi
# shellcheck disable=SC2086
runenv() { env $ENVSET OMP_NUM_THREADS="$THREADS" OPENBLAS_NUM_THREADS="$THREADS" "$@"; }

RAW=$tmp/raw.tsv # side cmd repeat wall cpu peak_MB setup_s step_s iters
: >"$RAW"

# The sum (what = sum) or mean (mean) over the accepted steps of the --series
# text FILE's column named NAME, or OLDNAME in an older text (whose column
# names follow a '# ' on its second line; a newer text has one header line of
# names and a row of t = 0, step 0, left out here); NA without rows.
col_stat() { # FILE WHAT NAME OLDNAME
  awk -F'\t' -v what="$2" -v a="$3" -v b="$4" '
    NR == 1 || /^# step/ { sub(/^# /, ""); for (i = 1; i <= NF; i++) if (!c && ($i == a || $i == b)) c = i; next }
    /^#/ { next }
    c && $1 > 0 { s += $c; k++ }
    END { if (!k) print "NA"; else if (what == "mean") printf "%.3f", s / k; else print s }' "$1"
}

# one measured run: side (old|new), binary, command (check|run), repeat
measure() {
  side=$1 bin=$2 cmd=$3 i=$4
  tag=${side}_${cmd}_$i
  if [ "$cmd" = check ]; then
    runenv /usr/bin/time -f '%e %U %S %M' -o "$tmp/$tag.time" \
      "$bin" check "$PROBLEM" --set geometry.epsilon="$EPS" >"$tmp/$tag.out" 2>"$tmp/$tag.err"
  else
    runenv /usr/bin/time -f '%e %U %S %M' -o "$tmp/$tag.time" \
      "$bin" run "$PROBLEM" --set geometry.epsilon="$EPS" --max-steps "$STEPS" --quiet \
      --out "$tmp/$tag.h5" --series "$tmp/$tag.tsv" >"$tmp/$tag.out" 2>"$tmp/$tag.err"
  fi
  st=$?
  if [ $st -ne 0 ]; then
    echo "compare_old.sh: $side $cmd (repeat $i) failed with status $st:" >&2
    tail -5 "$tmp/$tag.err" >&2
    return 1
  fi
  if [ "$cmd" = check ]; then
    setup=$(awk -F' = ' '$1 == "setup_seconds" {print $2}' "$tmp/$tag.out")
    step=NA iters=NA
  else
    runenv "$bin" info "$tmp/$tag.h5" >"$tmp/$tag.info" 2>>"$tmp/$tag.err" || {
      echo "compare_old.sh: $side info of $tmp/$tag.h5 failed" >&2; return 1; }
    setup=$(awk -F' = ' '$1 == "setup_seconds" {print $2}' "$tmp/$tag.info")
    step=$(col_stat "$tmp/$tag.tsv" mean solve_seconds seconds)
    iters=$(col_stat "$tmp/$tag.tsv" sum iterations iter)
  fi
  # /usr/bin/time: wall, user, sys (s), max RSS (kB); the last line (a
  # signal or exit note may come first)
  tail -1 "$tmp/$tag.time" | awk -v side="$side" -v cmd="$cmd" -v i="$i" -v setup="${setup:-NA}" \
    -v step="$step" -v iters="$iters" \
    '{printf "%s\t%s\t%s\t%.2f\t%.2f\t%.1f\t%s\t%s\t%s\n", side, cmd, i, $1, $2 + $3, $4 / 1024, setup, step, iters}' \
    | tee -a "$RAW" >&2
}

echo "# old: $OLD ($OLDBIN); new: $NEWSRC ($(git describe --always --dirty 2>/dev/null), built $(date -u -r "$NEWSRC" '+%Y-%m-%d %H:%M UTC'))" >&2
echo "# side cmd repeat wall_s cpu_s peak_MB setup_s step_s iters" >&2
rc=0
i=1
while [ "$i" -le "$R" ]; do
  if [ $((i % 2)) -eq 1 ]; then order="old new"; else order="new old"; fi
  for cmd in check run; do
    for side in $order; do
      if [ "$side" = old ]; then bin=$OLDBIN; else bin=$NEW; fi
      measure "$side" "$bin" "$cmd" "$i" || rc=1
    done
  done
  i=$((i + 1))
done

# the table: per command and metric the medians over the repeats
echo "# compare_old: $PROBLEM eps $EPS, run --max-steps $STEPS, $R repeat(s), threads $THREADS," \
  "OPENBLAS_CORETYPE ${CORETYPE:-unset}; old $OLD, new $(git describe --always --dirty 2>/dev/null);" \
  "$(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg); medians"
awk -F'\t' '
  function median(key,   n, j, k, t, v) {
    n = cnt[key]
    if (n == 0) return "NA"
    for (j = 1; j <= n; j++) v[j] = val[key, j]
    for (j = 2; j <= n; j++)
      for (k = j; k > 1 && v[k] < v[k - 1]; k--) { t = v[k]; v[k] = v[k - 1]; v[k - 1] = t }
    return n % 2 ? v[(n + 1) / 2] : (v[n / 2] + v[n / 2 + 1]) / 2
  }
  {
    for (c = 4; c <= 9; c++) {
      if ($c == "NA" || $c == "") continue
      key = $2 SUBSEP c SUBSEP $1
      val[key, ++cnt[key]] = $c
    }
  }
  END {
    name[4] = "wall_s"; name[5] = "cpu_s"; name[6] = "peak_MB"; name[7] = "setup_s"
    name[8] = "step_s"; name[9] = "iters"
    printf "%-6s %-8s %10s %10s %9s\n", "cmd", "metric", "old", "new", "old/new"
    split("check run", cmds, " ")
    for (m = 1; m <= 2; m++)
      for (c = 4; c <= 9; c++) {
        o = median(cmds[m] SUBSEP c SUBSEP "old"); w = median(cmds[m] SUBSEP c SUBSEP "new")
        if (o == "NA" && w == "NA") continue
        r = (o != "NA" && w != "NA" && w > 0) ? sprintf("%.2f", o / w) : "NA"
        printf "%-6s %-8s %10s %10s %9s\n", cmds[m], name[c], o, w, r
      }
  }' "$RAW"
exit $rc
