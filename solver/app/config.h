/* vesica — problem files: INI (ves_ini_scan) with a fixed, documented set of
 * sections and keys, each typed, with a default, a range and units.
 * Unknown sections or keys, wrong types and out-of-range values are errors
 * with a message naming the file, the key and the reason (the keys:
 * docs/manual.md; docs/design.md, "The program"). */
#ifndef VES_CONFIG_H
#define VES_CONFIG_H

#include <stddef.h>
#include <stdio.h>

#include "ves/status.h"

#define VES_CONFIG_STR 256

/* All parameters of a run. Lengths in R0 = sqrt(A0/4pi), energies in k, times
 * in t* = t k / (mu R0^3). */
typedef struct {
  char source[512]; /* the file it came from */
  /* [geometry] */
  double epsilon;                  /* interface width eps / R0 */
  double box_r, box_z;             /* meridian box [0, box_r] x [-box_z, box_z] */
  double h_band;                   /* node spacing in the band, in units of eps */
  char resolution[VES_CONFIG_STR]; /* h_band's name: coarse | standard | fine (0.6, 0.5, 0.4), or
                                      custom for any other h_band (config.c, couple_resolution) */
  double band;                     /* half-width of the refined band, units of eps */
  double slope;                    /* growth of the spacing away from the band */
  double h_far;                    /* largest spacing */
  double gamma;                    /* LME aspect ratio */
  double support_tol;              /* LME support truncation tol0 */
  double axis_spacings;            /* width of the regular axis strip (spacings) */
  int lloyd_iterations;            /* CVT smoothing iterations */
  int band_layers;                 /* 1: interface-aligned layers in the band */
  int seed;                        /* seed of the node sampling */
  /* the discrete energy */
  char quadrature[VES_CONFIG_STR]; /* rule per triangle (ves_quad_rule_parse) */
  double stabilization;            /* kappa of ves_model_params.stab */
  /* [shape] */
  char shape_type[VES_CONFIG_STR];  /* sphere | spheroid | discocyte | curve */
  char points[VES_CONFIG_STR];      /* curve: points file, relative to the problem file's folder */
  double radius;                    /* sphere radius */
  double reduced_volume;            /* spheroid reduced volume v */
  char orientation[VES_CONFIG_STR]; /* spheroid: oblate | prolate */
  int mode;                         /* radial perturbation 1 + delta P_mode(cos t) */
  double delta;                     /* perturbation amplitude */
  /* [material] */
  double k;            /* bending stiffness (energy unit: 1) */
  double mu;           /* viscosity (unit: 1) */
  double lambda_ratio; /* penalty lambda / mu (>= 10) */
  double c0;           /* spontaneous curvature C0 R0 */
  /* [time] (t* units) */
  double t_end, dt_initial, dt_max, dt_min; /* end, first, largest, smallest step */
  int adaptive;                             /* 1: dt from the energy decrement */
  double dE_target;                         /* target |dE*| per step */
  double growth_max;                        /* largest dt growth factor per step */
  int iter_target;                          /* no dt growth above this many iterations */
  int factor_target;                        /* ... or factorizations (0: off) */
  int factor_shrink;                        /* above this many factorizations: dt/2 (0: off) */
  int predictor;                            /* 1: steps start from the extrapolation */
  int order;                                /* 1: backward Euler, 2: BDF2 */
  int retry_memory;                         /* accepted steps a rejected dt is remembered */
  double retry_cap;                         /* dt <= retry_cap x that dt meanwhile */
  double event_cut;                         /* next dt x this after a reset or remeshing */
  /* [constraints] */
  int area, volume; /* 1: hold A = A0, V = V_target */
  /* [protocol] */
  double volume_rate;   /* dV/dt / V0 (1/t*), < 0 deflates */
  double volume_final;  /* V/V0 where the ramp stops */
  double c0_time;       /* time of a step change of C0 (< 0: none) */
  double c0_after;      /* C0 R0 after it */
  double c0_until;      /* time C0 returns to c0 (< 0: never) */
  double c0_ramp_start; /* a C0 ramp from c0 at this time (< 0: none) ... */
  double c0_ramp_end;   /* ... to c0_ramp_to at this time, then held */
  double c0_ramp_to;    /* C0 R0 at the ramp's end */
  /* [solver] */
  char backend[VES_CONFIG_STR];          /* ipopt | nlopt | newton | euler */
  double tol, ctol;                      /* optimality and constraint tolerances */
  int max_iter;                          /* iterations per attempt of a step (then dt/2) */
  int max_builds;                        /* newton: matrix builds per attempt (0: no limit) */
  double max_correction;                 /* newton: largest inertia correction (0: no limit) */
  int freeze_hessian;                    /* newton: Hessian once per step */
  char factor_precision[VES_CONFIG_STR]; /* newton, euler: single | double */
  double drift_damping;                  /* alpha of the drift damping (model.h), 0: off */
  int profile_every; /* restore phi's tanh profile every this many steps (profile.h), 0: off */
  /* [reconnect] reference-configuration resets (all 0: none) */
  int reconnect_every;       /* accepted steps between resets (0: off) */
  double reconnect_cond_max; /* reset when max cond_2 F exceeds this (0: off, else > 1) */
  double reconnect_det_min;  /* reset when min det F drops below this (0: off, else < 1) */
  char reconnect_nodes[VES_CONFIG_STR]; /* new nodes: "coefficients" (y^a, paper) or "motion"
                                           (y(X_a)) */
  /* [remesh] full remeshing (remesh.h; all 0: none) */
  int remesh_every;           /* accepted steps between remeshings (0: off) */
  double remesh_cond_max;     /* remesh when max cond_2 F exceeds this (0: off, else > 1) */
  double remesh_det_min;      /* remesh when min det F drops below this (0: off, else < 1) */
  int remesh_on_failed_reset; /* 1: remesh when a due reset failed */
  /* [output] */
  int snapshot_every; /* accepted steps between snapshots */
} ves_config;

