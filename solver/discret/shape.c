/* vesica — initial shapes as smooth parametric generating curves
 * P(t) = (R(t), Z(t)), t in [0, pi] from the north pole to the south pole,
 * with their exact signed distance and sharp area/volume (the node sizing
 * field built on the distance: sizing.c).
 *
 * Distance: the curve is sampled at VES_SHAPE_NS parameter values; the samples
 * that are local minima of |P - X| within one sample spacing of the smallest
 * one (found among the blocks of VES_SHAPE_NS / VES_SHAPE_NB samples whose
 * bounding circles come near enough, bit for bit the seeds of a scan of every
 * sample, ves_shape_distance_reference: 2.0 against 7.2 us a point on the
 * oblate, and ~330k points at eps 0.01's setup)
 * seed a safeguarded Newton iteration on g(t) = |P(t) - X|^2 / 2
 * (g' = (P - X).P', g'' = |P'|^2 + (P - X).P''), kept inside the bracket of
 * the neighbouring samples. The sign comes from the inward normal at the
 * closest point, n_in = (Z', -R') / |P'| for this orientation, so it is exact
 * (a sampled polygon would get the sign wrong within its sagitta, which at
 * eps = 0.01 would spoil phi0 by ~1e-3 next to the interface).
 * docs/design.md, "Discretization". */
#include "ves/shape.h"

#include "ves/geom.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>

#define VES_SHAPE_NS 1024         /* samples of the curve for the coarse search */
#define VES_SHAPE_NCAND 8         /* Newton seeds at most */
#define VES_SHAPE_NB 32           /* blocks of VES_SHAPE_NS / VES_SHAPE_NB consecutive samples */
#define SAMPLE_SLACK (1.0 + 1e-9) /* bounds against hypot's rounding (a few ulps) */

/* Evans-Fung parameters (micrometres; rescaled to area 4 pi). */
#define EF_D 7.82
#define EF_C0 0.81
#define EF_C2 7.83
#define EF_C4 (-4.39)

struct ves_shape {
  ves_shape_params par;                          /* as given */
  double a, c;                                   /* spheroid semi-axes (equatorial, polar) */
  double scale;                                  /* discocyte: factor to area 4 pi */
  double ts[VES_SHAPE_NS], ps[2 * VES_SHAPE_NS]; /* samples t_i, P(t_i) */
  double ds_max;                                 /* largest distance between consecutive samples */
  double bc[2 * VES_SHAPE_NB], br[VES_SHAPE_NB]; /* blocks of samples: centre, radius */
  double length;                                 /* sum of those distances: the meridian's length */
  /* curve: periodic cubic spline through the points and their mirror image */
  int ns;     /* knots of the closed loop, 2 (npts - 1) */
  double *u;  /* ns + 1 chord-length parameters, u[ns] = U */
  double *kp; /* 2 (ns + 1) knot coordinates (R, Z), last = first */
  double *m2; /* 2 ns second derivatives d2/du2 at the knots */
};

void ves_shape_params_default(ves_shape_params *par) {
  par->kind = VES_SHAPE_SPHERE;
  par->radius = 1.0;
  par->v = 0.9;
  par->prolate = 0;
  par->mode = 0;
  par->delta = 0.0;
  par->npts = 0;
  par->pts = NULL;
  par->keep_scale = 0;
}

/* Legendre P_l(x) and its first two derivatives by the three-term recurrences
 * (n+1)P_{n+1} = (2n+1) x P_n - n P_{n-1},  P'_{n+1} = P'_{n-1} + (2n+1) P_n. */
static void legendre(int l, double x, double *p, double *dp, double *ddp) {
  double p0 = 1, p1 = x, d0 = 0, d1 = 1, e0 = 0, e1 = 0;
  if (l == 0) {
    *p = 1, *dp = 0, *ddp = 0;
    return;
  }
  for (int n = 1; n < l; n++) {
    double p2 = ((2 * n + 1) * x * p1 - n * p0) / (n + 1);
    double d2 = d0 + (2 * n + 1) * p1, e2 = e0 + (2 * n + 1) * d1;
    p0 = p1, p1 = p2, d0 = d1, d1 = d2, e0 = e1, e1 = e2;
  }
  *p = p1, *dp = d1, *ddp = e1;
}

