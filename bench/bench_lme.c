/* vesica — benchmark of ves_lme_eval: evaluations/s by nder, cold/warm. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "ves/lme.h"

#define NPTS 400 /* evaluation points along a path */
#define MMAX 256 /* largest neighbourhood stored */

/* One evaluation point and its neighbours (gathered once, outside timing). */
typedef struct {
  double X[2];
  int m;
  double xa[2 * MMAX];
  double beta[MMAX];
} point;

/* Deterministic uniform numbers in [0, 1) (xorshift64*). */
static double urand(uint64_t *s) {
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return (double)((*s * 2685821657736338717ULL) >> 11) * 0x1.0p-53;
}

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* Hex lattice of spacing h = 1 on [-L, L]^2 (columns at R = k sqrt3/2),
 * each node moved by up to `jitter` h in both directions. */
static int lattice(double *x, int cap, double L, double jitter, uint64_t *s) {
  int n = 0, K = (int)(L / (sqrt(3.0) / 2)) + 1;
  for (int k = -K; k <= K; k++)
    for (int j = -(int)L - 1; j <= (int)L + 1; j++) {
      double R = k * sqrt(3.0) / 2, Z = j + ((abs(k) % 2) ? 0.5 : 0.0);
      if (fabs(R) > L || fabs(Z) > L || n >= cap) continue;
      x[2 * n] = R + jitter * (2 * urand(s) - 1);
      x[2 * n + 1] = Z + jitter * (2 * urand(s) - 1);
      n++;
    }
  return n;
}

/* Points along a meandering path (steps of 0.05 h, as consecutive quadrature
 * points would be), with their neighbours by brute force. */
static double setup(point *pts, const double *x, int n, const ves_lme_params *par, uint64_t *s) {
  double rad = ves_lme_radius(par, 1.0), beta = par->gamma, X[2] = {0, 0};
  double ang = 0, msum = 0;
  for (int i = 0; i < NPTS; i++) {
    ang += 0.3 * (2 * urand(s) - 1); /* gently turning direction */
    X[0] += 0.05 * cos(ang);
    X[1] += 0.05 * sin(ang);
    if (fabs(X[0]) > 3 || fabs(X[1]) > 3) ang += 3.14159; /* stay inside */
    point *p = &pts[i];
    p->X[0] = X[0];
    p->X[1] = X[1];
    p->m = 0;
    for (int a = 0; a < n && p->m < MMAX; a++) {
      double dR = X[0] - x[2 * a], dZ = X[1] - x[2 * a + 1];
      if (dR * dR + dZ * dZ > rad * rad) continue;
      p->xa[2 * p->m] = x[2 * a];
      p->xa[2 * p->m + 1] = x[2 * a + 1];
      p->beta[p->m] = beta; /* h_a = 1 */
      p->m++;
    }
    msum += p->m;
  }
  return msum / NPTS;
}

/* Time ~1 s of sweeps over the path; returns evaluations per second. */
static double run(const point *pts, const ves_lme_params *par, int nder, int warm, double *tab,
                  double *work, double *mean_it, int *fails) {
  long evals = 0, its = 0;
  double t0 = now(), t = t0, sink = 0;
  *fails = 0;
  while (t - t0 < 1.0) {
    double lam[2] = {0, 0};
    for (int i = 0; i < NPTS; i++) {
      if (!warm) lam[0] = lam[1] = 0; /* cold: lambda from 0 */
      ves_lme_info info;
      ves_status st = ves_lme_eval(par, pts[i].X, pts[i].m, pts[i].xa, pts[i].beta, lam, nder, tab,
                                   work, &info);
      if (st != VES_OK) (*fails)++;
      its += info.iterations;
      sink += tab[0];
    }
    evals += NPTS;
    t = now();
  }
  *mean_it = (double)its / evals;
  if (sink == 12345.678) printf(" "); /* keep the results alive */
  return evals / (t - t0);
}

int main(void) {
  ves_lme_params par;
  ves_lme_params_default(&par);
  par.gamma = 0.8; /* the paper's (tol0 1e-6) */
  int cap = 8000;
  double *x = malloc(2 * (size_t)cap * sizeof(double));
  point *pts = malloc(NPTS * sizeof(point));
  double *tab = malloc(6 * MMAX * sizeof(double));
  double *work = malloc((size_t)ves_lme_work_size(MMAX) * sizeof(double));
  if (!x || !pts || !tab || !work) return 1;
  printf("ves_lme_eval, gamma = %.2f, tol0 = %.0e, newton_tol = %.0e; "
         "%d points along a path, steps 0.05 h;\nwarm = lambda from the "
         "previous point. ~1 s per row, single thread.\n\n",
         par.gamma, par.tol0, par.newton_tol, NPTS);
  printf("%-22s %6s %5s %5s %12s %10s %6s\n", "lattice", "m", "nder", "start", "evals/s", "us/eval",
         "Newton");
  const char *names[2] = {"hex", "hex, jitter 0.2 h"};
  const double jit[2] = {0.0, 0.2};
  for (int l = 0; l < 2; l++) {
    uint64_t s = 99 + l;
    int n = lattice(x, cap, 10.0, jit[l], &s);
    double m = setup(pts, x, n, &par, &s);
    for (int nder = 0; nder <= 2; nder++)
      for (int warm = 0; warm <= 1; warm++) {
        double it;
        int fails;
        double rate = run(pts, &par, nder, warm, tab, work, &it, &fails);
        printf("%-22s %6.1f %5d %5s %12.0f %10.2f %6.2f%s\n", names[l], m, nder,
               warm ? "warm" : "cold", rate, 1e6 / rate, it, fails ? "  (failures!)" : "");
      }
  }
  free(x);
  free(pts);
  free(tab);
  free(work);
  return 0;
}
