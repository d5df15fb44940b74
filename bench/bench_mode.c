/* vesica — the hydrodynamic time scale: relaxation of a P_l shape
 * mode of a sphere with bending alone (problems/mode2.ini, mode3.ini), timed
 * through the shape itself rather than the energy.
 *
 * Observable: the multipole moment of the interior indicator chi = (1 + phi)/2,
 *   Q_l(t) = 2 pi sum_alpha w_alpha r det F chi (rho^l P_l(cos theta))
 * about the current centroid (rho, theta: polar coordinates of the point's
 * current position y(X_alpha) relative to it). For r = 1 + delta P_l,
 * Q_l = 4 pi delta / (2l + 1) + O(delta^2, eps^2): linear in the amplitude,
 * and free of the energy's discretization offset, so log Q_l is a straight
 * line of slope -s_l (the amplitude rate) once faster transients are gone.
 * The variational step is backward Euler for a linear gradient flow with K
 * frozen at y^n: the amplitude shrinks by 1/(1 + s dt) a step, so the
 * continuous rate is s = (exp(r dt) - 1) / dt with r the fitted slope.
 *
 * Prints a header (with E*(0)), then "t E* Q_l" per step (with --print), then one line
 *   l eps h_band lambda_ratio dt nodes s_raw s 2s
 * fitted over [--from, --to]. Threads: OMP_NUM_THREADS.
 * --restore M restores phi's tanh profile after every M steps (profile.h,
 * [solver] profile_every); the per-step line then adds E* after the
 * restoration and the largest shift of the level sets it made. --split
 * (without --restore) adds per step E* of the restored profile at the same
 * positions, the model put back after: E* - E*(restored) is the energy of the
 * profile's stretch.
 * --power T prints, for the step starting at t* T (within dt/2), the power
 * d^T K(y^n) d / dt^2 it dissipates split into shear 2 mu |D|^2 and
 * compression lambda (div v)^2, over the band |phi| < 0.9, the shell
 * 0.9 <= |phi| < 0.99, the rest and with
 * the weight 1 - phi^2 (phi the step's), beside -d(E*)/dt over the step and the
 * model's own d^T K d (power_table).
 * Usage: bench_mode [CONFIG] [--set section.key=value]... [--dt DT]
 *        [--from T] [--to T] [--print] [--restore M] [--split] [--power T]
 * (default: problems/mode2.ini, dt 0.04, window [0.4, 1.6]). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/backend.h"
#include "app/config.h"
#include "app/problem.h"
#include "ves/integrate.h"
#include "ves/profile.h"
#include "ves/setup.h"
#include "bench_common.h"
#include "app/blas_core_impl.h"

#define MAX_SET 32

/* P_l(x) for l <= 4. */
static double legendre(int l, double x) {
  switch (l) {
  case 0:
    return 1;
  case 1:
    return x;
  case 2:
    return 0.5 * (3 * x * x - 1);
  case 3:
    return 0.5 * (5 * x * x * x - 3 * x);
  default:
    return (35 * x * x * x * x - 30 * x * x + 3) / 8;
  }
}

/* Current r, z, det F and chi at every point: out[4 nq]. */
static void point_state(const ves_setup *s, const double *phi, const double *y, double *out) {
  const ves_quad *q = s->quad;
  for (int al = 0; al < q->nq; al++) {
    double r = 0, rR = 0, rZ = 0, z = 0, zR = 0, zZ = 0;
    const int m = q->ptr[al + 1] - q->ptr[al];
    const double *T = q->tab + 6 * (size_t)q->ptr[al];
    for (int k = 0; k < m; k++) {
      const int a = q->nbr[q->ptr[al] + k];
      const double sr = q->mirror[q->ptr[al] + k] ? -1.0 : 1.0; /* ghost: (-r, z) */
      const double ya = sr * y[2 * a], za = y[2 * a + 1];
      r += T[k] * ya, rR += T[m + k] * ya, rZ += T[2 * m + k] * ya;
      z += T[k] * za, zR += T[m + k] * za, zZ += T[2 * m + k] * za;
    }
    out[4 * al] = r, out[4 * al + 1] = z, out[4 * al + 2] = rR * zZ - rZ * zR;
    out[4 * al + 3] = 0.5 * (1 + phi[6 * al]);
  }
}