/* P(t), P'(t), P''(t) of the unperturbed curve. */
static void base_curve(const ves_shape *s, double t, double P[2], double D[2], double DD[2]) {
  double st = sin(t), ct = cos(t);
  switch (s->par.kind) {
  case VES_SHAPE_SPHERE:
    P[0] = s->par.radius * st, P[1] = s->par.radius * ct;
    D[0] = s->par.radius * ct, D[1] = -s->par.radius * st;
    DD[0] = -P[0], DD[1] = -P[1];
    break;
  case VES_SHAPE_SPHEROID:
    P[0] = s->a * st, P[1] = s->c * ct;
    D[0] = s->a * ct, D[1] = -s->c * st;
    DD[0] = -P[0], DD[1] = -P[1];
    break;
  case VES_SHAPE_CURVE: {
    /* u = t U / (2 pi): the half loop t in [0, pi] runs pole to pole */
    double U = s->u[s->ns], du = U / (2 * M_PI), uu = t * du;
    int lo = 0, hi = s->ns - 1;
    while (lo < hi) { /* last knot with u_k <= uu */
      int mid = (lo + hi + 1) / 2;
      if (s->u[mid] <= uu)
        lo = mid;
      else
        hi = mid - 1;
    }
    int k = lo;
    double h = s->u[k + 1] - s->u[k], a = (s->u[k + 1] - uu) / h, b = 1 - a;
    for (int i = 0; i < 2; i++) {
      double y0 = s->kp[2 * k + i], y1 = s->kp[2 * k + 2 + i];
      double M0 = s->m2[2 * k + i], M1 = s->m2[2 * ((k + 1) % s->ns) + i];
      /* cubic spline on [u_k, u_k+1] and its u-derivatives, times du/dt */
      P[i] = a * y0 + b * y1 + ((a * a * a - a) * M0 + (b * b * b - b) * M1) * h * h / 6;
      D[i] = ((y1 - y0) / h + (-(3 * a * a - 1) * M0 + (3 * b * b - 1) * M1) * h / 6) * du;
      DD[i] = (a * M0 + b * M1) * du * du;
    }
    break;
  }
  case VES_SHAPE_DISCOCYTE: {
    /* R = (D/2) sin t, Z = (1/2) cos t (C0 + C2 sin^2 t + C4 sin^4 t), scaled */
    double s2 = st * st, q = EF_C0 + EF_C2 * s2 + EF_C4 * s2 * s2;
    double dq = (2 * EF_C2 + 4 * EF_C4 * s2) * st * ct; /* dq/dt */
    double ddq =
        2 * EF_C2 * (ct * ct - s2) + 4 * EF_C4 * (3 * s2 * ct * ct - s2 * s2); /* d2q/dt2 */
    double k = s->scale;
    P[0] = k * 0.5 * EF_D * st, P[1] = k * 0.5 * ct * q;
    D[0] = k * 0.5 * EF_D * ct, D[1] = k * 0.5 * (-st * q + ct * dq);
    DD[0] = -P[0], DD[1] = k * 0.5 * (-ct * q - 2 * st * dq + ct * ddq);
    break;
  }
  }
}

/* The curve with the radial perturbation f(t) = 1 + delta P_l(cos t). */
static void curve(const ves_shape *s, double t, double P[2], double D[2], double DD[2]) {
  base_curve(s, t, P, D, DD);
  if (s->par.mode <= 0 || s->par.delta == 0.0) return;
  double st = sin(t), ct = cos(t), pl, dpl, ddpl;
  legendre(s->par.mode, ct, &pl, &dpl, &ddpl);
  double f = 1 + s->par.delta * pl, f1 = -s->par.delta * st * dpl,
         f2 = s->par.delta * (st * st * ddpl - ct * dpl);
  for (int i = 0; i < 2; i++) { /* (fP)'' = f''P + 2f'P' + fP'' */
    double p = P[i], d = D[i], dd = DD[i];
    P[i] = f * p, D[i] = f1 * p + f * d, DD[i] = f2 * p + 2 * f1 * d + f * dd;
  }
}

