#!/bin/bash
# Seven ways to lose or damage a run's output, rerun against a build: a full
# disk, overwrites, malformed inputs, torn files, other readers
# (docs/results.md, "Reliability and fuzzing"). Root (tmpfs mounts), from the
# repository root: bash bench/defects.sh [VESICA]; ~2 min.
V=$(readlink -f "${1:-build/vesica}")
P=$(readlink -f problems); X=$(readlink -f tests/xdmf_check.py)
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
D=$(mktemp -d); cd "$D"; trap 'umount full pf 2>/dev/null; rm -rf "$D"' EXIT
S="--set geometry.epsilon=0.12 --set geometry.band=3 --set time.t_end=0.02"
say() { echo "== $*"; }
ex() { "$@"; echo "-> exit $?"; }
say "1. full disk: 200 KB tmpfs"
mkdir -p full && mount -t tmpfs -o size=200k tmpfs full
ex $V run $P/oblate.ini $S --out full/r.h5 --quiet
ls -l full; cp full/r.h5 r_moved.h5; umount full
ex $V run --restart r_moved.h5 --quiet
$V info r_moved.h5 | grep -E '^status|^steps|^snapshots'
say "1b. a torn file (cut inside its last snapshot)"
cp r_moved.h5 torn.h5; truncate -s $(( $(stat -c %s torn.h5) - 3000 )) torn.h5
ex $V run --restart torn.h5
say "2. outputs overwritten"
cp $P/sphere.ini small.ini
ex $V run small.ini --out small.ini --set time.t_end=0.001 --quiet
head -c 40 small.ini | head -2
ex $V run small.ini --set geometry.epsilon=0.12 --set geometry.band=3 --max-steps 1 --quiet
ex $V run small.ini --set geometry.epsilon=0.12 --set geometry.band=3 --max-steps 1 --quiet
say "3. plot and spectrum --vectors on a full disk (60 KB tmpfs)"
mkdir -p pf && mount -t tmpfs -o size=60k tmpfs pf
ex $V plot small.h5 --outdir pf
ls -l pf
ex $V spectrum small.h5 --modes 2 --lanczos 10 --vectors pf/v.tsv
ls -l pf; umount pf
say "4. problem files"
ex $V run $P --quiet
printf '[geometry]\nepsilon = 0.1\nepsilon = 0.2\n' > dup.ini; ex $V check dup.ini
printf '[time]\nt_end = 1\n[time]\n' > dups.ini; ex $V check dups.ini
printf '\xef\xbb\xbf[geometry]\nepsilon = 0.12\nband = 3\n# %s\n' "$(head -c 3000 /dev/zero | tr '\0' x)" > bom.ini; ex $V check bom.ini | grep -E '^nodes|exit'
printf '[geometry\nepsilon = 0.1\n' > bad.ini; ex $V check bad.ini
say "5. curves"
printf '0 1\n1 0\n1 1\n0.3 -0.5\n0 -1\n' > cross.txt
printf '[shape]\ntype = curve\npoints = cross.txt\n[geometry]\nband_layers = 0\n' > cross.ini; ex $V check cross.ini
printf '[shape]\ntype = curve\npoints = cross.txt\n' > cross1.ini; ex $V check cross1.ini
printf '0 -1\n0.7 -0.7\n1 0\n0.7 0.7\n0 1\n' > north.txt
printf '[shape]\ntype = curve\npoints = north.txt\n' > north.ini; ex $V check north.ini
say "6. small items"
cp small.h5 cut.h5; truncate -s 20000 cut.h5; ex $V info cut.h5; ex $V run --restart cut.h5
ex $V plot small.h5 --outdir a/b/c; ls a/b/c
$V --help 2>&1 | grep -E '130|143'; ex $V help info >/dev/null; $V info --help 2>&1 | grep -c references
$V run $P/oblate.ini --set geometry.epsilon=0.12 --set geometry.band=3 --max-steps 12 --out eta.h5 2>&1 | grep -E 'ETA' | tail -2
ex $V check $P/oblate.ini --set geometry.epsilon=1e-4
say "7. other tools"
/usr/bin/python3 -c "
import h5py; f=h5py.File('small.h5','r'); bare=[]
f.visititems(lambda n,o: bare.append(n) if 'units' not in o.attrs else None); print('objects without units:', bare)
print('series/status:', f['series/status'].attrs['description'].decode()[:90], '...')"
mkdir -p 'd:ir'; ex $V run small.ini --set geometry.epsilon=0.12 --set geometry.band=3 --max-steps 2 --out 'd:ir/run.h5' --quiet
/usr/bin/python3 "$X" 'd:ir/run.xdmf'
ex $V run small.ini --out 'run:1.h5' --quiet
