#!/bin/sh
# VTI (newton) vs explicit Euler on a short interval: E* at t* = 4e-3 with constant dt.
# Usage: sh bench/vti_euler.sh [VESICA]; prints dt E0 E_vti E_euler (E, the series text's
# fourth column: E0 on its t = 0 row, the second line; E_vti, E_euler on its last).
V=${1:-build/vesica}
S="--set geometry.epsilon=0.12 --set geometry.box_r=1.9 --set geometry.box_z=1.9 --set geometry.band=3 --set shape.mode=2 --set shape.delta=0.15 --set time.t_end=4e-3 --set time.adaptive=0 --set time.dt_min=1e-8"
for dt in 4e-4 2e-4 1e-4 5e-5; do
  for b in newton euler; do
    # --force: a rerun replaces the outputs of the last one (vesica run refuses existing files)
    $V run problems/sphere.ini --quiet --backend $b $S --set time.dt_initial=$dt --set time.dt_max=$dt --out ${TMPDIR:-/tmp}/ve_${b}_$dt.h5 --series ${TMPDIR:-/tmp}/ve_${b}_$dt.tsv --force || echo "fail $b $dt"
  done
  en=$(tail -1 ${TMPDIR:-/tmp}/ve_newton_$dt.tsv | cut -f4); ee=$(tail -1 ${TMPDIR:-/tmp}/ve_euler_$dt.tsv | cut -f4); e0=$(sed -n 2p ${TMPDIR:-/tmp}/ve_newton_$dt.tsv | cut -f4)
  echo "$dt $e0 $en $ee"
done