/* Area 2 pi int R |P'| dt and volume pi int R^2 (-Z') dt, Gauss-Legendre. */
static void sharp_integrals(const ves_shape *s, double *area, double *vol) {
  static const double gx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                               0.8611363115940526};
  static const double gw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                               0.3478548451374538};
  const int panels = 2000; /* 4-point rule per panel: error ~ (pi/2000)^8, far below rounding */
  double A = 0, V = 0, hp = M_PI / panels;
  for (int k = 0; k < panels; k++)
    for (int g = 0; g < 4; g++) {
      double t = (k + 0.5 * (gx[g] + 1)) * hp, P[2], D[2], DD[2];
      curve(s, t, P, D, DD);
      A += 0.5 * hp * gw[g] * 2 * M_PI * P[0] * hypot(D[0], D[1]);
      V += 0.5 * hp * gw[g] * M_PI * P[0] * P[0] * (-D[1]);
    }
  *area = A, *vol = V;
}

/* (1/2) int (H - C0)^2 dA / k, H = (k1 + k2)/2, by 4-point Gauss-Legendre
 * on panels of t. */
double ves_shape_sharp_energy(const ves_shape *s, double c0) {
  static const double gx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                               0.8611363115940526};
  static const double gw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                               0.3478548451374538};
  const int panels = 4000;
  double E = 0, hp = M_PI / panels;
  for (int k = 0; k < panels; k++)
    for (int g = 0; g < 4; g++) {
      double t = (k + 0.5 * (gx[g] + 1)) * hp, P[2], D[2], DD[2];
      curve(s, t, P, D, DD);
      double sp = hypot(D[0], D[1]);
      double k1 = (D[1] * DD[0] - D[0] * DD[1]) / (sp * sp * sp); /* meridional curvature */
      double k2 = -D[1] / (P[0] * sp);                            /* parallel curvature */
      double H = 0.5 * (k1 + k2) - c0;
      E += 0.5 * hp * gw[g] * 0.5 * H * H * 2 * M_PI * P[0] * sp; /* (1/2)(H-C0)^2 dA */
    }
  return E;
}

/* Reduced volume of a spheroid of aspect ratio rho = c / a (a = 1). */
static double spheroid_v(double rho) {
  double A, V = 4.0 / 3.0 * M_PI * rho;
  if (fabs(rho - 1) < 1e-12) return 1.0;
  if (rho < 1) {
    double e = sqrt(1 - rho * rho);
    A = 2 * M_PI * (1 + (1 - e * e) / e * atanh(e));
  } else {
    double e = sqrt(1 - 1 / (rho * rho));
    A = 2 * M_PI * (1 + rho / e * asin(e));
  }
  return V / (4.0 / 3.0 * M_PI * pow(A / (4 * M_PI), 1.5));
}

void ves_shape_destroy(ves_shape **s) {
  if (!s || !*s) return;
  free((*s)->u);
  free((*s)->kp);
  free((*s)->m2);
  free(*s);
  *s = NULL;
}

/* Periodic cubic spline through the loop (points, then their mirror image
 * back up): second derivatives from the cyclic tridiagonal system
 * h_{k-1} M_{k-1} + 2 (h_{k-1} + h_k) M_k + h_k M_{k+1}
 *   = 6 [(y_{k+1} - y_k)/h_k - (y_k - y_{k-1})/h_{k-1}],
 * solved by Sherman-Morrison around the Thomas algorithm. */
