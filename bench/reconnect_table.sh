#!/bin/sh
# The effect of the reconnection frequency: one problem run with
# the reference reset every N = 5, 20, 100 steps, by the distortion
# threshold (max cond F > 2 or min det F < 0.5: reconnect.c's defaults), all
# with the paper's new nodes (y^a; NODES=motion: y(X_a)), every 20 steps with the new nodes at
# y(X_a) (m20), and never; one table of resets, steps, E* on the way and at the end, the
# energy's monotonicity, the cost, and how each run ended.
#
#   bench/reconnect_table.sh                 all five runs, one after another
#   ONLY="n5 thr" bench/reconnect_table.sh   some of them (the table lists
#                                            every run whose files exist)
#   TABLE=1 bench/reconnect_table.sh         only print the table
#
# Environment: VESICA (build/vesica), PROBLEM (problems/stomatocyte_discocyte.ini),
# OUT (results/reconnect), TMARK (t* at which E* is also listed; 5: the end of
# the stomatocyte's relaxation in PROBLEM), SET (extra --set arguments for all),
# NODES (the new nodes of n5, n20, n100 and thr: coefficients, the paper's y^a,
# or motion, y(X_a)).
set -u
V=${VESICA:-build/vesica}
PROBLEM=${PROBLEM:-problems/stomatocyte_discocyte.ini}
OUT=${OUT:-results/reconnect}
TMARK=${TMARK:-5}
SET=${SET:-}
NODES=${NODES:-coefficients}
ALL="none n5 n20 n100 thr m20"
ONLY=${ONLY:-$ALL}
mkdir -p "$OUT"

args_of() {
  case $1 in
    none) echo "--set reconnect.every=0" ;;
    n5) echo "--set reconnect.every=5 --set reconnect.nodes=$NODES" ;;
    n20) echo "--set reconnect.every=20 --set reconnect.nodes=$NODES" ;;
    n100) echo "--set reconnect.every=100 --set reconnect.nodes=$NODES" ;;
    thr) echo "--set reconnect.every=0 --set reconnect.cond_max=2 --set reconnect.det_min=0.5 --set reconnect.nodes=$NODES" ;;
    m20) echo "--set reconnect.every=20 --set reconnect.nodes=motion" ;;
  esac
}

if [ -z "${TABLE:-}" ]; then
  for r in $ONLY; do
    a=$(args_of "$r")
    [ -n "$a" ] || { echo "reconnect_table: unknown run '$r' (one of: $ALL)" >&2; exit 2; }
    echo "== $r: $V run $PROBLEM $a $SET" >&2
    # shellcheck disable=SC2086 # --force: a rerun replaces that run's files
    "$V" run "$PROBLEM" $a $SET --out "$OUT/$r.h5" --series "$OUT/$r.tsv" --quiet --force \
      2> "$OUT/$r.log"
    echo "$?" > "$OUT/$r.exit"
  done
fi

printf '| run | resets | steps | t* reached | E*(t*=%s) | E* at the end | E monotone | retried steps | interface volume drift | Newton iterations | wall s | exit |\n' "$TMARK"
printf '|---|---|---|---|---|---|---|---|---|---|---|---|\n'
for r in $ALL; do
  [ -f "$OUT/$r.tsv" ] || continue
  info=$("$V" info "$OUT/$r.h5" 2>/dev/null)
  get() { printf '%s\n' "$info" | sed -n "s/^$1 = //p" | head -1; }
  em=$(awk -v T="$TMARK" 'NR > 1 && $2 <= T + 1e-9 { e = $4 } END { printf "%.6f", e }' "$OUT/$r.tsv")
  printf '| %s | %s | %s | %s | %s | %.6f | %s | %s | %s | %s | %.0f | %s |\n' "$r" \
    "$(get reconnections)" "$(get steps)" "$(get t_final)" "$em" "$(get energy_final)" \
    "$(get energy_monotone)" "$(get retries)" "$(get interface_volume_drift_max)" \
    "$(get newton_iterations)" "$(get wall_seconds)" \
    "$(cat "$OUT/$r.exit" 2>/dev/null || echo '?')"
done
