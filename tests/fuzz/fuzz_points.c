/* vesica — libFuzzer target: the points-file reader of curve shapes
 * (ves_config_read_points on a file holding the input) and, for an
 * accepted curve, the shape built from it as the setup builds it
 * (ves_shape_create). Built and run by `make fuzz` with AddressSanitizer +
 * UBSan. The contract: an accepted curve has at least 4 finite points, R >=
 * 0, R = 0 exactly at its first and last point, runs north to south, and
 * gives a shape (or a clean refusal of the shape) with a finite sharp area
 * 4 pi and a finite positive volume; a refused file gets a status < 0, a
 * one-line message naming the file, and no points. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "app/config.h"
#include "ves/shape.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void die(const char *what, const char *detail) {
  fprintf(stderr, "fuzz_points: contract broken: %s: %s\n", what, detail);
  abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static char path[64];
  if (!path[0]) snprintf(path, sizeof path, "/tmp/vesica_fuzz_points_%d.txt", (int)getpid());
  FILE *f = fopen(path, "wb");
  if (!f) return 0;
  fwrite(data, 1, size, f);
  fclose(f);
  ves_config cfg;
  ves_config_default(&cfg);
  snprintf(cfg.source, sizeof cfg.source, "/tmp/fuzz.ini");
  snprintf(cfg.shape_type, sizeof cfg.shape_type, "curve");
  snprintf(cfg.points, sizeof cfg.points, "%s", path);
  int n = -1;
  double *p = (double *)1;
  char err[1024] = "";
  ves_status st = ves_config_read_points(&cfg, &n, &p, err, sizeof err);
  if (st != VES_OK) {
    if (st >= 0 || p != NULL || n != 0) die("refusal left points", ves_status_str(st));
    if (!err[0] || strchr(err, '\n') || !strstr(err, path)) die("refusal message", err);
    return 0;
  }
  char msg[256];
  snprintf(msg, sizeof msg, "%d points", n);
  if (n < 4 || !p) die("accepted too few points", msg);
  for (int i = 0; i < n; i++)
    if (!isfinite(p[2 * i]) || !isfinite(p[2 * i + 1]) || p[2 * i] < 0)
      die("accepted a point", msg);
  if (p[0] != 0 || p[2 * n - 2] != 0) die("accepted ends off the axis", msg);
  if (!(p[1] > p[2 * n - 1])) die("accepted south to north", msg);
  ves_shape_params sp;
  ves_shape_params_default(&sp);
  sp.kind = VES_SHAPE_CURVE, sp.npts = n, sp.pts = p;
  ves_shape *s = NULL;
  st = ves_shape_create(&sp, &s);
  if (st == VES_OK) {
    double A, V;
    ves_shape_sharp(s, &A, &V);
    snprintf(msg, sizeof msg, "%d points: area %.17g, volume %.17g", n, A, V);
    if (!isfinite(A) || fabs(A / (4 * M_PI) - 1) > 1e-6 || !isfinite(V) || !(V > 0))
      die("accepted curve gives a broken shape", msg);
    ves_shape_destroy(&s);
  }
  free(p);
  return 0;
}