/* INI text, as problem and study files have it: "[section]" headers,
 * "key = value" lines (a value in double or single quotes is taken
 * verbatim; otherwise it ends at a ';' or '#'), comment lines starting with
 * ';' or '#', blank lines, CRLF line ends and a UTF-8 byte-order mark
 * accepted. Refused (VES_ERR_CONFIG, one line "NAME: line N: ..." in err):
 * a key outside a section, a repeated section or key (names are
 * case-insensitive), a header without its ']', a line without '=', a NUL
 * byte. Every header and key goes to fn in the text's order: section and
 * key lower-cased (key NULL for a header), the value value[vlen] (not
 * NUL-terminated); an error fn returns stops the scan and is returned. */
typedef ves_status (*ves_ini_item_fn)(void *ctx, const char *name, int line, const char *section,
                                      const char *key, const char *value, size_t vlen, char *err,
                                      size_t errlen);
ves_status ves_ini_scan(const char *text, size_t len, const char *name, ves_ini_item_fn fn,
                        void *ctx, char *err, size_t errlen);

/* The same for the file path: a regular file of at most 1 MiB (`what`, e.g.
 * "problem file", names its kind in messages; `name` stands for it);
 * VES_ERR_IO when it cannot be opened or read. */
ves_status ves_ini_load(const char *path, const char *name, const char *what, ves_ini_item_fn fn,
                        void *ctx, char *err, size_t errlen);

/* Defaults for every key. */
void ves_config_default(ves_config *cfg);

/* Load `path` over the defaults, then apply the overrides "section.key=value"
 * (nset of them). On error returns VES_ERR_CONFIG (or VES_ERR_IO for an
 * unreadable file) and writes one line "FILE: [section] key: reason" to err. */
ves_status ves_config_load(const char *path, int nset, const char *const *set, ves_config *cfg,
                           char *err, size_t errlen);

/* The same from problem-file text (e.g. the text stored in an output file):
 * `name` stands for the file in messages and in cfg->source (a relative
 * points file is found next to it). No overrides. */
ves_status ves_config_load_text(const char *text, const char *name, ves_config *cfg, char *err,
                                size_t errlen);

/* Apply the overrides "section.key=value" (nset of them) to a loaded cfg,
 * then check its consistency; errors as ves_config_load (cfg may then hold
 * some of the overrides). */
ves_status ves_config_set(ves_config *cfg, int nset, const char *const *set, char *err,
                          size_t errlen);

/* Cross-key consistency (epsilon vs box, a protocol that would do nothing,
 * an event after t_end, ...); same error convention. */
ves_status ves_config_validate(const ves_config *cfg, char *err, size_t errlen);

/* Typed access to every key, in table order (for writers of parameters). */
typedef enum { VES_KEY_REAL, VES_KEY_INT, VES_KEY_TEXT } ves_key_type;
typedef struct {
  const char *section, *key; /* names (static strings) */
  ves_key_type type;         /* which of the three values below holds */
  double real;               /* VES_KEY_REAL */
  int integer;               /* VES_KEY_INT */
  const char *text;          /* VES_KEY_TEXT, borrowed from the configuration */
} ves_config_entry;

/* Number of keys, and key i (0 <= i < count) of cfg. */
int ves_config_count(void);
void ves_config_entry_get(const ves_config *cfg, int i, ves_config_entry *e);

/* Every key of cfg as problem-file text (reals in the shortest form that
 * reads back exactly, so ves_config_load_text gives back the identical
 * configuration). *text is malloc'd and taken by the caller. */
ves_status ves_config_to_text(const ves_config *cfg, char **text);

/* v as the shortest "%.Ng" (N = 15..17) that strtod reads back as v. */
void ves_config_format_real(double v, char *buf, size_t len);

/* Read a points file (lines "R Z", '#' comments) for a curve shape; a
 * relative path is taken relative to the folder of cfg->source. *pts (2 *n)
 * taken by the caller. Errors as ves_config_load. */
ves_status ves_config_read_points(const ves_config *cfg, int *n, double **pts, char *err,
                                  size_t errlen);

/* Print every key: section, key, type, default, range, units and meaning
 * (the table problems/README.md is written from). */
void ves_config_print_keys(FILE *f);
/* The table of the keys named name ("section.key", or "key": every section's
 * key of that name) into f: the header and their rows, as in
 * ves_config_print_keys. Returns how many; with none, near (when not NULL)
 * receives the closest key's "section.key" (edit distance). */
int ves_config_print_key(FILE *f, const char *name, char *near, size_t nearlen);

#endif