/* Q_l about the centroid of chi. */
static double moment(const ves_setup *s, const double *ps, int l) {
  const ves_quad *q = s->quad;
  double m0 = 0, m1 = 0, Q = 0;
  for (int al = 0; al < q->nq; al++) {
    const double *p = ps + 4 * al, dv = 2 * M_PI * q->w[al] * p[0] * p[2] * p[3];
    m0 += dv, m1 += dv * p[1];
  }
  const double zc = m1 / m0;
  for (int al = 0; al < q->nq; al++) {
    const double *p = ps + 4 * al, dv = 2 * M_PI * q->w[al] * p[0] * p[2] * p[3];
    const double dz = p[1] - zc, rho = hypot(p[0], dz);
    if (rho > 0) Q += dv * pow(rho, l) * legendre(l, dz / rho);
  }
  return Q;
}

/* --power: the step y^n -> y^n + d's dissipated power d^T K(y^n) d / dt^2 per
 * point, split into shear 2 mu |D|^2 and compression lambda (div v)^2 (the
 * terms of ves_model_local_dissip, v = d / dt, L = Fdot F^-1 at y^n, hoop
 * rate rdot/r), and by phi (point data of the step, pd): the band |phi| < 0.9,
 * the shell 0.9 <= |phi| < 0.99 beside it, the rest, and the weight 1 - phi^2;
 * density: a region's share of the power over its share of the volume.
 * Prints one table; dE (E*^{n+1} - E*^n) for the energy released, Pm the
 * model's d^T K d / dt^2 (the check). */
static void power_table(const ves_setup *s, const ves_model_params *mp, double k, const double *pd,
                        const double *yn, const double *d, double dt, double t0, double dE,
                        double Pm) {
  const ves_quad *q = s->quad;
  double vol[5] = {0}, sh[5] = {0}, co[5] = {0}; /* band, shell, rest, weighted, all */
  for (int al = 0; al < q->nq; al++) {
    double r = 0, rR = 0, rZ = 0, zR = 0, zZ = 0, v = 0, vR = 0, vZ = 0, wR = 0, wZ = 0;
    const int m = q->ptr[al + 1] - q->ptr[al];
    const double *T = q->tab + 6 * (size_t)q->ptr[al];
    for (int j = 0; j < m; j++) {
      const int a = q->nbr[q->ptr[al] + j];
      const double sr = q->mirror[q->ptr[al] + j] ? -1.0 : 1.0; /* ghost: (-r, z) */
      const double ya = sr * yn[2 * a], za = yn[2 * a + 1];
      const double ua = sr * d[2 * a] / dt, wa = d[2 * a + 1] / dt;
      r += T[j] * ya, rR += T[m + j] * ya, rZ += T[2 * m + j] * ya;
      zR += T[m + j] * za, zZ += T[2 * m + j] * za;
      v += T[j] * ua, vR += T[m + j] * ua, vZ += T[2 * m + j] * ua;
      wR += T[m + j] * wa, wZ += T[2 * m + j] * wa;
    }
    const double J = rR * zZ - rZ * zR;
    /* H = F^-1 (material x spatial); L_ij = Fdot_iI H_Ij */
    const double HRr = zZ / J, HRz = -rZ / J, HZr = -zR / J, HZz = rR / J;
    const double Lrr = vR * HRr + vZ * HZr, Lrz = vR * HRz + vZ * HZz;
    const double Lzr = wR * HRr + wZ * HZr, Lzz = wR * HRz + wZ * HZz, hs = v / r;
    const double dv = 2 * M_PI * q->w[al] * r * J, ph = pd[6 * al];
    const double pS =
        dv * 2 * mp->mu * (Lrr * Lrr + Lzz * Lzz + hs * hs + 0.5 * (Lrz + Lzr) * (Lrz + Lzr)) / k;
    const double dvg = Lrr + Lzz + hs, pC = dv * mp->lambda * dvg * dvg / k;
    const int b = fabs(ph) < 0.9 ? 0 : (fabs(ph) < 0.99 ? 1 : 2);
    const double wt = 1 - ph * ph;
    vol[b] += dv, sh[b] += pS, co[b] += pC;
    vol[3] += wt * dv, sh[3] += wt * pS, co[3] += wt * pC;
    vol[4] += dv, sh[4] += pS, co[4] += pC;
  }
  printf("# power over the step t* %.4f -> %.4f (units k/t*; volume R0^3): -dE*/dt %.6e, "
         "model d^T K d/dt^2 %.6e, sum of points %.6e\n",
         t0, t0 + dt, -dE / dt, Pm / k, sh[4] + co[4]);
  printf("# region volume vol_share shear compression power_share shear_share comp_share "
         "density (power_share / vol_share)\n");
  const char *name[5] = {"band|phi|<0.9", "shell0.9<=|phi|<0.99", "rest", "weight(1-phi^2)", "all"};
  const double P = sh[4] + co[4];
  for (int i = 0; i < 5; i++)
    printf("%s %.6e %.4f %.6e %.6e %.4f %.4f %.4f %.3f\n", name[i], vol[i], vol[i] / vol[4], sh[i],
           co[i], (sh[i] + co[i]) / P, sh[i] / P, co[i] / P, (sh[i] + co[i]) / P * vol[4] / vol[i]);
}

