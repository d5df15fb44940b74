# Error of the final E* against the sharp equilibrium versus CPU seconds, one
# point per discretization setting (bench/pareto.sh output); docs/results.md, "Convergence in ε and h".
# usage: gnuplot bench/pareto_plot.gp   (from the repository root)
set terminal pngcairo size 900,600 font "DejaVu Sans,11" noenhanced
set output "bench/figures/pareto_eps001.png"
set datafile separator "\t"
set logscale xy
set xrange [50:2000]
set yrange [3e-6:1e-2]
set xlabel "CPU time of the run, user + sys (s)"
set ylabel "|E*(t* = 4) - E*_sharp|  (units of k; signed value in the labels)"
set title "Oblate v = 0.9 to t* = 4: cost against accuracy (h_band in eps; standard = the default)"
set key outside right top box
set format y "%.0e"
set grid xtics ytics mxtics mytics
set arrow from 50,1e-4 to 2000,1e-4 nohead dt 2 lw 1.5 lc rgb "gray40"
set label "1e-4 absolute" at 55,1.2e-4 tc rgb "gray30"
# 1e-4 relative to E*_sharp = 7.652042
set arrow from 50,7.652e-4 to 2000,7.652e-4 nohead dt 3 lw 1.5 lc rgb "gray40"
set label "1e-4 relative" at 55,6.3e-4 tc rgb "gray30"
# the oblate's rows only (column 1: the problem): the sharp value above is its own
ok(y) = (strcol(1) eq "oblate" && abs(y) < 1e-2) ? abs(y) : NaN
# h_band=0.6 and the default at eps 0.02 are labelled on the left of their points, the others
# on the right
onleft(s) = (s eq "h_band=0.6" || s eq "default")
# the settings geometry.resolution names are labelled by their names
name(s) = (s eq "default") ? "standard (0.5)" : (s eq "h_band=0.6") ? "coarse (0.6)" : \
  (s eq "h_band=0.4") ? "fine (0.4)" : s
lab(s, y) = name(s) . sprintf(", %+.1e", y)
# label positions: a factor on x and y per setting, so that close points keep apart
fy(s) = (s eq "gamma=0.8") ? 1.0 : (s eq "h_band=0.6") ? 1.0 : (s eq "default") ? 0.97 : \
  (s eq "h_band=0.4") ? 0.8 : 1.15
plot "bench/figures/pareto_eps001.tsv" skip 1 using 5:(ok($8)) \
       with points pt 7 ps 1.8 lc rgb "#c00000" title "eps 0.01", \
     "" skip 1 using ($5*1.06):(ok($8)*fy(strcol(3))):(lab(strcol(3), $8)) with labels left \
       tc rgb "#c00000" notitle, \
     "bench/figures/pareto_eps002.tsv" skip 1 using 5:(ok($8)) \
       with points pt 5 ps 1.5 lc rgb "#0050c0" title "eps 0.02 (pre-scan)", \
     "" skip 1 using ($5*1.06):(onleft(strcol(3)) ? NaN : ok($8)*fy(strcol(3))):(lab(strcol(3), $8)) \
       with labels left tc rgb "#0050c0" notitle, \
     "" skip 1 using ($5/1.06):(onleft(strcol(3)) ? ok($8) : NaN):(lab(strcol(3), $8)) \
       with labels right tc rgb "#0050c0" notitle