static ves_status curve_setup(ves_shape *s, int np, const double *pts) {
  int n = 2 * (np - 1);
  s->ns = n;
  s->u = malloc(((size_t)n + 1) * sizeof *s->u);
  s->kp = malloc(2 * ((size_t)n + 1) * sizeof *s->kp);
  s->m2 = malloc(2 * (size_t)n * sizeof *s->m2);
  double *w = malloc(6 * (size_t)n * sizeof *w);
  if (!s->u || !s->kp || !s->m2 || !w) {
    free(w);
    return VES_ERR_ALLOC;
  }
  for (int k = 0; k < np; k++) s->kp[2 * k] = pts[2 * k], s->kp[2 * k + 1] = pts[2 * k + 1];
  for (int k = 1; k < np - 1; k++) { /* mirror image, south to north */
    s->kp[2 * (np - 1 + k)] = -pts[2 * (np - 1 - k)];
    s->kp[2 * (np - 1 + k) + 1] = pts[2 * (np - 1 - k) + 1];
  }
  s->kp[2 * n] = s->kp[0], s->kp[2 * n + 1] = s->kp[1];
  s->u[0] = 0;
  for (int k = 0; k < n; k++) {
    double l = hypot(s->kp[2 * k + 2] - s->kp[2 * k], s->kp[2 * k + 3] - s->kp[2 * k + 1]);
    if (!(l > 0)) {
      free(w);
      return VES_ERR_ARG; /* repeated point */
    }
    s->u[k + 1] = s->u[k] + l;
  }
  double *dg = w, *lo = w + n, *up = w + 2 * n, *r = w + 3 * n, *z = w + 4 * n, *q = w + 5 * n;
  for (int i = 0; i < 2; i++) {
    for (int k = 0; k < n; k++) {
      double hm = s->u[k] - (k ? s->u[k - 1] : s->u[n - 1] - s->u[n]), hp = s->u[k + 1] - s->u[k];
      int km = (k + n - 1) % n;
      dg[k] = 2 * (hm + hp), lo[k] = hm, up[k] = hp;
      r[k] = 6 * ((s->kp[2 * (k + 1) + i] - s->kp[2 * k + i]) / hp -
                  (s->kp[2 * k + i] - s->kp[2 * km + i]) / hm);
    }
    /* A = T' + u v^T with the corners tl = A[0][n-1] = lo[0] and
     * bl = A[n-1][0] = up[n-1]: gam = -dg[0], u = (gam, 0.., bl),
     * v = (1, 0.., tl/gam), T' tridiagonal with dg[0] - gam and
     * dg[n-1] - tl bl / gam on the diagonal ends */
    double gam = -dg[0], tl = lo[0], bl = up[n - 1];
    for (int k = 0; k < n; k++) q[k] = 0;
    q[0] = gam, q[n - 1] = bl;
    double *d2 = z; /* Thomas: T' y = r and T' q' = u, c' kept in d2 */
    for (int pass = 0; pass < 2; pass++) {
      double *rhs = pass ? q : r;
      /* Thomas on the tridiagonal part with the modified ends */
      double cp_prev = 0, dp_prev = 0;
      for (int k = 0; k < n; k++) {
        double b = dg[k] - (k == 0 ? gam : 0) - (k == n - 1 ? tl * bl / gam : 0);
        double a = k ? lo[k] : 0, c = k < n - 1 ? up[k] : 0;
        double den = b - a * cp_prev;
        cp_prev = c / den;
        dp_prev = (rhs[k] - a * dp_prev) / den;
        d2[k] = cp_prev, rhs[k] = dp_prev; /* store c' in d2, d' in rhs */
      }
      for (int k = n - 2; k >= 0; k--) rhs[k] -= d2[k] * rhs[k + 1];
    }
    /* x = y - (v.y / (1 + v.q')) q' */
    double vy = r[0] + tl / gam * r[n - 1], vz = q[0] + tl / gam * q[n - 1];
    for (int k = 0; k < n; k++) s->m2[2 * k + i] = r[k] - vy / (1 + vz) * q[k];
  }
  free(w);
  return VES_OK;
}

/* The curve at VES_SHAPE_NS parameter values t_i = pi i / (NS - 1), its
 * polygon length and largest chord, and each block's bounding circle: centre
 * of its box, radius to its farthest sample (the coarse search's lower
 * bounds, ves_shape_distance). */
static void sample_curve(ves_shape *s) {
  s->ds_max = 0, s->length = 0;
  for (int i = 0; i < VES_SHAPE_NS; i++) {
    double D[2], DD[2];
    s->ts[i] = M_PI * i / (VES_SHAPE_NS - 1);
    curve(s, s->ts[i], s->ps + 2 * i, D, DD);
    if (i > 0) {
      double l = hypot(s->ps[2 * i] - s->ps[2 * i - 2], s->ps[2 * i + 1] - s->ps[2 * i - 1]);
      if (l > s->ds_max) s->ds_max = l;
      s->length += l;
    }
  }
  for (int b = 0, w = VES_SHAPE_NS / VES_SHAPE_NB; b < VES_SHAPE_NB; b++) {
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY}, rad = 0;
    for (int i = b * w; i < (b + 1) * w; i++)
      for (int k = 0; k < 2; k++)
        lo[k] = fmin(lo[k], s->ps[2 * i + k]), hi[k] = fmax(hi[k], s->ps[2 * i + k]);
    for (int k = 0; k < 2; k++) s->bc[2 * b + k] = 0.5 * (lo[k] + hi[k]);
    for (int i = b * w; i < (b + 1) * w; i++)
      rad = fmax(rad, hypot(s->ps[2 * i] - s->bc[2 * b], s->ps[2 * i + 1] - s->bc[2 * b + 1]));
    s->br[b] = rad;
  }
}

