/* vesica — problem-file parsing: one table of keys (type, default, range,
 * documentation) drives defaults, parsing, validation and the key listing
 * (the keys: docs/manual.md; docs/design.md, "The program"). */
#include "app/config.h"

#include "ves/step.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

typedef enum { KEY_DOUBLE, KEY_INT, KEY_STRING } key_type;

typedef struct {
  const char *section, *key;
  key_type type;
  size_t offset;      /* into ves_config */
  const char *def;    /* default, as text */
  double min, max;    /* inclusive range (numbers) */
  const char *choice; /* strings: allowed values, '|'-separated */
  const char *doc;    /* units and meaning */
} key_spec;

#define OFF(f) offsetof(ves_config, f)
static const key_spec KEYS[] = {
    {"geometry", "epsilon", KEY_DOUBLE, OFF(epsilon), "0.04", 1e-4, 0.5, NULL,
     "interface width eps/R0 (paper: 0.01)"},
    {"geometry", "box_r", KEY_DOUBLE, OFF(box_r), "2.0", 0.1, 100, NULL,
     "meridian box extent in R (units R0)"},
    {"geometry", "box_z", KEY_DOUBLE, OFF(box_z), "2.0", 0.1, 100, NULL,
     "meridian box half-extent in Z (units R0)"},
    {"geometry", "resolution", KEY_STRING, OFF(resolution), "standard", 0, 0,
     "coarse|standard|fine|custom",
     "the band's node spacing by name: sets h_band to 0.6 (coarse), 0.5 (standard) or 0.4 (fine); "
     "an h_band given after it wins, and names itself (custom when it is none of these); errors "
     "and costs of each: docs/results.md, \"Cost against accuracy of the resolution\""},
    {"geometry", "h_band", KEY_DOUBLE, OFF(h_band), "0.5", 0.05, 2.0, NULL,
     "node spacing in the band, units of eps (<= 0.5 recommended; geometry.resolution names the "
     "measured choices)"},
    {"geometry", "band", KEY_DOUBLE, OFF(band), "5.5", 0.0, 20.0, NULL,
     "half-width of the refined band |d| < band*eps, units of eps"},
    {"geometry", "band_layers", KEY_INT, OFF(band_layers), "1", 0, 1, NULL,
     "1: nodes in the band on interface-aligned layers (hex lattice bent along the "
     "interface); 0: CVT everywhere but the axis strip"},
    {"geometry", "slope", KEY_DOUBLE, OFF(slope), "0.15", 0.01, 0.5, NULL,
     "growth rate of the spacing away from the band (< 0.2 recommended)"},
    {"geometry", "h_far", KEY_DOUBLE, OFF(h_far), "0.2", 1e-4, 10, NULL,
     "largest node spacing (units R0)"},
    {"geometry", "gamma", KEY_DOUBLE, OFF(gamma), "0.6", 0.1, 4.0, NULL,
     "LME aspect ratio gamma, beta_a = gamma/h_a^2 (0.6: docs/design.md, \"Numerical choices and "
     "why\")"},
    {"geometry", "support_tol", KEY_DOUBLE, OFF(support_tol), "1e-6", 1e-14, 1e-2, NULL,
     "LME support truncation tol0"},
    {"geometry", "quadrature", KEY_STRING, OFF(quadrature), "d4", 0, 0,
     "d4|d6|d4x4|d6x4|d4x16|d6x16",
     "rule per Delaunay triangle: base degree 4 (6 points) or 6 (12 points, Dunavant), "
     "xN on each of N congruent sub-triangles (docs/design.md, \"Numerical choices and why\")"},
    {"geometry", "stabilization", KEY_DOUBLE, OFF(stabilization), "0.1", 0, 1e6, NULL,
     "kappa (units k/R0^3): E gets (1/2) sum_a kappa 2 pi M_a/h_a^2 |y^a - y(X_a)|^2, positive "
     "curvature on the grid-scale coefficient modes, zero at the reference, O(h^2) on smooth "
     "motions (0: off, the paper's energy; docs/design.md, \"Numerical choices and why\")"},
    {"geometry", "axis_spacings", KEY_DOUBLE, OFF(axis_spacings), "10", 8, 50, NULL,
     "width of the regular lattice strip along the axis, in spacings"},
    {"geometry", "lloyd_iterations", KEY_INT, OFF(lloyd_iterations), "60", 0, 10000, NULL,
     "Lloyd (CVT) smoothing iterations of the node set"},
    {"geometry", "seed", KEY_INT, OFF(seed), "1", 0, 2147483647, NULL,
     "seed of the deterministic node sampling"},
    {"shape", "type", KEY_STRING, OFF(shape_type), "sphere", 0, 0,
     "sphere|spheroid|discocyte|curve", "initial shape"},
    {"shape", "points", KEY_STRING, OFF(points), "none", 0, 0, NULL,
     "curve: file of points 'R Z' from the north to the south pole (relative to the problem "
     "file's folder), scaled to area 4 pi"},
    {"shape", "radius", KEY_DOUBLE, OFF(radius), "1.0", 1e-3, 100, NULL,
     "sphere radius (units R0)"},
    {"shape", "reduced_volume", KEY_DOUBLE, OFF(reduced_volume), "0.9", 0.3, 1.0, NULL,
     "spheroid reduced volume v = V / (4 pi R0^3 / 3)"},
    {"shape", "orientation", KEY_STRING, OFF(orientation), "oblate", 0, 0, "oblate|prolate",
     "spheroid: oblate (short axis along Z) or prolate (long axis along Z)"},
    {"shape", "mode", KEY_INT, OFF(mode), "0", 0, 40, NULL,
     "radial perturbation 1 + delta P_mode(cos t); 0 for none"},
    {"shape", "delta", KEY_DOUBLE, OFF(delta), "0", -0.49, 0.49, NULL, "perturbation amplitude"},
    /* k and mu are the units: every energy the program reads and writes is
     * E* = E/k and every time t* = t k/(mu R0^3), so a k or mu other than 1
     * would only relabel the model's own time (docs/manual.md, "Units") */
    {"material", "k", KEY_DOUBLE, OFF(k), "1", 1, 1, NULL,
     "the bending stiffness, the energy unit (E* = E/k)"},
    {"material", "mu", KEY_DOUBLE, OFF(mu), "1", 1, 1, NULL,
     "the viscosity, with k and R0 the time unit (t* = t k/(mu R0^3))"},
    {"material", "lambda_ratio", KEY_DOUBLE, OFF(lambda_ratio), "100", 10, 1e8, NULL,
     "compressibility penalty lambda/mu (>= 10)"},
    {"material", "c0", KEY_DOUBLE, OFF(c0), "0", -100, 100, NULL, "spontaneous curvature C0 R0"},
    {"time", "t_end", KEY_DOUBLE, OFF(t_end), "1.0", 1e-12, 1e12, NULL, "final time (t*)"},
    {"time", "dt_initial", KEY_DOUBLE, OFF(dt_initial), "1e-4", 1e-14, 1e6, NULL,
     "first time step (t*)"},
    {"time", "dt_max", KEY_DOUBLE, OFF(dt_max), "0.1", 1e-14, 1e6, NULL, "largest time step (t*)"},
    {"time", "dt_min", KEY_DOUBLE, OFF(dt_min), "1e-10", 1e-16, 1e6, NULL,
     "smallest step when halving a rejected one; below it the run stops (t*)"},
    {"time", "adaptive", KEY_INT, OFF(adaptive), "1", 0, 1, NULL,
     "1: adapt dt to keep |dE*| per step near dE_target; 0: constant dt"},
    {"time", "dE_target", KEY_DOUBLE, OFF(dE_target), "0.02", 1e-12, 1e6, NULL,
     "target energy decrement per step (units k)"},
    {"time", "growth_max", KEY_DOUBLE, OFF(growth_max), "2", 1, 100, NULL,
     "largest factor between consecutive steps"},
    {"time", "iter_target", KEY_INT, OFF(iter_target), "8", 1, 10000, NULL,
     "above this many solver iterations (nlopt: Hessians) dt is not grown"},
    {"time", "factor_target", KEY_INT, OFF(factor_target), "2", 0, 10000, NULL,
     "above this many KKT factorizations in a step (newton with freeze_hessian >= 1: matrix "
     "builds and inertia corrections) dt is not grown; 0: no such rule"},
    {"time", "factor_shrink", KEY_INT, OFF(factor_shrink), "0", 0, 10000, NULL,
     "above this many KKT factorizations in a step (newton with freeze_hessian >= 1) the next "
     "dt is at most half this one, and the step counts as a rejection for retry_memory and "
     "retry_cap; 0: no such rule"},
    {"time", "predictor", KEY_INT, OFF(predictor), "1", 0, 1, NULL,
     "1: a step starts from the linear extrapolation of the last two states (y^{n-1} is kept in "
     "the snapshots: restarts stay bit-exact); 0: from y^n"},
    {"time", "order", KEY_INT, OFF(order), "1", 1, 2, NULL,
     "1: backward Euler steps (the paper's); 2: BDF2 steps, second order in dt where y^{n-1} "
     "is held (not with solver.backend = euler; needs growth_max <= 2.4)"},
    {"time", "retry_memory", KEY_INT, OFF(retry_memory), "10", 0, 1000000, NULL,
     "after a rejected attempt at dt_r, this many accepted steps keep dt <= retry_cap dt_r"},
    {"time", "retry_cap", KEY_DOUBLE, OFF(retry_cap), "0.7", 0.01, 1, NULL,
     "factor of that cap (1: up to the rejected dt)"},
    {"time", "event_cut", KEY_DOUBLE, OFF(event_cut), "0.5", 0.01, 1, NULL,
     "after a reset of the reference or a remeshing the next dt is at most this factor times "
     "the controller's (1: no cut)"},
    {"constraints", "area", KEY_INT, OFF(area), "1", 0, 1, NULL, "1: hold the area at A0"},
    {"constraints", "volume", KEY_INT, OFF(volume), "1", 0, 1, NULL,
     "1: hold the volume at its target (V0, or the protocol's ramp)"},
    {"protocol", "volume_rate", KEY_DOUBLE, OFF(volume_rate), "0", -1e6, 1e6, NULL,
     "volume ramp dV/dt / V0 (1/t*; < 0 deflates; 0: none)"},
    {"protocol", "volume_final", KEY_DOUBLE, OFF(volume_final), "1", 0.05, 20, NULL,
     "V/V0 at which the ramp stops and the volume is held"},
    {"protocol", "c0_time", KEY_DOUBLE, OFF(c0_time), "-1", -1, 1e12, NULL,
     "time of a step change of C0 (t*; -1: none)"},
    {"protocol", "c0_after", KEY_DOUBLE, OFF(c0_after), "0", -100, 100, NULL,
     "C0 R0 from c0_time on"},
    {"protocol", "c0_until", KEY_DOUBLE, OFF(c0_until), "-1", -1, 1e12, NULL,
     "time C0 returns to [material] c0, ending a pulse (t*; -1: never)"},
    {"protocol", "c0_ramp_start", KEY_DOUBLE, OFF(c0_ramp_start), "-1", -1, 1e12, NULL,
     "start of a C0 ramp: C0 rises linearly from [material] c0 at this time to c0_ramp_to at "
     "c0_ramp_end, then stays (t*; -1: none; not with c0_time)"},
    {"protocol", "c0_ramp_end", KEY_DOUBLE, OFF(c0_ramp_end), "-1", -1, 1e12, NULL,
     "end of the C0 ramp (t*; after c0_ramp_start)"},
    {"protocol", "c0_ramp_to", KEY_DOUBLE, OFF(c0_ramp_to), "0", -100, 100, NULL,
     "C0 R0 at the end of the ramp and after it"},
    {"solver", "backend", KEY_STRING, OFF(backend), "newton", 0, 0, "ipopt|nlopt|newton|euler",
     "step solver (euler: explicit, the paper's comparison)"},
    {"solver", "tol", KEY_DOUBLE, OFF(tol), "1e-9", 1e-16, 1e-2, NULL,
     "optimality tolerance of the step solve (relative)"},
    {"solver", "ctol", KEY_DOUBLE, OFF(ctol), "1e-10", 1e-16, 1e-2, NULL,
     "constraint tolerance, relative to A0 and V"},
    {"solver", "max_iter", KEY_INT, OFF(max_iter), "40", 1, 100000, NULL,
     "iterations per attempt of a step; an attempt that needs more is retried at dt/2"},
    {"solver", "max_builds", KEY_INT, OFF(max_builds), "0", 0, 100000, NULL,
     "newton (freeze_hessian >= 1): matrix builds (Hessian + factorization) per attempt of a "
     "step; an attempt that needs more is given up and retried at dt/2 (0: no limit)"},
    {"solver", "max_correction", KEY_DOUBLE, OFF(max_correction), "0", 0, 1e6, NULL,
     "newton: the largest inertia correction delta (the matrix H + delta K, K the dissipation) "
     "an attempt of a step may need (the correction ladder's last rung); a matrix that needs "
     "more gives the attempt up, retried at dt/2 (0: no limit)"},
    {"solver", "freeze_hessian", KEY_INT, OFF(freeze_hessian), "1", 0, 2, NULL,
     "newton: 0 a fresh Hessian every iteration; 1 assembled once per step, rebuilt when "
     "the chord stalls (paper); 2 also kept across steps while the chord converges"},
    {"solver", "factor_precision", KEY_STRING, OFF(factor_precision), "single", 0, 0,
     "single|double",
     "newton, euler: precision of the KKT factorization (single: half the memory, ~1.7x "
     "faster at eps 0.01, each solve refined in double to 1e-6 relative, newton's chord solves "
     "to 1e-3; double: MUMPS in double)"},
    {"solver", "drift_damping", KEY_DOUBLE, OFF(drift_damping), "0", 0, 1e6, NULL,
     "viscous penalty alpha on the rate of the coefficient drift y^a - y(X_a), added to the "
     "dissipation (0: off; docs/design.md, \"Numerical choices and why\")"},
    {"solver", "profile_every", KEY_INT, OFF(profile_every), "0", 0, 1000000, NULL,
     "restore phi to tanh(d / (sqrt2 eps)) of the signed distance d to its current zero set "
     "every this many accepted steps, positions kept (0: off; removes the band's resistance to "
     "normal stretch: shape-mode rates, docs/results.md; a restart does not carry it)"},
    {"reconnect", "every", KEY_INT, OFF(reconnect_every), "0", 0, 1000000, NULL,
     "reset the reference configuration to the current positions every this many accepted "
     "steps (paper Fig. 5: 20; 0: off)"},
    {"reconnect", "cond_max", KEY_DOUBLE, OFF(reconnect_cond_max), "0", 0, 1e12, NULL,
     "reset when max cond_2 F (distortion of the meridian motion since the last reset, "
     "dimensionless, >= 1) exceeds this; 0: off, else > 1"},
    {"reconnect", "det_min", KEY_DOUBLE, OFF(reconnect_det_min), "0", 0, 1, NULL,
     "reset when min det F (meridian area ratio since the last reset) drops below this; 0: "
     "off, else below 1"},
    {"reconnect", "nodes", KEY_STRING, OFF(reconnect_nodes), "coefficients", 0, 0,
     "coefficients|motion",
     "new reference nodes: the nodal coefficients y^a (paper) or the motion y(X_a) of the "
     "old nodes"},
    {"remesh", "every", KEY_INT, OFF(remesh_every), "0", 0, 1000000, NULL,
     "full remeshing (new adapted nodes, quadrature, phi projected, A and V restored) every "
     "this many accepted steps (paper Fig. 6; 0: off; each is stored in the output's "
     "/remeshes, and a restart continues across it)"},
    {"remesh", "cond_max", KEY_DOUBLE, OFF(remesh_cond_max), "0", 0, 1e12, NULL,
     "remesh when max cond_2 F since the last reference exceeds this; 0: off, else > 1"},
    {"remesh", "det_min", KEY_DOUBLE, OFF(remesh_det_min), "0", 0, 1, NULL,
     "remesh when min det F since the last reference drops below this; 0: off, else below 1"},
    {"remesh", "on_failed_reset", KEY_INT, OFF(remesh_on_failed_reset), "0", 0, 1, NULL,
     "1: remesh when a reset of the reference configuration was due and failed"},
    {"output", "snapshot_every", KEY_INT, OFF(snapshot_every), "10", 1, 1000000, NULL,
     "accepted steps between snapshots of nodes and phi"},
};
#define NKEYS ((int)(sizeof KEYS / sizeof KEYS[0]))