/* --power: the step's start: y^n, its phi and E*^n (after a restoration). */
static void power_start(ves_sim *sim, double *yn, double *pdn, double *En) {
  ves_sim_state ss;
  ves_sim_get_state(sim, &ss, yn);
  ves_model_point_data(ves_sim_model(sim), pdn);
  *En = ss.E;
}

/* --power: the step from y^n (yn, phi pdn, E*^n En, t* tn) just taken: the
 * model's d^T K(y^n) d as the check, then power_table. */
static ves_status power_step(const ves_setup *s, ves_sim *sim, const double *yn, const double *pdn,
                             double En, double tn, const ves_step_report *rep) {
  ves_model *m = ves_sim_model(sim);
  ves_model_params mp;
  ves_model_get_params(m, &mp);
  const int n2 = 2 * s->nodes->n;
  const double *y1 = ves_sim_y(sim), dt = rep->t - tn;
  double *d = malloc(2 * (size_t)n2 * sizeof *d), Ek = 0, Dv = 0;
  double *qn = malloc(ves_model_dissipation_ref_size(m) * sizeof *qn);
  ves_status st = d && qn ? VES_OK : VES_ERR_ALLOC;
  if (st == VES_OK) {
    for (int i = 0; i < n2; i++) d[i] = y1[i] - yn[i];
    st = ves_model_dissipation_ref(m, yn, qn);
  }
  if (st == VES_OK)
    st = ves_model_eval_step(m, y1, VES_F_E, qn, NULL, 1.0, &Ek, NULL, NULL, &Dv, d + n2, NULL,
                             NULL);
  if (st == VES_OK) {
    if (mp.drift > 0) printf("# --power: the drift damping's share is not in the table\n");
    power_table(s, &mp, ves_model_get_k(m), pdn, yn, d, dt, tn, rep->E - En, 2 * Dv / (dt * dt));
  }
  free(d);
  free(qn);
  return st;
}