ves_status ves_shape_create(const ves_shape_params *par, ves_shape **out) {
  VES_CHECK(par && out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(par->kind == VES_SHAPE_SPHERE || par->kind == VES_SHAPE_SPHEROID ||
                par->kind == VES_SHAPE_DISCOCYTE || par->kind == VES_SHAPE_CURVE,
            VES_ERR_ARG);
  if (par->kind == VES_SHAPE_CURVE) { /* pole to pole, R >= 0 */
    VES_CHECK(par->npts >= 4 && par->pts, VES_ERR_ARG);
    VES_CHECK(par->pts[0] == 0.0 && par->pts[2 * par->npts - 2] == 0.0, VES_ERR_ARG);
    VES_CHECK(par->pts[1] > par->pts[2 * par->npts - 1], VES_ERR_ARG);
    for (int k = 0; k < par->npts; k++)
      VES_CHECK(par->pts[2 * k] >= 0 && isfinite(par->pts[2 * k]) && isfinite(par->pts[2 * k + 1]),
                VES_ERR_ARG);
  }
  VES_CHECK(par->kind != VES_SHAPE_SPHERE || par->radius > 0, VES_ERR_ARG);
  VES_CHECK(par->kind != VES_SHAPE_SPHEROID || (par->v > 0.2 && par->v <= 1.0), VES_ERR_ARG);
  VES_CHECK(par->mode >= 0 && par->mode <= 40 && fabs(par->delta) < 0.5, VES_ERR_ARG);
  ves_shape *s = calloc(1, sizeof *s);
  if (!s) return VES_ERR_ALLOC;
  s->par = *par;
  s->par.pts = NULL; /* copied into the spline knots, not kept */
  s->scale = 1.0;
  if (par->kind == VES_SHAPE_SPHEROID) {
    /* bisection on the aspect ratio: v(rho) increases on (0,1), decreases on (1,inf) */
    double lo = par->prolate ? 1.0 : 1e-3, hi = par->prolate ? 1e3 : 1.0;
    for (int it = 0; it < 200; it++) {
      double mid = 0.5 * (lo + hi), vm = spheroid_v(mid);
      if ((vm < par->v) == (par->prolate == 0))
        lo = mid;
      else
        hi = mid;
    }
    double rho = 0.5 * (lo + hi);
    s->a = 1.0, s->c = rho;
    double A, V;
    sharp_integrals(s, &A, &V);
    double k = sqrt(4 * M_PI / A); /* scale to area 4 pi */
    s->a = k, s->c = k * rho;
  } else if (par->kind == VES_SHAPE_CURVE) {
    ves_status st = curve_setup(s, par->npts, par->pts);
    if (st == VES_OK && !par->keep_scale) { /* scale to area 4 pi */
      double A, V;
      sharp_integrals(s, &A, &V);
      /* the spline through a valid polygon can still swing across the axis
       * (a long segment after short ones): no area, or R < 0 on the way */
      if (!(isfinite(A) && A > 0 && isfinite(V) && V > 0)) st = VES_ERR_GEOM;
      for (int i = 1; st == VES_OK && i < VES_SHAPE_NS - 1; i++) {
        double P[2], D[2], DD[2];
        curve(s, M_PI * i / (VES_SHAPE_NS - 1), P, D, DD);
        if (!(P[0] > 0)) st = VES_ERR_GEOM;
      }
      if (st == VES_OK) {
        double k = sqrt(4 * M_PI / A);
        for (int i = 0; i < 2 * (s->ns + 1); i++) s->kp[i] *= k;
        for (int i = 0; i < 2 * s->ns; i++) s->m2[i] /= k;
        for (int i = 0; i <= s->ns; i++) s->u[i] *= k;
      }
    }
    if (st != VES_OK) {
      ves_shape_destroy(&s);
      return st;
    }
  } else if (par->kind == VES_SHAPE_DISCOCYTE) {
    double A, V;
    sharp_integrals(s, &A, &V);
    s->scale = sqrt(4 * M_PI / A);
  }
  sample_curve(s);
  *out = s;
  return VES_OK;
}

void ves_shape_extent(const ves_shape *s, double *rmax, double *zmax) {
  double r = 0, z = 0;
  for (int i = 0; i < VES_SHAPE_NS; i++) {
    r = fmax(r, s->ps[2 * i]);
    z = fmax(z, fabs(s->ps[2 * i + 1]));
  }
  *rmax = r, *zmax = z;
}

double ves_shape_length(const ves_shape *s) { return s->length; }

void ves_shape_axes(const ves_shape *s, double *a, double *c) {
  double P[2], D[2], DD[2];
  curve(s, 0.5 * M_PI, P, D, DD);
  *a = P[0];
  curve(s, 0.0, P, D, DD);
  *c = P[1];
}

/* A = 2 pi int R |P'| dt, V = pi int R^2 (-Z') dt (sharp_integrals). */
void ves_shape_sharp(const ves_shape *s, double *area, double *volume) {
  sharp_integrals(s, area, volume);
}

/* Minimize g(t) = |P(t) - X|^2 / 2 on [lo, hi] from t; returns the distance
 * and the parameter in *tbest. */
static double newton_closest(const ves_shape *s, const double X[2], double t, double lo, double hi,
                             double *tbest) {
  double P[2], D[2], DD[2];
  for (int it = 0; it < 60; it++) {
    curve(s, t, P, D, DD);
    double ex = P[0] - X[0], ez = P[1] - X[1];
    double g1 = ex * D[0] + ez * D[1];                               /* g'(t) */
    double g2 = D[0] * D[0] + D[1] * D[1] + ex * DD[0] + ez * DD[1]; /* g''(t) */
    if (g1 > 0)
      hi = t;
    else
      lo = t; /* the minimum is bracketed */
    double tn = g2 > 0 ? t - g1 / g2 : 0.5 * (lo + hi);
    if (!(tn > lo && tn < hi)) tn = 0.5 * (lo + hi); /* safeguard: bisect */
    if (fabs(tn - t) <= 1e-15 * (1 + fabs(t))) {
      t = tn;
      break;
    }
    t = tn;
    if (hi - lo <= 1e-15) break;
  }
  curve(s, t, P, D, DD);
  *tbest = t;
  return hypot(P[0] - X[0], P[1] - X[1]);
}

/* |P(t_i) - X| of sample i, as the seed tests compare it. */
static double sample_distance(const ves_shape *s, const double X[2], int i) {
  return hypot(s->ps[2 * i] - X[0], s->ps[2 * i + 1] - X[1]);
}

/* Newton from sample i (within its neighbours' bracket); keeps the nearest. */
static void seed(const ves_shape *s, const double X[2], int i, double *best, double *tb) {
  double t, d = newton_closest(s, X, s->ts[i], s->ts[i > 0 ? i - 1 : 0],
                               s->ts[i + 1 < VES_SHAPE_NS ? i + 1 : i], &t);
  if (d < *best) *best = d, *tb = t;
}

/* The distance d to the closest point P(tb), signed by the side of X. */
static double signed_distance(const ves_shape *s, const double X[2], double d, double tb) {
  double P[2], D[2], DD[2];
  curve(s, tb, P, D, DD);
  /* inward normal (Z', -R'): positive when X lies inside */
  double side = (X[0] - P[0]) * D[1] - (X[1] - P[1]) * D[0];
  return side >= 0 ? d : -d;
}

double ves_shape_distance(const ves_shape *s, const double X[2]) {
  if (!isfinite(X[0]) || !isfinite(X[1])) return NAN; /* no nearest point to search for */
  if (s->par.kind == VES_SHAPE_SPHERE && (s->par.mode == 0 || s->par.delta == 0.0))
    return s->par.radius - hypot(X[0], X[1]); /* exact closed form */
  /* The coarse search: the samples' blocks bound the distance (|X - c| -+
   * the block's radius); only the blocks that may hold a sample within reach
   * of the nearest (dmin + ds_max, the seeds' window) are scanned, on squared
   * distances; hypot only where a seed test could go either way. The seeds,
   * and so the distance, are bit for bit those of a hypot at every sample
   * (which would be ~10% of the setup's CPU at eps 0.01); SAMPLE_SLACK covers the
   * bounds' rounding. */
  const int w = VES_SHAPE_NS / VES_SHAPE_NB;
  double bd[VES_SHAPE_NB], ub = INFINITY;
  for (int b = 0; b < VES_SHAPE_NB; b++) {
    bd[b] = hypot(s->bc[2 * b] - X[0], s->bc[2 * b + 1] - X[1]);
    const double u = bd[b] + s->br[b];
    ub = u < ub ? u : ub; /* not fmin: a libm call at -O2 */
  }
  const double far = (ub + s->ds_max) * SAMPLE_SLACK; /* >= dmin + ds_max */
  int scan[VES_SHAPE_NB], nscan = 0;
  for (int b = 0; b < VES_SHAPE_NB; b++)
    if ((bd[b] - s->br[b]) <= far * SAMPLE_SLACK) scan[nscan++] = b;
  double d2[VES_SHAPE_NS], d2min = INFINITY;
  for (int k = 0; k < nscan; k++)
    for (int i = scan[k] * w; i < (scan[k] + 1) * w; i++) {
      const double dr = s->ps[2 * i] - X[0], dz = s->ps[2 * i + 1] - X[1];
      d2[i] = dr * dr + dz * dz;
      d2min = d2[i] < d2min ? d2[i] : d2min;
    }
  double dmin = INFINITY;
  const double near2 = d2min * SAMPLE_SLACK + DBL_MIN;
  for (int k = 0; k < nscan; k++)
    for (int i = scan[k] * w; i < (scan[k] + 1) * w; i++)
      if (d2[i] <= near2) {
        const double di = sample_distance(s, X, i);
        dmin = di < dmin ? di : dmin;
      }
  const double reach = dmin + s->ds_max, reach2 = reach * reach * SAMPLE_SLACK + DBL_MIN;
  double best = INFINITY, tb = 0;
  int seeds = 0;
  for (int k = 0; k < nscan && seeds < VES_SHAPE_NCAND; k++)
    for (int i = scan[k] * w; i < (scan[k] + 1) * w && seeds < VES_SHAPE_NCAND; i++) {
      if (d2[i] > reach2) continue; /* surely beyond dmin + ds_max */
      const double di = sample_distance(s, X, i);
      if (di > reach) continue;
      if (i > 0 && sample_distance(s, X, i - 1) < di) continue; /* not a local minimum */
      if (i + 1 < VES_SHAPE_NS && sample_distance(s, X, i + 1) < di) continue;
      seed(s, X, i, &best, &tb);
      seeds++;
    }
  return signed_distance(s, X, best, tb);
}

double ves_shape_distance_reference(const ves_shape *s, const double X[2]) {
  if (!isfinite(X[0]) || !isfinite(X[1])) return NAN;
  if (s->par.kind == VES_SHAPE_SPHERE && (s->par.mode == 0 || s->par.delta == 0.0))
    return s->par.radius - hypot(X[0], X[1]);
  double dist[VES_SHAPE_NS], dmin = INFINITY;
  for (int i = 0; i < VES_SHAPE_NS; i++) {
    dist[i] = sample_distance(s, X, i);
    if (dist[i] < dmin) dmin = dist[i];
  }
  double best = INFINITY, tb = 0;
  for (int i = 0, seeds = 0; i < VES_SHAPE_NS && seeds < VES_SHAPE_NCAND; i++) {
    if (dist[i] > dmin + s->ds_max) continue;
    if (i > 0 && dist[i - 1] < dist[i]) continue;
    if (i + 1 < VES_SHAPE_NS && dist[i + 1] < dist[i]) continue;
    seed(s, X, i, &best, &tb);
    seeds++;
  }
  return signed_distance(s, X, best, tb);
}

/* phi0 = tanh(d / (sqrt2 eps)), the equilibrium profile across the interface. */
double ves_shape_phi0(const ves_shape *s, double eps, const double X[2]) {
  return tanh(ves_shape_distance(s, X) / (M_SQRT2 * eps));
}

#define VES_BAND_NS 16384 /* samples per layer for its arclength table */

ves_status ves_shape_band_nodes(const ves_shape *s, double h, double halfwidth, int *n, double **x,
                                int **flag) {
  VES_CHECK(s && n && x && flag && h > 0 && halfwidth >= 0, VES_ERR_ARG);
  *n = 0, *x = NULL, *flag = NULL;
  const double dl = 0.5 * sqrt(3.0) * h; /* layer spacing of a hex lattice */
  int J = (int)floor(halfwidth / dl + 1e-9), cap = 0, cnt = 0;
  double *tt = malloc(VES_BAND_NS * sizeof *tt), *ss = malloc(VES_BAND_NS * sizeof *ss);
  double *xs = NULL;
  int *fs = NULL;
  ves_status st = VES_OK;
  if (!tt || !ss) {
    st = VES_ERR_ALLOC;
    goto done;
  }
  for (int j = -J; j <= J && st == VES_OK; j++) {
    double dj = j * dl, prev[2] = {0, 0}, prevP[2] = {0, 0};
    /* arclength table of the offset curve Q = P + dj n_in by chords */
    for (int k = 0; k < VES_BAND_NS; k++) {
      double t = M_PI * k / (VES_BAND_NS - 1), P[2], D[2], DD[2];
      curve(s, t, P, D, DD);
      double sp = hypot(D[0], D[1]), Q[2] = {P[0] + dj * D[1] / sp, P[1] - dj * D[0] / sp};
      tt[k] = t;
      ss[k] = 0;
      if (k > 0) {
        double c[2] = {Q[0] - prev[0], Q[1] - prev[1]}, e[2] = {P[0] - prevP[0], P[1] - prevP[1]};
        if (c[0] * e[0] + c[1] * e[1] <= 0) { /* the offset runs backwards: a fold */
          st = VES_ERR_GEOM;
          break;
        }
        ss[k] = ss[k - 1] + hypot(c[0], c[1]);
      }
      prev[0] = Q[0], prev[1] = Q[1], prevP[0] = P[0], prevP[1] = P[1];
    }
    if (st != VES_OK) break;
    double L = ss[VES_BAND_NS - 1];
    int nj = (int)lround(L / h), odd = (j % 2 != 0);
    if (nj < 2) continue;
    double hj = L / nj;
    int k = 0;
    for (int i = 0; i <= nj - odd; i++) {
      double target = (i + 0.5 * odd) * hj;
      while (k < VES_BAND_NS - 2 && ss[k + 1] < target) k++;
      double f = (target - ss[k]) / (ss[k + 1] - ss[k]); /* linear in t between samples */
      double t = tt[k] + f * (tt[k + 1] - tt[k]), P[2], D[2], DD[2];
      curve(s, t, P, D, DD);
      double sp = hypot(D[0], D[1]), X[2] = {P[0] + dj * D[1] / sp, P[1] - dj * D[0] / sp};
      int fl = 0;
      if (!odd && (i == 0 || i == nj)) X[0] = 0.0, fl = VES_NODE_AXIS; /* the poles */
      if (X[0] < 0) continue;
      /* keep only nodes at their layer's distance (not closer to another branch) */
      if (fabs(fabs(ves_shape_distance(s, X)) - fabs(dj)) > 0.25 * h) continue;
      /* a layer that runs along the axis (inside a neck or tether thinner
       * than the band): a node within dl/2 of it goes onto it, so no node
       * sits a fraction of a spacing from its mirrored ghost */
      if (fl == 0 && X[0] < 0.5 * dl) X[0] = 0.0, fl = VES_NODE_AXIS;
      if (cnt == cap) {
        cap = cap ? 2 * cap : 4096;
        double *nx = realloc(xs, 2 * (size_t)cap * sizeof *nx);
        int *nf = nx ? realloc(fs, (size_t)cap * sizeof *nf) : NULL;
        if (nx) xs = nx;
        if (nf) fs = nf;
        if (!nx || !nf) {
          st = VES_ERR_ALLOC;
          goto done;
        }
      }
      xs[2 * cnt] = X[0], xs[2 * cnt + 1] = X[1], fs[cnt++] = fl;
    }
  }
done:
  free(tt);
  free(ss);
  if (st != VES_OK) {
    free(xs);
    free(fs);
    return st;
  }
  *n = cnt, *x = xs, *flag = fs;
  return VES_OK;
}