/* geometry.resolution's names for h_band (units eps); the choice of the
 * default and the measured cost and error of each: docs/results.md, "Cost
 * against accuracy of the resolution". */
static const struct {
  const char *name;
  double h_band;
} RESOLUTIONS[] = {{"coarse", 0.6}, {"standard", 0.5}, {"fine", 0.4}};
#define NRES ((int)(sizeof RESOLUTIONS / sizeof RESOLUTIONS[0]))

/* The name of a named h_band, NULL for any other. */
static const char *resolution_name(double h_band) {
  for (int i = 0; i < NRES; i++)
    if (h_band == RESOLUTIONS[i].h_band) return RESOLUTIONS[i].name;
  return NULL;
}

/* The two keys of one setting stay in step, whichever comes last wins: a
 * resolution's name sets h_band, and the name always follows h_band
 * (custom for a value without one); custom itself leaves h_band as it is
 * (the stored problem text writes it with its h_band, and reads back to the
 * same run; a custom with a named h_band is refused by validate_setup). */
static void couple_resolution(ves_config *cfg, size_t offset) {
  if (offset == OFF(resolution)) {
    if (!strcasecmp(cfg->resolution, "custom")) {
      snprintf(cfg->resolution, sizeof cfg->resolution, "custom");
      return;
    }
    for (int i = 0; i < NRES; i++)
      if (!strcasecmp(cfg->resolution, RESOLUTIONS[i].name)) cfg->h_band = RESOLUTIONS[i].h_band;
  } else if (offset != OFF(h_band)) {
    return;
  }
  const char *name = resolution_name(cfg->h_band);
  snprintf(cfg->resolution, sizeof cfg->resolution, "%s", name ? name : "custom");
}

