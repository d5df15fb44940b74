#!/bin/sh
# Sphere convergence: relative errors of E* (vs 2 pi, exact for every
# eps), A and V (vs the phase-field values 4 pi (1 + (pi^2/6 - 1) eps^2) and
# (4 pi / 3)(1 + (pi^2/2) eps^2)) for eps in {0.04, 0.02, 0.01} and
# h_band/eps in {0.75, 0.5, 0.4}; the last rows use sampled phi0 coefficients
# instead of the least-squares fit. Usage: sh bench/sphere_convergence.sh [VESICA]
V=${1:-build/vesica}
printf '%-6s %-6s %-8s %7s %8s %12s %11s %11s %11s %8s\n' eps h/eps phi0 nodes m E* "E/2pi-1" "A/A_pf-1" "V/V_pf-1" setup_s
run() { # eps hband phi0 [extra --set ...]
  eps=$1; hb=$2; ph=$3; shift 3
  out=$($V check problems/sphere.ini --set geometry.epsilon=$eps --set geometry.h_band=$hb --phi0 $ph "$@") || { echo "failed: eps=$eps h=$hb"; return; }
  echo "$out" | awk -v eps=$eps -v hb=$hb -v ph=$ph -F' = ' '
    {v[$1]=$2}
    END{pi=3.141592653589793; Apf=4*pi*(1+(pi*pi/6-1)*eps*eps); Vpf=4*pi/3*(1+pi*pi/2*eps*eps);
        printf "%-6s %-6s %-8s %7d %8.1f %12.7f %11.2e %11.2e %11.2e %8.1f\n", eps, hb, ph, v["nodes"], v["neighbours_mean"],
          v["energy"], v["energy"]/(2*pi)-1, v["area"]/Apf-1, v["volume"]/Vpf-1, v["setup_seconds"]}'
}
for eps in 0.04 0.02 0.01; do
  for hb in 0.75 0.5 0.4; do run $eps $hb l2; done
done
run 0.04 0.5 sampled
run 0.02 0.5 sampled
