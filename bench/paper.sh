#!/bin/sh
# vesica — `make paper`: the paper's results at one scale, resumable.
#
#   PAPER_EPS   eps/R0 of every run (empty: each result's default scale below;
#               0.01 is the paper's)
#   PAPER_ONLY  run only the results whose name contains it (fig34, table1,
#               fig5left, fig5right, fig6, fig7; fig34 includes fig34_eps001)
#   PAPER_OUT   where the runs go (default results/paper, at a PAPER_EPS
#               results/paper_epsE; not in git)
#   PAPER_JOBS  runs at a time (default 2: two lanes of one thread each, on
#               the two cores; 1: one after the other). Lane 1: fig6, fig34,
#               fig34_eps001, fig5left, table1, fig7_fast; lane 2: fig5right,
#               fig7_medium, fig7_slow (balanced by their measured times at the
#               default scale; Fig. 7's three rates in both lanes, so that
#               PAPER_ONLY=fig7 uses both cores); each lane's output in
#               OUT/laneN.log, then one sequential pass (every run done)
#               draws the figures and writes the table (below)
#   VESICA, TABLE1  the programs (make paper passes build/vesica and
#               build/bench/bench_table1)
#
# Every run writes OUT/NAME.h5; NAME.done marks a finished one, which the
# next call skips; a run interrupted (killed, a full disk, the machine
# lost) is continued with `vesica run --restart` from its last snapshot.
# Each scale has its own files, so a PAPER_EPS call leaves the default
# scale's record alone: with PAPER_EPS empty the figures go to
# bench/figures/paper/ and the table to bench/PAPER.md, with PAPER_EPS=E to
# bench/figures/paper_epsE/ and bench/PAPER_epsE.md.
# Figures: `vesica plot` (E* and dt* against t*,
# the nodes coloured by phi with the phi = 0 curve, the constraints and the
# volume protocol, the flow on one arrow scale);
# the table of each result next to the paper's statement:
# the table rewritten from whatever has finished at every call.
# Fig. 6 (pearling, problems/pearling.ini) and Fig. 7 also get their own
# figure and tables in the paper's layout (bench/fig6.py, bench/fig7.py).
set -u
VESICA=${VESICA:-build/vesica}
TABLE1=${TABLE1:-build/bench/bench_table1}
PAPER_EPS=${PAPER_EPS:-}
PAPER_ONLY=${PAPER_ONLY:-}
scale=""
[ -n "$PAPER_EPS" ] && scale="_eps$PAPER_EPS"
OUT=${PAPER_OUT:-results/paper$scale}
FIG=bench/figures/paper$scale
MD=bench/PAPER$scale.md
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}" OPENBLAS_NUM_THREADS=1
PAPER_JOBS=${PAPER_JOBS:-2}
LANE=${PAPER_LANE:-}
mkdir -p "$OUT" "$FIG" || exit 3
failed=0
start=$(date +%s)

# The lanes: two children of this script, each running its own results
# (want() below), then this process goes on as a sequential call in which
# every finished run is skipped.
if [ -z "$LANE" ] && [ "$PAPER_JOBS" -gt 1 ]; then
  echo "paper: 2 lanes (PAPER_JOBS=$PAPER_JOBS), logs $OUT/lane1.log $OUT/lane2.log"
  PAPER_LANE=1 sh "$0" > "$OUT/lane1.log" 2>&1 &
  p1=$!
  PAPER_LANE=2 sh "$0" > "$OUT/lane2.log" 2>&1 &
  p2=$!
  wait $p1 || failed=1
  echo "paper: lane 1 finished ($(( $(date +%s) - start )) s)"
  wait $p2 || failed=1
  echo "paper: lane 2 finished ($(( $(date +%s) - start )) s)"
  cat "$OUT/lane1.log" "$OUT/lane2.log"
  AFTER_LANES=1 # the final pass runs nothing: what a lane did not finish stays so
fi

lane_of() { case "$1" in fig6|fig34|fig34_eps001|fig5left|table1|fig7_fast) echo 1;; *) echo 2;; esac; }
want() {
  case "$1" in *"$PAPER_ONLY"*) ;; *) return 1;; esac
  [ -z "$LANE" ] || [ "$(lane_of "$1")" = "$LANE" ]
}
post() { [ -z "$LANE" ] && want "$1"; } # figures and tables: the final pass only