/* Parse text into the field of spec k; 0 on success, -1 with a reason. */
static int set_value(ves_config *cfg, const key_spec *k, const char *text, const char **why) {
  char *end;
  void *field = (char *)cfg + k->offset;
  while (*text == ' ' || *text == '\t') text++;
  if (k->type == KEY_STRING) {
    size_t len = strlen(text);
    if (len == 0 || len >= VES_CONFIG_STR) return *why = "empty or too long", -1;
    const char *c = k->choice;
    int ok = c == NULL; /* free text when no choices are listed */
    while (c && *c) {   /* one of the '|'-separated choices */
      size_t l = strcspn(c, "|");
      if (l == len && !strncasecmp(c, text, l)) ok = 1;
      c += l + (c[l] == '|');
    }
    if (!ok) return *why = "not one of the allowed values", -1;
    memcpy(field, text, len + 1);
    couple_resolution(cfg, k->offset);
    return 0;
  }
  errno = 0;
  double v = strtod(text, &end);
  while (*end == ' ' || *end == '\t') end++;
  if (end == text || *end || errno || !isfinite(v)) return *why = "not a number", -1;
  if (k->type == KEY_INT && v != floor(v)) return *why = "not an integer", -1;
  if (v < k->min || v > k->max) return *why = "out of range", -1;
  if (k->type == KEY_INT)
    *(int *)field = (int)v;
  else
    *(double *)field = v;
  couple_resolution(cfg, k->offset);
  return 0;
}

static const key_spec *find_key(const char *section, const char *key) {
  for (int i = 0; i < NKEYS; i++)
    if (!strcasecmp(KEYS[i].section, section) && !strcasecmp(KEYS[i].key, key)) return &KEYS[i];
  return NULL;
}

/* 1 + the index of the section's first key in KEYS, 0 for an unknown one. */
static int known_section(const char *section) {
  for (int i = 0; i < NKEYS; i++)
    if (!strcasecmp(KEYS[i].section, section)) return i + 1;
  return 0;
}

void ves_config_default(ves_config *cfg) {
  memset(cfg, 0, sizeof *cfg);
  for (int i = 0; i < NKEYS; i++) {
    const char *why;
    (void)set_value(cfg, &KEYS[i], KEYS[i].def, &why); /* defaults are valid by construction */
  }
}

static ves_status range_msg(char *err, size_t errlen, const char *src, const key_spec *k,
                            const char *val, const char *why) {
  if (k->type == KEY_STRING)
    ves_error_say(err, errlen, "%s: [%s] %s = '%s': %s (allowed: %s)", src, k->section, k->key, val,
                  why, k->choice);
  else if (k->min == k->max) /* a unit: one value */
    ves_error_say(err, errlen, "%s: [%s] %s = '%s': %s: %s, so %g only", src, k->section, k->key,
                  val, why, k->doc, k->min);
  else
    ves_error_say(err, errlen, "%s: [%s] %s = '%s': %s (allowed: %g to %g)", src, k->section,
                  k->key, val, why, k->min, k->max);
  return VES_ERR_CONFIG;
}

/* The largest problem file read (a problem file is a few KiB; anything
 * larger is not one). */
#define INI_MAX_BYTES (1 << 20)

/* Lower-case copy of s[0, n) into out (INI names are case-insensitive, as
 * in most INI readers); 0 when it does not fit. */
static int ini_name(char *out, size_t len, const char *s, size_t n) {
  if (n == 0 || n >= len) return 0;
  for (size_t i = 0; i < n; i++) out[i] = (char)tolower((unsigned char)s[i]);
  out[n] = 0;
  return 1;
}

/* s[0, *n) without leading and trailing blanks. */
static const char *ini_trim(const char *s, size_t *n) {
  while (*n && isspace((unsigned char)*s)) s++, (*n)--;
  while (*n && isspace((unsigned char)s[*n - 1])) (*n)--;
  return s;
}

/* The sections and keys a scan has met, with their lines (key "" for a
 * section): a repeated one is refused. */
typedef struct {
  struct ini_seen {
    char sec[64], key[64];
    int line;
  } * at;
  size_t n, cap;
} ini_seen_list;

/* The line where sec (key "" for the section itself) was met, else 0 after
 * recording it at `line`; -1 when out of memory. */
