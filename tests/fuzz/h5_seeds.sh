#!/bin/sh
# Seeds of the HDF5 reader's fuzzer (tests/fuzz/fuzz_h5.c): the files of two
# small runs of VESICA into DIR, and copies of them cut short (what a full
# disk or an interrupted copy leaves: ves_io_salvage's input).
#   tiny.h5    331 nodes, 2 steps, 2 snapshots (~190 KB)
#   remesh.h5  the same with a reset after step 2 and a remeshing after step
#              3, a snapshot every 2 steps, 4 steps (~500 KB: references,
#              remeshes, y_prev)
# Usage: sh tests/fuzz/h5_seeds.sh VESICA DIR   (~5 s)
set -eu
vesica=$1
dir=$2
here=$(cd "$(dirname "$0")/../.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# test_cli's TINY problem: a sphere with a P2 bump at eps 0.2, coarse
set -- --set geometry.epsilon=0.2 --set geometry.box_r=2 --set geometry.box_z=2 \
  --set geometry.band=2 --set geometry.h_band=0.7 --set geometry.h_far=0.3 --set shape.mode=2 \
  --set shape.delta=0.15 --set time.dt_initial=5e-3 --set time.dE_target=0.05 --quiet
OPENBLAS_NUM_THREADS=1 "$vesica" run "$here/problems/sphere.ini" "$@" --max-steps 2 \
  --out "$work/tiny.h5"
OPENBLAS_NUM_THREADS=1 "$vesica" run "$here/problems/sphere.ini" "$@" --set reconnect.every=2 \
  --set remesh.every=3 --set output.snapshot_every=2 --max-steps 4 --out "$work/remesh.h5"
mkdir -p "$dir"
for f in tiny remesh; do
  cp "$work/$f.h5" "$dir/seed_$f.h5"
  size=$(wc -c <"$work/$f.h5")
  for cut in 100 4000 $((size / 10)) $((size / 2)); do
    head -c $((size - cut)) "$work/$f.h5" >"$dir/seed_${f}_cut$cut.h5"
  done
done
echo "h5_seeds: $(ls "$dir"/seed_*.h5 | wc -l) seed files in $dir"