# run NAME PROBLEM DEFAULT_EPS [--set k=v]...: one vesica run, resumable
run() {
  name=$1 problem=$2 eps=${PAPER_EPS:-$3}
  shift 3
  want "$name" || return 0
  h5=$OUT/$name.h5
  if [ -n "${AFTER_LANES:-}" ]; then
    [ -f "$OUT/$name.done" ] || echo "paper: $name: not finished (its lane's log above)"
    return 0
  fi
  have=$(sed -n 's/^geometry.epsilon = //p' "$OUT/$name.info" 2>/dev/null)
  if [ -f "$OUT/$name.done" ] && [ -n "$have" ] &&
    awk -v a="$have" -v b="$eps" 'BEGIN { exit !(a + 0 != b + 0) }'; then
    echo "paper: $name: $OUT holds it at eps $have, not $eps (set PAPER_OUT to another folder)"
    failed=1
  elif [ -f "$OUT/$name.done" ]; then
    echo "paper: $name: done (remove $OUT/$name.done to rerun)"
  elif [ -f "$h5" ]; then
    echo "paper: $name: continuing $h5"
    # --series is not allowed with --restart: the text keeps the rows of the first part, and
    # the run's file all of them (vesica info FILE.h5 --series 0)
    "$VESICA" run --restart "$h5" --quiet || { echo "paper: $name: failed (exit $?)"; failed=1; return; }
  else
    echo "paper: $name: $problem at eps $eps"
    "$VESICA" run "$problem" --set geometry.epsilon="$eps" "$@" --out "$h5" --quiet --force \
      --series "$OUT/$name.tsv" ||
      { echo "paper: $name: failed (exit $?)"; failed=1; return; }
  fi
  [ -f "$OUT/$name.done" ] && return
  "$VESICA" info "$h5" > "$OUT/$name.info" && touch "$OUT/$name.done"
  "$VESICA" plot "$h5" --outdir "$FIG" --force > /dev/null || echo "paper: $name: plot failed"
}

# The default scale of each result: the largest eps at which it is still
# qualitatively right (docs/results.md, "The paper's figures and tables"):
# the relaxation at 0.08 (oblate.ini with band 4), the Fig. 5 runs at 0.04
# (their files), Fig. 7 at 0.08.
# Fig. 7 at any eps: an energy target of 1 per step instead of the files' 0.25
# (4x fewer steps while E* rises by 8-54) and a snapshot every step (the
# shape at the energy's maximum); at eps >= 0.08 band 4 (the files' 5.5 does
# not fit the oblate's curvature there).
band4=""
[ -z "$PAPER_EPS" ] && band4="--set geometry.band=4"
fig7set="--set time.dE_target=1 --set output.snapshot_every=1"
e7=${PAPER_EPS:-0.08}
awk -v e="$e7" 'BEGIN { exit !(e >= 0.08) }' && fig7set="$fig7set --set geometry.band=4"
run fig34 problems/oblate.ini 0.08
# and once at the paper's eps 0.01 (19,391 nodes, the file's band; ~8 min
# on one thread): the relaxation at its scale, beside the default one. Not
# with a PAPER_EPS, where fig34 itself runs at that eps.
[ -z "$PAPER_EPS" ] && run fig34_eps001 problems/oblate.ini 0.01
# At the default eps the runs with resets or remeshings (fig5left, fig5right,
# fig6) take the step after each at the controller's full dt
# (time.event_cut = 1), as the recorded runs of bench/PAPER.md did; at
# another PAPER_EPS the default cut holds (docs/results.md, "Why the steps
# after a reset or a remeshing are hard").
recorded=""
[ -z "$PAPER_EPS" ] && recorded="--set time.event_cut=1"
run fig5left problems/stomatocyte_discocyte.ini 0.04 $recorded
# Fig. 5 right to its end state: in a box 4.5 high (in the file's box 3 high
# the upper tether's bud reaches the wall at t* ~2.8, where the steps fail)
# with a remeshing every 40 steps (the tethers stay resolved), to t* 8 (at
# eps 0.04 the buds are absorbed into the tethers by t* ~3.7), and
# factor_shrink 4 (the bud phase's rejected attempts); docs/results.md, "The
# paper's figures and tables". At the default eps the file's controller keys
# for the paper's scale (growth_max, iter_target, max_builds, max_correction:
# docs/results.md, "Long runs at ε = 0.01") are set back to the defaults the
# recorded run (bench/PAPER.md) used, which they would otherwise change; at
# another PAPER_EPS the file's keys hold.
f5r_controller=""
[ -z "$PAPER_EPS" ] && f5r_controller="--set time.growth_max=2 --set time.iter_target=8
  --set solver.max_builds=0 --set solver.max_correction=0"