static int ini_seen(ini_seen_list *l, const char *sec, const char *key, int line) {
  for (size_t i = 0; i < l->n; i++)
    if (!strcmp(l->at[i].sec, sec) && !strcmp(l->at[i].key, key)) return l->at[i].line;
  if (l->n == l->cap) {
    size_t cap = l->cap ? 2 * l->cap : 64;
    struct ini_seen *p = realloc(l->at, cap * sizeof *p);
    if (!p) return -1;
    l->at = p, l->cap = cap;
  }
  snprintf(l->at[l->n].sec, sizeof l->at[l->n].sec, "%s", sec);
  snprintf(l->at[l->n].key, sizeof l->at[l->n].key, "%s", key);
  l->at[l->n++].line = line;
  return 0;
}

/* The section header t[n] (starting with '[') at line `line` of file name:
 * its name into sec[seclen], checked not to be given before, then handed
 * to fn. */
static ves_status ini_section(const char *t, size_t n, const char *name, int line, char *sec,
                              size_t seclen, ini_seen_list *seen, ves_ini_item_fn fn, void *ctx,
                              char *err, size_t errlen) {
  /* a comment after the header ("[geometry] ; note") is dropped, as after a value */
  const char *close = memchr(t, ']', n);
  if (close) {
    size_t rest = n - (size_t)(close + 1 - t);
    const char *r = ini_trim(close + 1, &rest);
    if (rest && r[0] != ';' && r[0] != '#') {
      ves_error_say(err, errlen,
                    "%s: line %d: '%.*s': text after the section header's ']' (a comment "
                    "starts with ';' or '#')",
                    name, line, (int)(n > 60 ? 60 : n), t);
      return VES_ERR_CONFIG;
    }
    n = (size_t)(close + 1 - t);
  }
  if (t[n - 1] != ']') {
    ves_error_say(err, errlen, "%s: line %d: '%.*s': a section header needs a closing ']'", name,
                  line, (int)(n > 60 ? 60 : n), t);
    return VES_ERR_CONFIG;
  }
  size_t m = n - 2;
  const char *sn = ini_trim(t + 1, &m);
  if (!ini_name(sec, seclen, sn, m)) {
    ves_error_say(err, errlen, "%s: line %d: '%.*s': not a section name", name, line,
                  (int)(n > 60 ? 60 : n), t);
    return VES_ERR_CONFIG;
  }
  const int first = ini_seen(seen, sec, "", line);
  if (first < 0) return VES_ERR_ALLOC;
  if (first) {
    ves_error_say(err, errlen, "%s: line %d: [%s]: duplicate section (first at line %d)", name,
                  line, sec, first);
    return VES_ERR_CONFIG;
  }
  return fn(ctx, name, line, sec, NULL, NULL, 0, err, errlen);
}

/* The scan of ves_ini_scan over its own list of what it has met. One pass
 * over the lines: the state (section, line number) is the loop's, hence
 * one function. */
static ves_status ini_scan(const char *text, size_t len, const char *name, ves_ini_item_fn fn,
                           void *ctx, ini_seen_list *seen, char *err, size_t errlen) {
  char sec[64] = ""; /* the current section ("" before the first) */
  int line = 0;
  if (len >= 3 && !memcmp(text, "\xef\xbb\xbf", 3)) text += 3, len -= 3; /* UTF-8 BOM */
  if (memchr(text, 0, len)) {
    size_t at = (const char *)memchr(text, 0, len) - text;
    int l = 1;
    for (size_t i = 0; i < at; i++) l += text[i] == '\n';
    ves_error_say(err, errlen, "%s: line %d: a NUL byte: not a text file", name, l);
    return VES_ERR_CONFIG;
  }
  for (size_t pos = 0; pos < len;) {
    const char *ln = text + pos, *nl = memchr(ln, '\n', len - pos);
    size_t n = nl ? (size_t)(nl - ln) : len - pos;
    pos += n + (nl ? 1 : 0);
    line++;
    const char *t = ini_trim(ln, &n);
    if (n == 0 || t[0] == ';' || t[0] == '#') continue;
    if (t[0] == '[') { /* a section header */
      const ves_status st =
          ini_section(t, n, name, line, sec, sizeof sec, seen, fn, ctx, err, errlen);
      if (st != VES_OK) return st;
      continue;
    }
    const char *eq = memchr(t, '=', n);
    if (!eq) {
      ves_error_say(err, errlen, "%s: line %d: '%.*s%s': expected key = value", name, line,
                    (int)(n > 60 ? 60 : n), t, n > 60 ? "..." : "");
      return VES_ERR_CONFIG;
    }
    size_t kn = (size_t)(eq - t), vn = n - kn - 1;
    const char *kt = ini_trim(t, &kn), *v = ini_trim(eq + 1, &vn);
    char key[64];
    if (!ini_name(key, sizeof key, kt, kn)) {
      ves_error_say(err, errlen, "%s: line %d: '%.*s': not a key name", name, line,
                    (int)(n > 60 ? 60 : n), t);
      return VES_ERR_CONFIG;
    }
    if (!sec[0]) {
      ves_error_say(err, errlen, "%s: line %d: %s: key outside a section", name, line, key);
      return VES_ERR_CONFIG;
    }
    if (vn >= 2 && (v[0] == '"' || v[0] == '\'') && v[vn - 1] == v[0]) {
      v++, vn -= 2; /* quoted: verbatim */
    } else {
      size_t c = 0; /* an inline comment (searched within the line only: the text of a
                       file is not NUL-terminated at the line's end) */
      while (c < vn && v[c] != ';' && v[c] != '#') c++;
      vn = c;
      v = ini_trim(v, &vn);
    }
    const int first = ini_seen(seen, sec, key, line);
    if (first < 0) return VES_ERR_ALLOC;
    if (first) {
      ves_error_say(err, errlen, "%s: line %d: [%s] %s: duplicate key (first at line %d)", name,
                    line, sec, key, first);
      return VES_ERR_CONFIG;
    }
    const ves_status st = fn(ctx, name, line, sec, key, v, vn, err, errlen);
    if (st != VES_OK) return st;
  }
  return VES_OK;
}

ves_status ves_ini_scan(const char *text, size_t len, const char *name, ves_ini_item_fn fn,
                        void *ctx, char *err, size_t errlen) {
  VES_CHECK(text && name && fn, VES_ERR_ARG);
  ini_seen_list seen = {NULL, 0, 0};
  const ves_status st = ini_scan(text, len, name, fn, ctx, &seen, err, errlen);
  free(seen.at);
  return st;
}

/* A section or key of a problem file, checked against the table of keys
 * and set in the configuration ctx. */
static ves_status config_item(void *ctx, const char *name, int line, const char *sec,
                              const char *key, const char *v, size_t vn, char *err, size_t errlen) {
  ves_config *cfg = ctx;
  if (!key) {
    if (known_section(sec)) return VES_OK;
    ves_error_say(err, errlen, "%s: line %d: [%s]: unknown section", name, line, sec);
    return VES_ERR_CONFIG;
  }
  const key_spec *k = find_key(sec, key);
  if (!k) {
    ves_error_say(err, errlen, "%s: line %d: [%s] %s: unknown key", name, line, sec, key);
    return VES_ERR_CONFIG;
  }
  char val[VES_CONFIG_STR];
  if (vn >= sizeof val) {
    ves_error_say(err, errlen, "%s: line %d: [%s] %s: value longer than %d characters", name, line,
                  sec, key, (int)sizeof val - 1);
    return VES_ERR_CONFIG;
  }
  memcpy(val, v, vn);
  val[vn] = 0;
  const char *why;
  if (set_value(cfg, k, val, &why)) {
    char where[600];
    snprintf(where, sizeof where, "%s: line %d", name, line);
    return range_msg(err, errlen, where, k, val, vn ? why : "no value");
  }
  return VES_OK;
}

