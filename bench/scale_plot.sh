#!/bin/sh
# The cost of a Newton step against the node count, log-log: reads a table
# that bench/scale.sh printed (bench_scale rows; '#' lines are comments),
# fits step_s = c nodes^p by least squares in log-log per thread count,
# prints the exponents and writes a PNG with the points and the fits.
#
#   sh bench/scale.sh > scale.tsv && sh bench/scale_plot.sh scale.tsv bench/figures/scale_step.png
#
# Columns used (bench_scale's header): threads (2), nodes (4), stepH_s (15),
# factor_s (17), step_s (18). Needs gnuplot (make deps installs gnuplot-nox).
set -eu
[ $# -eq 2 ] || { echo "usage: scale_plot.sh TABLE.tsv OUT.png" >&2; exit 2; }
T=$1 OUT=$2
[ -r "$T" ] || { echo "scale_plot.sh: $T: cannot read" >&2; exit 2; }
command -v gnuplot >/dev/null || { echo "scale_plot.sh: gnuplot not found" >&2; exit 3; }
# least squares of log(step) on log(nodes), one line per thread count
fits=$(awk -F'\t' '!/^#/ && NF >= 18 && $18 > 0 {
    k = $2; x = log($4); y = log($18); n[k]++; sx[k] += x; sy[k] += y; sxx[k] += x*x; sxy[k] += x*y
  }
  END {
    for (k in n) {
      if (n[k] < 2) continue
      p = (n[k]*sxy[k] - sx[k]*sy[k]) / (n[k]*sxx[k] - sx[k]*sx[k])
      c = exp((sy[k] - p*sx[k]) / n[k])
      printf "%s %.4f %.6g %d\n", k, p, c, n[k]
    }
  }' "$T" | sort -n)
[ -n "$fits" ] || { echo "scale_plot.sh: $T: fewer than two rows per thread count" >&2; exit 2; }
echo "# threads  exponent p  (step_s = c nodes^p)  rows"
echo "$fits" | awk '{printf "  %s         %.3f       c = %.3g                    %d\n", $1, $2, $3, $4}'
plot="" fn=""
for thr in $(echo "$fits" | awk '{print $1}'); do
  p=$(echo "$fits" | awk -v t="$thr" '$1 == t {print $2}')
  c=$(echo "$fits" | awk -v t="$thr" '$1 == t {print $3}')
  plot="$plot${plot:+, }'$T' using (\$2 == $thr ? \$4 : 1/0):18 with points pt 7 ps 1.3 title '$thr thread(s)'"
  plot="$plot, $c * x**$p with lines dt 2 title sprintf('fit: nodes^{%.2f}', $p)"
done
gnuplot <<EOF
set terminal pngcairo size 800,600 font ',11'
set output '$OUT'
set logscale xy
set xlabel 'nodes'
set ylabel 'one Newton step (s, wall)'
set title 'problems/oblate.ini: cost of a step against the node count'
set key top left
set grid
plot $plot
EOF
echo "# wrote $OUT"