run fig5right problems/prolate_c0.ini 0.04 --set geometry.box_z=4.5 --set remesh.every=40 \
  --set time.t_end=8 --set time.factor_shrink=4 $f5r_controller $recorded
# shape_md NAME: bench/fig6.py's tables of finished run NAME into OUT/NAME.md
# (its figure into FIG), in the final pass
shape_md() {
  if post "$1" && [ -f "$OUT/$1.done" ]; then
    if /usr/bin/python3 bench/fig6.py "$OUT/$1.h5" "$FIG" > "$OUT/$1.md.part"; then
      mv "$OUT/$1.md.part" "$OUT/$1.md"
    else
      echo "paper: $1: bench/fig6.py failed"; failed=1
    fi
  fi
}
# its shape along the run (bench/fig6.py: the body's and beads' radii, the
# tethers' length, the fastest node of the flow; figure fig5right_pearls.png)
shape_md fig5right
fig5md=""
[ -f "$OUT/fig5right.md" ] && fig5md=$OUT/fig5right.md
# Fig. 6 at eps 0.04 (the file's; 0.08 cannot hold the pearls: C0 eps would be
# 0.96), then bench/fig6.py: the nodes coloured by phi at six times, E*, C0 R0
# and v against t*, the pearls' and necks' radii, the remeshings
run fig6 problems/pearling.ini 0.04 $recorded
shape_md fig6
fig6md=""
[ -f "$OUT/fig6.md" ] && fig6md=$OUT/fig6.md
for r in fast medium slow; do
  # shellcheck disable=SC2086
  run fig7_$r problems/deflate_$r.ini 0.08 $fig7set
done
# Fig. 7 in the paper's layout and its tables (bench/fig7.py: V/V0 and E*
# against t*, the phi = 0 shapes at the energy's maximum and at the end, the
# sharp equilibrium, vesica check of each shape)
fig7md=""
if post fig7 && ls "$OUT"/fig7_*.done > /dev/null 2>&1; then
  if /usr/bin/python3 bench/fig7.py "$OUT" "$FIG" "$VESICA" > "$OUT/fig7.md.part"; then
    mv "$OUT/fig7.md.part" "$OUT/fig7.md"
  else
    echo "paper: fig7: bench/fig7.py failed"; failed=1
  fi
fi
[ -f "$OUT/fig7.md" ] && fig7md=$OUT/fig7.md
if want table1; then
  t=$OUT/table1.txt
  if [ -f "$t.done" ]; then
    echo "paper: table1: done"
  elif [ -n "${AFTER_LANES:-}" ]; then
    echo "paper: table1: not finished (its lane's log above)"
  else
    e=${PAPER_EPS:-0.08}
    echo "paper: table1: bench_table1 at eps $e"
    t0=$(date +%s)
    # shellcheck disable=SC2086
    if "$TABLE1" problems/oblate.ini --set geometry.epsilon="$e" $band4 > "$t.part"; then
      echo $(( $(date +%s) - t0 )) > "$t.wall"
      mv "$t.part" "$t" && touch "$t.done"
    else
      echo "paper: table1: failed"; failed=1
    fi
  fi
fi