/* Parse the text of a problem file over cfg; messages name `name` and the
 * line (the format: ves_ini_scan). */
static ves_status parse_ini(const char *text, size_t len, const char *name, ves_config *cfg,
                            char *err, size_t errlen) {
  return ves_ini_scan(text, len, name, config_item, cfg, err, errlen);
}

ves_status ves_ini_load(const char *path, const char *name, const char *what, ves_ini_item_fn fn,
                        void *ctx, char *err, size_t errlen) {
  VES_CHECK(path && name && what && fn, VES_ERR_ARG);
  FILE *f = fopen(path, "rb");
  if (!f) {
    ves_error_say(err, errlen, "%s: cannot open: %s", name, strerror(errno));
    return VES_ERR_IO;
  }
  struct stat sb;
  memset(&sb, 0, sizeof sb);
  if (fstat(fileno(f), &sb) != 0 || !S_ISREG(sb.st_mode)) {
    ves_error_say(err, errlen, "%s: %s%s", name,
                  S_ISDIR(sb.st_mode) ? "is a folder, not a " : "not a regular file",
                  S_ISDIR(sb.st_mode) ? what : "");
    fclose(f);
    return VES_ERR_IO;
  }
  if (sb.st_size > INI_MAX_BYTES) {
    ves_error_say(err, errlen, "%s: %lld bytes: too large for a %s (at most %d)", name,
                  (long long)sb.st_size, what, INI_MAX_BYTES);
    fclose(f);
    return VES_ERR_CONFIG;
  }
  char *text = malloc((size_t)sb.st_size + 1);
  size_t len = text ? fread(text, 1, (size_t)sb.st_size, f) : 0;
  int bad = !text || ferror(f);
  fclose(f);
  if (bad) {
    free(text);
    ves_error_say(err, errlen, "%s: cannot read: %s", name,
                  text ? strerror(errno) : "out of memory");
    return text ? VES_ERR_IO : VES_ERR_ALLOC;
  }
  text[len] = 0;
  ves_status s = ves_ini_scan(text, len, name, fn, ctx, err, errlen);
  free(text);
  return s;
}

/* Read the problem file `path` over cfg: a regular file of at most
 * INI_MAX_BYTES (a folder or a device is refused); messages name `name`. */
static ves_status load_ini(const char *path, const char *name, ves_config *cfg, char *err,
                           size_t errlen) {
  return ves_ini_load(path, name, "problem file", config_item, cfg, err, errlen);
}

/* Apply the overrides "section.key=value". */
static ves_status apply_overrides(int nset, const char *const *set, ves_config *cfg, char *err,
                                  size_t errlen) {
  for (int i = 0; i < nset; i++) {
    char sec[64], key[64];
    const char *dot = strchr(set[i], '.'), *eq = strchr(set[i], '=');
    if (!dot || !eq || dot > eq || dot - set[i] >= 64 || eq - dot - 1 >= 64 || eq == dot + 1) {
      ves_error_say(err, errlen, "--set '%s': expected section.key=value", set[i]);
      return VES_ERR_CONFIG;
    }
    memcpy(sec, set[i], (size_t)(dot - set[i]));
    sec[dot - set[i]] = 0;
    memcpy(key, dot + 1, (size_t)(eq - dot - 1));
    key[eq - dot - 1] = 0;
    const key_spec *k = find_key(sec, key);
    const char *why;
    if (!k) {
      ves_error_say(err, errlen, "--set: [%s] %s: unknown key", sec, key);
      return VES_ERR_CONFIG;
    }
    if (set_value(cfg, k, eq + 1, &why)) return range_msg(err, errlen, "--set", k, eq + 1, why);
  }
  return VES_OK;
}

ves_status ves_config_load(const char *path, int nset, const char *const *set, ves_config *cfg,
                           char *err, size_t errlen) {
  VES_CHECK(cfg && (nset == 0 || set), VES_ERR_ARG);
  ves_config_default(cfg);
  if (path) {
    snprintf(cfg->source, sizeof cfg->source, "%s", path);
    VES_CALL(load_ini(path, path, cfg, err, errlen));
  }
  VES_CALL(apply_overrides(nset, set, cfg, err, errlen));
  return ves_config_validate(cfg, err, errlen);
}

ves_status ves_config_set(ves_config *cfg, int nset, const char *const *set, char *err,
                          size_t errlen) {
  VES_CHECK(cfg && (nset == 0 || set), VES_ERR_ARG);
  VES_CALL(apply_overrides(nset, set, cfg, err, errlen));
  return ves_config_validate(cfg, err, errlen);
}

ves_status ves_config_load_text(const char *text, const char *name, ves_config *cfg, char *err,
                                size_t errlen) {
  VES_CHECK(text && name && cfg, VES_ERR_ARG);
  ves_config_default(cfg);
  snprintf(cfg->source, sizeof cfg->source, "%s", name);
  ves_status s = parse_ini(text, strlen(text), name, cfg, err, errlen);
  if (s != VES_OK) return s;
  return ves_config_validate(cfg, err, errlen);
}

/* A list of independent checks, one a key or a pair of keys, each with its
 * message: long, but read line by line. */
/* The checks of the shape, the time steps and the box (src names the file). */
static ves_status validate_setup(const ves_config *cfg, const char *src, char *err, size_t errlen) {
  if (!strcasecmp(cfg->shape_type, "curve") && !strcmp(cfg->points, "none")) {
    ves_error_say(err, errlen, "%s: [shape] points: a curve needs a points file", src);
    return VES_ERR_CONFIG;
  }
  if (cfg->dt_initial > cfg->dt_max || cfg->dt_min > cfg->dt_initial) {
    ves_error_say(err, errlen,
                  "%s: [time] dt_initial = %g: must lie in [dt_min, dt_max] = [%g, %g]", src,
                  cfg->dt_initial, cfg->dt_min, cfg->dt_max);
    return VES_ERR_CONFIG;
  }
  if (cfg->order == 2 && cfg->growth_max > VES_BDF2_RATIO_MAX) {
    ves_error_say(err, errlen,
                  "%s: [time] growth_max = %g: order = 2 needs at most %g (BDF2 is zero-stable "
                  "for step ratios below 1 + sqrt 2)",
                  src, cfg->growth_max, VES_BDF2_RATIO_MAX);
    return VES_ERR_CONFIG;
  }
  if (cfg->order == 2 && !strcasecmp(cfg->backend, "euler")) {
    ves_error_say(err, errlen,
                  "%s: [time] order = 2: an implicit scheme; solver.backend = euler takes "
                  "explicit steps (order = 1: --set time.order=1)",
                  src);
    return VES_ERR_CONFIG;
  }
  if (cfg->epsilon * 10 > fmin(cfg->box_r, cfg->box_z)) {
    ves_error_say(err, errlen,
                  "%s: [geometry] epsilon = %g: too large for the box (needs 10 eps <= %g)", src,
                  cfg->epsilon, fmin(cfg->box_r, cfg->box_z));
    return VES_ERR_CONFIG;
  }
  /* spheres: the radius is known here; every shape is checked exactly
   * against the box (with its band) when the setup builds it */
  double size = cfg->radius * (1 + fabs(cfg->delta));
  if (!strcasecmp(cfg->shape_type, "sphere") &&
      size + (cfg->band + 1) * cfg->epsilon >= fmin(cfg->box_r, cfg->box_z)) {
    ves_error_say(err, errlen,
                  "%s: [geometry] box_r/box_z = %g/%g: the sphere (radius %g) and its band of "
                  "(band + 1) eps = %g do not fit in the box",
                  src, cfg->box_r, cfg->box_z, size, (cfg->band + 1) * cfg->epsilon);
    return VES_ERR_CONFIG;
  }
  if (!strcmp(cfg->resolution, "custom") && resolution_name(cfg->h_band)) {
    ves_error_say(err, errlen,
                  "%s: [geometry] resolution = custom: names an h_band given by value, and h_band "
                  "= %g is '%s' (set geometry.h_band, or resolution to a name)",
                  src, cfg->h_band, resolution_name(cfg->h_band));
    return VES_ERR_CONFIG;
  }
  if (cfg->h_far < cfg->h_band * cfg->epsilon) {
    ves_error_say(err, errlen, "%s: [geometry] h_far = %g: smaller than the band spacing %g", src,
                  cfg->h_far, cfg->h_band * cfg->epsilon);
    return VES_ERR_CONFIG;
  }
  return VES_OK;
}