/* Kept whole (134 lines): the option parsing, the runs and the table they print, in order. */
int main(int argc, char **argv) {
  ves_blas_core_fix(argv); /* OpenBLAS's kernels (blas_core_impl.h) */
  setvbuf(stdout, NULL, _IOLBF, 0);
  const char *path = "problems/mode2.ini", *set[MAX_SET];
  int nset = 0, print = 0, restore = 0, split = 0;
  double dt = 0.04, from = 0.4, to = 1.6, tpow = -1;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--set") && v && nset < MAX_SET)
      set[nset++] = v, i++;
    else if (!strcmp(a, "--dt") && v)
      dt = atof(v), i++;
    else if (!strcmp(a, "--from") && v)
      from = atof(v), i++;
    else if (!strcmp(a, "--to") && v)
      to = atof(v), i++;
    else if (!strcmp(a, "--print"))
      print = 1;
    else if (!strcmp(a, "--restore") && v)
      restore = atoi(v), i++;
    else if (!strcmp(a, "--split"))
      split = 1;
    else if (!strcmp(a, "--power") && v)
      tpow = atof(v), i++;
    else if (a[0] != '-')
      path = a;
    else {
      fprintf(stderr, "bench_mode: bad argument '%s' (see bench/bench_mode.c)\n", a);
      return 2;
    }
  }
  if (!(dt > 0 && to > from && from >= 0 && restore >= 0 && !(split && restore))) {
    fprintf(stderr,
            "bench_mode: need dt > 0, 0 <= from < to, --restore M >= 0, not with --split\n");
    return 2;
  }
  ves_config cfg;
  char err[1024] = "";
  if (ves_config_load(path, nset, set, &cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "bench_mode: %s\n", err);
    return 2;
  }
  if (cfg.mode < 1 || cfg.mode > 4) {
    fprintf(stderr, "bench_mode: %s: [shape] mode must be 1 to 4\n", path);
    return 2;
  }
  ves_setup *s = NULL;
  if (ves_problem_setup_create(&cfg, VES_PHI0_L2, &s, err, sizeof err) != VES_OK) {
    fprintf(stderr, "bench_mode: %s: %s\n", path, err);
    return 3;
  }
  const int nq = s->quad->nq, l = cfg.mode;
  double *phi = malloc(6 * (size_t)nq * sizeof *phi), *ps = malloc(4 * (size_t)nq * sizeof *ps);
  if (!phi || !ps) return 3;
  ves_quad_field(s->quad, s->phi0c, 0, phi);
  ves_integrate_params ip;
  bench_constant_params(&cfg, dt, to, &ip);
  ip.profile_every = restore ? restore : (split ? 0 : cfg.profile_every); /* or the key's */
  ves_backend_options bo;
  bench_backend_options(&cfg, &bo);
  ves_sim *sim = NULL;
  ves_status st = ves_sim_create(s->model, ves_backend_find(cfg.backend), &bo, &ip, &sim);
  if (st != VES_OK) {
    fprintf(stderr, "bench_mode: %s\n", ves_status_str(st));
    return 3;
  }
  double E0;
  ves_sim_initial(sim, &E0, NULL, NULL);
  point_state(s, phi, ves_sim_y(sim), ps);
  const double Q0 = moment(s, ps, l);
  printf("# %s l %d eps %g h_band %g lambda/mu %g dt %g: %d nodes; Q_l(0) = %.6e "
         "(sharp 4 pi delta/(2l+1) = %.6e); E*(0) %.9f\n",
         path, l, cfg.epsilon, cfg.h_band, cfg.lambda_ratio, dt, s->nodes->n, Q0,
         4 * M_PI * cfg.delta / (2 * l + 1), E0);
  if (print) printf("%.6f %.12f %.9e\n", 0.0, E0, Q0);
  /* least squares of log|Q| against t over the window */
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  ves_step_report rep;
  ves_profile *prof = NULL;
  if (split && ves_profile_create(&prof) != VES_OK) return 3;
  const int n2 = 2 * s->nodes->n;
  double *yn = tpow >= 0 ? malloc((size_t)n2 * sizeof *yn) : NULL, *pdn = NULL, En = 0;
  if (tpow >= 0 && (!yn || !(pdn = malloc(6 * (size_t)nq * sizeof *pdn)))) return 3;
  for (;;) {
    const double tn = ves_sim_time(sim);
    const int pstep = tpow >= 0 && tn <= tpow + 0.5 * dt && tn + 0.5 * dt > tpow;
    if (pstep) power_start(sim, yn, pdn, &En);
    if ((st = ves_sim_step(sim, &rep)) != VES_OK) break;
    if (pstep && power_step(s, sim, yn, pdn, En, tn, &rep) != VES_OK) return 3;
    ves_model_point_data(ves_sim_model(sim), phi); /* the restored phi0 too */
    point_state(s, phi, ves_sim_y(sim), ps);
    const double Q = moment(s, ps, l);
    if (print && restore) {
      ves_sim_state ss;
      ves_sim_get_state(sim, &ss, NULL);
      printf("%.6f %.12f %.9e %.12f %.3e\n", rep.t, rep.E, Q, ss.E, rep.profile_shift);
    } else if (print && split) {
      ves_model *m = ves_sim_model(sim);
      ves_profile_info info = {0, NAN, NAN};
      double Er = NAN;
      if (ves_profile_restore(prof, m, ves_sim_y(sim), &info) == VES_OK &&
          ves_model_eval(m, ves_sim_y(sim), VES_F_E, &Er, NULL, NULL, NULL, NULL, NULL) == VES_OK)
        Er /= ves_model_get_k(m);
      ves_profile_forget(prof);           /* its coefficients are the restored ones */
      (void)ves_model_set_points(m, phi); /* phi holds the run's point data */
      printf("%.6f %.12f %.9e %.12f %.3e\n", rep.t, rep.E, Q, Er, info.max_shift);
    } else if (print)
      printf("%.6f %.12f %.9e\n", rep.t, rep.E, Q);
    if (rep.t >= from - 1e-12 && rep.t <= to + 1e-12) {
      const double x = rep.t, yv = log(fabs(Q));
      n++, sx += x, sy += yv, sxx += x * x, sxy += x * yv;
    }
  }
  if (st < 0) {
    fprintf(stderr, "bench_mode: step failed at t* = %g: %s\n", ves_sim_time(sim),
            ves_status_str(st));
    return 3;
  }
  if (n < 3) {
    fprintf(stderr, "bench_mode: fewer than 3 steps in the window\n");
    return 2;
  }
  const double r = -(n * sxy - sx * sy) / (n * sxx - sx * sx), sl = (exp(r * dt) - 1) / dt;
  printf("l %d eps %g h_band %g lambda_ratio %g dt %g nodes %d s_raw %.5f s %.5f 2s %.5f\n", l,
         cfg.epsilon, cfg.h_band, cfg.lambda_ratio, dt, s->nodes->n, r, sl, 2 * sl);
  ves_sim_destroy(&sim);
  ves_profile_destroy(&prof);
  free(yn);
  free(pdn);
  free(phi);
  free(ps);
  ves_setup_destroy(&s);
  return 0;
}