# ---- the table (MD) from what has finished --------------------------------
[ -n "$LANE" ] && exit $failed
wall=$(( $(date +%s) - start ))
key() { sed -n "s/^$1 = //p" "$OUT/$2.info" 2>/dev/null | head -1; }
ours() { # ours NAME TEXT: TEXT where run NAME has finished, else "not run"
  if [ -f "$OUT/$1.done" ]; then echo "$2"; else echo "not run"; fi
}
row() { # name: the run's figures, or "not run"
  if [ -f "$OUT/$1.done" ]; then
    dtr=$(awk -v a="$(key dt_first "$1")" -v b="$(key dt_largest "$1")" \
      'BEGIN { if (a > 0) printf "%.0f", b / a }')
    echo "| $1 | $(key geometry.epsilon "$1") | $(key nodes "$1") -> $(key nodes_final "$1") | $(key steps "$1") | $(key t_final "$1") | $(key energy_initial "$1") | $(key energy_final "$1") | ${dtr}x | $(key reconnections "$1") | $(key remeshings "$1") | $(key area_drift_max "$1") | $(key volume_drift_max "$1") | $(key wall_seconds "$1") |"
  else
    echo "| $1 | not run | | | | | | | | | | | |"
  fi
}
# the runs, in the table's order (fig34_eps001 only at the default scale)
RUNS="fig34 fig5left fig5right fig6 fig7_slow fig7_medium fig7_fast"
[ -z "$PAPER_EPS" ] && RUNS="fig34 fig34_eps001 ${RUNS#fig34 }"
lane_wall() { # the sum of the wall seconds of lane $1's finished runs
  tot=0
  for n in $RUNS; do
    [ "$(lane_of "$n")" = "$1" ] && [ -f "$OUT/$n.done" ] && tot=$(awk -v a="$tot" -v b="$(key wall_seconds "$n")" 'BEGIN { print a + b }')
  done
  [ "$1" = 1 ] && [ -f "$OUT/table1.txt.wall" ] && tot=$(awk -v a="$tot" -v b="$(cat "$OUT/table1.txt.wall")" 'BEGIN { print a + b }')
  printf '%.0f' "$tot"
}
{
  echo "# The paper's results by \`make paper\`"
  echo
  echo "Written by bench/paper.sh (\`make paper\`) from its runs (PAPER_OUT; PAPER_EPS=${PAPER_EPS:-per result})."
  echo "Figures: $FIG/NAME_{energy,snapshots,constraints,flow}.png. The"
  echo "columns are \`vesica info\` keys (dt growth: dt_largest / dt_first; wall s over"
  echo "restarts). What each result shows against the paper, why ours differs where it"
  echo "does, and the runs at the paper's eps 0.01 made by hand (Fig. 5 right, Fig. 6):"
  echo "docs/results.md, \"The paper's figures and tables\" and \"Long runs at ε = 0.01\"."
  echo "The Fig. 3-4 figure is ours in the README's layout, not the paper's panels at its"
  echo "times."
  echo
  echo "Run time: lane 1 (fig34, fig34_eps001, fig6, fig5left, table1, fig7_fast) $(lane_wall 1) s,"
  echo "lane 2 (fig5right, fig7_medium, fig7_slow) $(lane_wall 2) s: the sums of the runs' own wall seconds"
  echo "(\`vesica info\` wall_seconds, over restarts; table1 timed by bench/paper.sh). With"
  echo "PAPER_JOBS=2 (the default) the lanes run side by side, one thread each; this call"
  echo "took $wall s ($(date -u '+%Y-%m-%d %H:%M UTC'), $(getconf _NPROCESSORS_ONLN) cores; a call that finds"
  echo "every run done takes only the figures' time)."
  echo
  echo "| run | eps | nodes (initial -> final) | steps | t* | E* initial | E* final | dt growth | resets | remeshings | max \|A/A0-1\| | max \|V/Vt-1\| | wall s |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"
  for n in $RUNS; do row $n; done
  echo
  echo "Fig. 5 right (bench/fig6.py; figures $FIG/fig5right_pearls.png, the"
  echo "flow: fig5right_flow.png):"
  echo
  if [ -n "$fig5md" ]; then grep -v '^figure: ' "$fig5md"; else echo "not run"; fi
  echo
  if [ -f "$OUT/fig6.done" ]; then
    echo "Fig. 6 (bench/fig6.py; figure $FIG/fig6_eps$(key geometry.epsilon fig6).png):"
  else
    echo "Fig. 6 (bench/fig6.py):"
  fi
  echo
  if [ -n "$fig6md" ]; then grep -v '^figure: ' "$fig6md"; else echo "not run"; fi
  echo
  if [ -f "$OUT/fig6.done" ]; then # the comparison from the run's keys
    echo "| Fig. 6 | the paper states | ours |"
    echo "|---|---|---|"
    echo "| protocol | prolate v 0.9 deflated to v 0.55 at constant area, C0 R0 raised to 12 (no rates, no times given) | problems/pearling.ini: V/V0 1 -> $(key protocol.volume_final fig6) at $(key protocol.volume_rate fig6) V0 per t* and C0 R0 $(key material.c0 fig6) -> $(key protocol.c0_ramp_to fig6) linearly over t* [$(key protocol.c0_ramp_start fig6), $(key protocol.c0_ramp_end fig6)], then held |"
    echo "| resolution | eps/R0 0.01, 12,650 nodes | eps $(key geometry.epsilon fig6), $(key nodes fig6) -> $(key nodes_final fig6) nodes |"
    echo "| resets | frequent | $(key reconnections fig6) (every $(key reconnect.every fig6) steps) |"
    echo "| remeshings | four, at later stages | $(key remeshings fig6) |"
    echo "| outcome | elongation and pearling | the table above: pearls and necks against t* |"
  fi
  echo
  echo "Fig. 7 (bench/fig7.py; figure $FIG/fig7_eps$(key geometry.epsilon fig7_fast).png):"
  echo
  if [ -n "$fig7md" ]; then grep -v '^figure: ' "$fig7md"; else echo "not run"; fi
  echo
  echo "| result | the paper states | ours (where measured) |"
  echo "|---|---|---|"
  echo "| Fig. 3-4 (oblate relaxation) | E* decreases monotonically to the equilibrium; dt grows ~2048x over the run; 6,124 nodes at eps 0.01 | $(ours fig34 "$( [ -z "$PAPER_EPS" ] && echo "runs fig34 and fig34_eps001" || echo "run fig34") above"); against the sharp equilibrium: docs/results.md, \"Convergence in ε and h\" |"
  echo "| Table 1 (VTI vs forward Euler) | VTI stable at dt* 1e-2..1e-4 with E*(t2) 9.243/9.240/9.239; FE needs dt* 1e-5 | $( [ -f "$OUT/table1.txt.done" ] && echo "bench_table1's table, table1.txt beside the runs" || echo "not run"); at eps 0.04 and 0.01: docs/results.md, \"Robustness at large Δt\" |"
  echo "| Fig. 5 left (stomatocyte -> discocyte) | a C0 pulse pushes the stomatocyte past the barrier into a discocyte | $(ours fig5left "run fig5left above (eps $(key geometry.epsilon fig5left), to t* $(key t_final fig5left))"); docs/results.md, \"The paper's figures and tables\" |"
  echo "| Fig. 5 right (prolate, C0 R0 = 10) | two dissimilar spheres joined by a narrow neck | $(ours fig5right "run fig5right above (eps $(key geometry.epsilon fig5right), box_z $(key geometry.box_z fig5right), a remeshing every $(key remesh.every fig5right) steps) and its shape table: a sphere with a tether up and down, E* $(key energy_final fig5right) at t* $(key t_final fig5right)"); the sharp model's limit shapes (bench/fig5_limit.py) and the end state at eps 0.01: docs/results.md, \"The paper's figures and tables\" |"
  echo "| Fig. 6 (pearling: v 0.9 -> 0.55, C0 R0 -> 12, four remeshings, 12,650 nodes) | elongation and pearling | $(ours fig6 "the Fig. 6 tables above"); at eps 0.01: docs/results.md, \"Long runs at ε = 0.01\" |"
  echo "| Fig. 7 (deflation at three rates) | E* peaks at the end of deflation; the faster the rate, the further from equilibrium at that instant (shape and E*); all reach the same equilibrium shape D by t* ~ 1 | the Fig. 7 tables above (E* max per rate, the shapes at the maxima and at the end against D); at eps 0.04, and what sets the relaxation after the peak: docs/results.md, \"The paper's figures and tables\" |"
} > "$MD.part" && mv "$MD.part" "$MD"
echo "paper: wrote $MD"
exit $failed