/* Protocols that would silently do nothing. */
static ves_status validate_protocol(const ves_config *cfg, const char *src, char *err,
                                    size_t errlen) {
  if (cfg->volume_rate != 0 && !cfg->volume) {
    ves_error_say(err, errlen,
                  "%s: [protocol] volume_rate = %g: a volume ramp needs [constraints] volume = 1",
                  src, cfg->volume_rate);
    return VES_ERR_CONFIG;
  }
  if ((cfg->volume_rate < 0 && cfg->volume_final >= 1) ||
      (cfg->volume_rate > 0 && cfg->volume_final <= 1)) {
    ves_error_say(err, errlen,
                  "%s: [protocol] volume_final = %g: must be %s 1 for volume_rate = %g", src,
                  cfg->volume_final, cfg->volume_rate < 0 ? "below" : "above", cfg->volume_rate);
    return VES_ERR_CONFIG;
  }
  if (cfg->c0_time < 0 && cfg->c0_after != 0) {
    ves_error_say(err, errlen, "%s: [protocol] c0_after = %g: has no effect without c0_time >= 0",
                  src, cfg->c0_after);
    return VES_ERR_CONFIG;
  }
  if (cfg->c0_until >= 0 && !(cfg->c0_time >= 0 && cfg->c0_until > cfg->c0_time)) {
    ves_error_say(err, errlen,
                  "%s: [protocol] c0_until = %g: needs c0_time >= 0 before it (c0_time = %g)", src,
                  cfg->c0_until, cfg->c0_time);
    return VES_ERR_CONFIG;
  }
  if (cfg->c0_ramp_start < 0 && (cfg->c0_ramp_end != -1 || cfg->c0_ramp_to != 0)) {
    ves_error_say(err, errlen, "%s: [protocol] %s: has no effect without c0_ramp_start >= 0", src,
                  cfg->c0_ramp_end != -1 ? "c0_ramp_end" : "c0_ramp_to");
    return VES_ERR_CONFIG;
  }
  if (cfg->c0_ramp_start >= 0) {
    const char *why = cfg->c0_ramp_end <= cfg->c0_ramp_start ? "c0_ramp_end must come after it"
                      : cfg->c0_time >= 0                    ? "a ramp excludes c0_time"
                      : cfg->c0_ramp_to == cfg->c0
                          ? "c0_ramp_to equals [material] c0: nothing to do"
                      : cfg->c0_ramp_start >= cfg->t_end ? "not before [time] t_end"
                                                         : NULL;
    if (why) {
      ves_error_say(err, errlen, "%s: [protocol] c0_ramp_start = %g: %s", src, cfg->c0_ramp_start,
                    why);
      return VES_ERR_CONFIG;
    }
  }
  return VES_OK;
}

/* The thresholds of resets and remeshings. */
static ves_status validate_resets(const ves_config *cfg, const char *src, char *err,
                                  size_t errlen) {
  if (cfg->reconnect_cond_max > 0 && cfg->reconnect_cond_max <= 1) {
    ves_error_say(err, errlen,
                  "%s: [reconnect] cond_max = %g: must be 0 (off) or above 1 (cond F >= 1)", src,
                  cfg->reconnect_cond_max);
    return VES_ERR_CONFIG;
  }
  if (cfg->reconnect_det_min >= 1) {
    ves_error_say(err, errlen, "%s: [reconnect] det_min = %g: must be below 1 (0: off)", src,
                  cfg->reconnect_det_min);
    return VES_ERR_CONFIG;
  }
  if (cfg->remesh_cond_max > 0 && cfg->remesh_cond_max <= 1) {
    ves_error_say(err, errlen,
                  "%s: [remesh] cond_max = %g: must be 0 (off) or above 1 (cond F >= 1)", src,
                  cfg->remesh_cond_max);
    return VES_ERR_CONFIG;
  }
  if (cfg->remesh_det_min >= 1) {
    ves_error_say(err, errlen, "%s: [remesh] det_min = %g: must be below 1 (0: off)", src,
                  cfg->remesh_det_min);
    return VES_ERR_CONFIG;
  }
  return VES_OK;
}

ves_status ves_config_validate(const ves_config *cfg, char *err, size_t errlen) {
  const char *src = cfg->source[0] ? cfg->source : "(defaults)";
  ves_status st = validate_setup(cfg, src, err, errlen);
  if (st == VES_OK) st = validate_protocol(cfg, src, err, errlen);
  if (st == VES_OK) st = validate_resets(cfg, src, err, errlen);
  if (st != VES_OK) return st;
  if (cfg->c0_time > cfg->t_end) {
    ves_error_say(err, errlen, "%s: [protocol] c0_time = %g: after [time] t_end = %g", src,
                  cfg->c0_time, cfg->t_end);
    return VES_ERR_CONFIG;
  }
  return VES_OK;
}

int ves_config_count(void) { return NKEYS; }

void ves_config_entry_get(const ves_config *cfg, int i, ves_config_entry *e) {
  const key_spec *k = &KEYS[i];
  const void *field = (const char *)cfg + k->offset;
  memset(e, 0, sizeof *e);
  e->section = k->section, e->key = k->key;
  e->type = k->type == KEY_DOUBLE ? VES_KEY_REAL : k->type == KEY_INT ? VES_KEY_INT : VES_KEY_TEXT;
  if (k->type == KEY_DOUBLE)
    e->real = *(const double *)field;
  else if (k->type == KEY_INT)
    e->integer = *(const int *)field;
  else
    e->text = field;
}

void ves_config_format_real(double v, char *buf, size_t len) {
  for (int digits = 15; digits <= 17; digits++) { /* 17 always reads back exactly */
    snprintf(buf, len, "%.*g", digits, v);
    if (strtod(buf, NULL) == v) return;
  }
}

ves_status ves_config_to_text(const ves_config *cfg, char **text) {
  VES_CHECK(cfg && text, VES_ERR_ARG);
  *text = NULL;
  size_t len = 0;
  FILE *f = open_memstream(text, &len);
  if (!f) return VES_ERR_ALLOC;
  fprintf(f, "; every key of the run (reals in their shortest exact form)\n");
  const char *section = "";
  for (int i = 0; i < NKEYS; i++) {
    ves_config_entry e;
    ves_config_entry_get(cfg, i, &e);
    if (strcmp(e.section, section)) fprintf(f, "%s[%s]\n", i ? "\n" : "", e.section);
    section = e.section;
    char num[32];
    ves_config_format_real(e.real, num, sizeof num);
    if (e.type == VES_KEY_REAL)
      fprintf(f, "%s = %s\n", e.key, num);
    else if (e.type == VES_KEY_INT)
      fprintf(f, "%s = %d\n", e.key, e.integer);
    else
      fprintf(f, "%s = \"%s\"\n", e.key, e.text); /* quoted: ';' and '#' stay text */
  }
  if (fclose(f) != 0 || !*text) {
    free(*text);
    *text = NULL;
    return VES_ERR_ALLOC;
  }
  return VES_OK;
}

/* Print text with '|' escaped for a Markdown table cell. */
static void cell(FILE *f, const char *t) {
  fputs("| ", f);
  for (; *t; t++) {
    if (*t == '|') fputc('\\', f);
    fputc(*t, f);
  }
  fputc(' ', f);
}

#define KEYS_HEAD                                                                                  \
  "| section | key | type | default | allowed | meaning |\n|---|---|---|---|---|---|\n"

/* The table row of key k. */
static void print_key_row(FILE *f, const key_spec *k) {
  char range[96];
  if (k->type == KEY_STRING)
    snprintf(range, sizeof range, "%s", k->choice ? k->choice : "text");
  else if (k->min == k->max)
    snprintf(range, sizeof range, "%.10g", k->min);
  else
    snprintf(range, sizeof range, "%.10g to %.10g", k->min, k->max);
  cell(f, k->section), cell(f, k->key);
  cell(f, k->type == KEY_DOUBLE ? "real" : k->type == KEY_INT ? "integer" : "text");
  cell(f, k->def), cell(f, range), cell(f, k->doc);
  fputs("|\n", f);
}

void ves_config_print_keys(FILE *f) {
  fputs(KEYS_HEAD, f);
  for (int i = 0; i < NKEYS; i++) print_key_row(f, &KEYS[i]);
}

/* The edit distance of a and b (insertions, deletions, substitutions),
 * case-insensitive; names are short (a row of 64 is enough: longer names
 * count their tail as differing). */
static int edit_distance(const char *a, const char *b) {
  int row[65], la = (int)strlen(a), lb = (int)strlen(b);
  if (lb > 64) lb = 64;
  for (int j = 0; j <= lb; j++) row[j] = j;
  for (int i = 1; i <= la; i++) {
    int diag = row[0];
    row[0] = i;
    for (int j = 1; j <= lb; j++) {
      const int up = row[j];
      const int same = tolower((unsigned char)a[i - 1]) == tolower((unsigned char)b[j - 1]);
      int v = diag + !same;
      if (up + 1 < v) v = up + 1;
      if (row[j - 1] + 1 < v) v = row[j - 1] + 1;
      row[j] = v, diag = up;
    }
  }
  return row[lb];
}

int ves_config_print_key(FILE *f, const char *name, char *near, size_t nearlen) {
  const char *dot = strchr(name, '.');
  int found = 0, best = INT_MAX;
  if (near && nearlen) near[0] = 0;
  for (int i = 0; i < NKEYS; i++) {
    const key_spec *k = &KEYS[i];
    const int match = dot ? (size_t)(dot - name) == strlen(k->section) &&
                                !strncmp(name, k->section, (size_t)(dot - name)) &&
                                !strcmp(dot + 1, k->key)
                          : !strcmp(name, k->key);
    if (match) {
      if (!found) fputs(KEYS_HEAD, f);
      print_key_row(f, k), found++;
      continue;
    }
    char full[128];
    snprintf(full, sizeof full, "%s.%s", k->section, k->key);
    const int d = edit_distance(name, dot ? full : k->key);
    if (d < best && near && nearlen) best = d, snprintf(near, nearlen, "%s", full);
  }
  return found;
}

/* Orientation of the triangle a, b, c: > 0 counter-clockwise. */
static double orient(const double *a, const double *b, const double *c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Whether the closed segments [a, b] and [c, d] share a point. */
static int segments_meet(const double *a, const double *b, const double *c, const double *d) {
  const double o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a),
               o4 = orient(c, d, b);
  if (((o1 > 0 && o2 < 0) || (o1 < 0 && o2 > 0)) && ((o3 > 0 && o4 < 0) || (o3 < 0 && o4 > 0)))
    return 1; /* a proper crossing */
  /* touching or collinear overlap: an endpoint on the other segment */
  const double *e[4][3] = {{a, b, c}, {a, b, d}, {c, d, a}, {c, d, b}};
  const double o[4] = {o1, o2, o3, o4};
  for (int i = 0; i < 4; i++)
    if (o[i] == 0 && fmin(e[i][0][0], e[i][1][0]) <= e[i][2][0] &&
        e[i][2][0] <= fmax(e[i][0][0], e[i][1][0]) && fmin(e[i][0][1], e[i][1][1]) <= e[i][2][1] &&
        e[i][2][1] <= fmax(e[i][0][1], e[i][1][1]))
      return 1;
  return 0;
}

/* The cells [c0, c1] (per axis) a segment's bounding box covers in the
 * grid of cell size h from (x0, y0), clamped to the g[0] x g[1] cells. */
static void seg_cells(const double *a, const double *b, double x0, double y0, double h,
                      const long *g, long *c) {
  const double lo[2] = {fmin(a[0], b[0]), fmin(a[1], b[1])};
  const double hi[2] = {fmax(a[0], b[0]), fmax(a[1], b[1])};
  const double o[2] = {x0, y0};
  for (int d = 0; d < 2; d++) {
    long l = (long)floor((lo[d] - o[d]) / h), u = (long)floor((hi[d] - o[d]) / h);
    c[2 * d] = l < 0 ? 0 : l >= g[d] ? g[d] - 1 : l;
    c[2 * d + 1] = u < 0 ? 0 : u >= g[d] ? g[d] - 1 : u;
  }
}

/* The first pair of non-adjacent segments (i < j, in that order; segment
 * i joins points i and i + 1) of the polygon p[n] that meet, or -1, -1.
 * Each segment is bucketed into the cells of a uniform grid its bounding
 * box covers (cell size about the mean segment length, enlarged while the
 * buckets would hold more than 16 entries per segment); two segments that
 * meet share the cell of a common point (floor is monotone), so only pairs
 * within a cell are tested: O(n) for a curve of even spacing, instead of
 * the n^2/2 pairs (a 200,001-point curve: minutes; docs/results.md,
 * "Reliability and fuzzing"). */
static ves_status first_crossing(int n, const double *p, int *pi, int *pj) {
  *pi = *pj = -1;
  const long ns = n - 1;
  if (ns < 3) return VES_OK;
  double x0 = p[0], x1 = p[0], y0 = p[1], y1 = p[1], len = 0;
  for (int i = 0; i < n; i++) {
    x0 = fmin(x0, p[2 * i]), x1 = fmax(x1, p[2 * i]);
    y0 = fmin(y0, p[2 * i + 1]), y1 = fmax(y1, p[2 * i + 1]);
    if (i) len += hypot(p[2 * i] - p[2 * i - 2], p[2 * i + 1] - p[2 * i - 1]);
  }
  const double span = fmax(x1 - x0, y1 - y0);
  double h = fmax(len / (double)ns, span / 4096.0);
  if (!(h > 0) || !isfinite(h)) h = 1;
  long g[2], c[4], total = 0;
  for (;;) { /* the grid: cells about the mean segment, at most 16 entries per segment */
    g[0] = (long)floor((x1 - x0) / h) + 1, g[1] = (long)floor((y1 - y0) / h) + 1;
    total = 0;
    for (long s = 0; s < ns && total <= 16 * ns; s++) {
      seg_cells(p + 2 * s, p + 2 * s + 2, x0, y0, h, g, c);
      total += (c[1] - c[0] + 1) * (c[3] - c[2] + 1);
    }
    if (total <= 16 * ns && g[0] * g[1] <= 16 * ns) break;
    h *= 2;
  }
  const long ncell = g[0] * g[1];
  long *start = calloc((size_t)ncell + 1, sizeof *start);
  int *seg = malloc((size_t)total * sizeof *seg);
  if (!start || !seg) {
    free(start), free(seg);
    return VES_ERR_ALLOC;
  }
  for (long s = 0; s < ns; s++) { /* counting sort of the (cell, segment) entries */
    seg_cells(p + 2 * s, p + 2 * s + 2, x0, y0, h, g, c);
    for (long cy = c[2]; cy <= c[3]; cy++)
      for (long cx = c[0]; cx <= c[1]; cx++) start[cy * g[0] + cx + 1]++;
  }
  for (long k = 0; k < ncell; k++) start[k + 1] += start[k];
  for (long s = 0; s < ns; s++) { /* in each cell the segments ascending */
    seg_cells(p + 2 * s, p + 2 * s + 2, x0, y0, h, g, c);
    for (long cy = c[2]; cy <= c[3]; cy++)
      for (long cx = c[0]; cx <= c[1]; cx++) seg[start[cy * g[0] + cx]++] = (int)s;
  }
  for (long k = ncell; k > 0; k--) start[k] = start[k - 1];
  start[0] = 0;
  for (long k = 0; k < ncell; k++)
    for (long a = start[k]; a < start[k + 1]; a++)
      for (long b = a + 1; b < start[k + 1]; b++) {
        const int i = seg[a], j = seg[b];
        if (j < i + 2 || (*pi >= 0 && (i > *pi || (i == *pi && j >= *pj)))) continue;
        if (segments_meet(p + 2 * i, p + 2 * i + 2, p + 2 * j, p + 2 * j + 2)) *pi = i, *pj = j;
      }
  free(start), free(seg);
  return VES_OK;
}

/* A generating curve the shape can use: from the north pole (larger Z) to
 * the south pole, on the axis only at its ends, no point repeated, and
 * not crossing or touching itself (the polygon through the points; the
 * spline through them follows it). Names the lines of the points at fault. */
static ves_status check_curve(const char *path, int n, const double *p, const int *lines, char *err,
                              size_t errlen) {
  if (p[1] <= p[2 * n - 1]) {
    ves_error_say(
        err, errlen,
        "%s: the points run from Z = %g (line %d) to Z = %g (line %d): a curve goes from the "
        "north pole (the larger Z) to the south pole; reverse the file's lines",
        path, p[1], lines[0], p[2 * n - 1], lines[n - 1]);
    return VES_ERR_CONFIG;
  }
  for (int i = 1; i < n; i++) {
    if (i < n - 1 && p[2 * i] == 0.0) {
      ves_error_say(
          err, errlen,
          "%s: line %d: R = 0 inside the curve: it meets the axis only at its first and last "
          "points",
          path, lines[i]);
      return VES_ERR_CONFIG;
    }
    if (p[2 * i] == p[2 * i - 2] && p[2 * i + 1] == p[2 * i - 1]) {
      ves_error_say(err, errlen, "%s: line %d: repeats the point of line %d", path, lines[i],
                    lines[i - 1]);
      return VES_ERR_CONFIG;
    }
  }
  int ci = -1, cj = -1;
  VES_CALL(first_crossing(n, p, &ci, &cj));
  if (ci >= 0) {
    ves_error_say(
        err, errlen,
        "%s: the curve crosses itself: the segment of lines %d-%d meets that of lines %d-%d", path,
        lines[ci], lines[ci + 1], lines[cj], lines[cj + 1]);
    return VES_ERR_CONFIG;
  }
  return VES_OK;
}

ves_status ves_config_read_points(const ves_config *cfg, int *n, double **pts, char *err,
                                  size_t errlen) {
  VES_CHECK(cfg && n && pts, VES_ERR_ARG);
  *n = 0, *pts = NULL;
  char path[2 * VES_CONFIG_STR + 8];
  const char *slash = strrchr(cfg->source, '/');
  if (cfg->points[0] != '/' && slash) /* relative to the problem file's folder */
    snprintf(path, sizeof path, "%.*s/%s", (int)(slash - cfg->source), cfg->source, cfg->points);
  else
    snprintf(path, sizeof path, "%s", cfg->points);
  FILE *f = fopen(path, "r");
  if (!f) {
    ves_error_say(err, errlen, "%s: [shape] points = %s: cannot open %s: %s", cfg->source,
                  cfg->points, path, strerror(errno));
    return VES_ERR_IO;
  }
  struct stat sb;
  if (fstat(fileno(f), &sb) == 0 && S_ISDIR(sb.st_mode)) { /* fopen opens a folder */
    ves_error_say(err, errlen, "%s: [shape] points = %s: %s is a folder, not a points file",
                  cfg->source, cfg->points, path);
    fclose(f);
    return VES_ERR_CONFIG;
  }
  int cap = 0, cnt = 0, line = 0, *lines = NULL; /* lines[i]: the file line of point i */
  double *p = NULL;
  char *buf = NULL;
  size_t bufcap = 0;
  ssize_t got;
  ves_status st = VES_OK;
  while ((got = getline(&buf, &bufcap, f)) > 0) {
    line++;
    if (memchr(buf, 0, (size_t)got)) {
      ves_error_say(err, errlen, "%s: line %d: holds a NUL byte: not a text file", path, line);
      st = VES_ERR_CONFIG;
      break;
    }
    if ((size_t)got - (buf[got - 1] == '\n') > 510) {
      ves_error_say(err, errlen, "%s: line %d: longer than %d characters", path, line, 510);
      st = VES_ERR_CONFIG;
      break;
    }
    char *s = buf;
    while (*s == ' ' || *s == '\t') s++;
    if (*s == '#' || *s == '\n' || *s == 0) continue;
    double R, Z;
    char extra;
    if (sscanf(s, "%lf %lf %c", &R, &Z, &extra) != 2 || !isfinite(R) || !isfinite(Z) || R < 0) {
      ves_error_say(err, errlen, "%s: line %d: expected two numbers 'R Z' with R >= 0", path, line);
      st = VES_ERR_CONFIG;
      break;
    }
    if (cnt == cap) {
      cap = cap ? 2 * cap : 256;
      double *q = realloc(p, 2 * (size_t)cap * sizeof *q);
      int *ql = realloc(lines, (size_t)cap * sizeof *ql);
      if (q) p = q;
      if (ql) lines = ql;
      if (!q || !ql) {
        st = VES_ERR_ALLOC;
        break;
      }
    }
    p[2 * cnt] = R, p[2 * cnt + 1] = Z, lines[cnt] = line;
    cnt++;
  }
  free(buf);
  fclose(f);
  if (st == VES_OK && (cnt < 4 || p[0] != 0.0 || p[2 * cnt - 2] != 0.0)) {
    ves_error_say(err, errlen, "%s: %d points: need at least 4, the first and the last with R = 0",
                  path, cnt);
    st = VES_ERR_CONFIG;
  }
  if (st == VES_OK) st = check_curve(path, cnt, p, lines, err, errlen);
  free(lines);
  if (st != VES_OK) {
    free(p);
    return st;
  }
  *n = cnt, *pts = p;
  return VES_OK;
}
