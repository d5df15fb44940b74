/* vesica — the provenance of a run's output: what built the program (its
 * version, git commit, compiler and flags, the library versions) and where
 * and how it ran (host, threads, start time, command line), one member of
 * /provenance per run (the first run and each restart that writes). Written
 * only, never read back into a computation. Layout: app/io.h; docs/manual.md,
 * "Output format". */
#define _GNU_SOURCE /* gethostname */
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "app/cli_impl.h" /* VES_VERSION, the program's version */
#include "app/io_impl.h"

#if defined(__has_include)
#if __has_include(<dmumps_c.h>)
#include <dmumps_c.h> /* MUMPS_VERSION */
#endif
#if __has_include(<coin/IpoptConfig.h>)
#include <coin/IpoptConfig.h> /* IPOPT_VERSION */
#endif
#endif

/* Given by the Makefile (git describe --always --dirty; the compiler flags). */
#ifndef VES_COMMIT
#define VES_COMMIT "unknown"
#endif
#ifndef VES_CFLAGS
#define VES_CFLAGS "unknown"
#endif

/* The libraries' own version queries, weak: a program that links this file
 * without them (the HDF5 reader's fuzzer) records "unknown". */
void nlopt_version(int *major, int *minor, int *bugfix) __attribute__((weak));
char *openblas_get_config(void) __attribute__((weak));
char *openblas_get_corename(void) __attribute__((weak));
int omp_get_max_threads(void) __attribute__((weak));

void io_utc_now(char *buf, size_t len) {
  const time_t now = time(NULL);
  struct tm tm;
  if (!gmtime_r(&now, &tm) || !strftime(buf, len, "%Y-%m-%dT%H:%M:%SZ", &tm))
    snprintf(buf, len, "unknown");
}

/* The process's command line (/proc/self/cmdline) with every argument
 * quoted for a POSIX shell where it needs it (malloc'd; "unknown" when the
 * file does not read). */
static char *command_line(void) {
  FILE *f = fopen("/proc/self/cmdline", "rb");
  size_t cap = 4096, len = 0;
  char *raw = malloc(cap);
  while (f && raw) {
    if (len == cap) {
      char *t = realloc(raw, cap *= 2);
      if (!t) break;
      raw = t;
    }
    const size_t got = fread(raw + len, 1, cap - len, f);
    if (got == 0) break;
    len += got;
  }
  if (f) fclose(f);
  if (!raw || len == 0) {
    free(raw);
    return strdup("unknown");
  }
  char *out = malloc(4 * len + 3);
  size_t o = 0;
  for (size_t i = 0; out && i < len;) {
    const char *arg = raw + i;
    const size_t n = strnlen(arg, len - i);
    const int plain = n > 0 && strspn(arg, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                           "0123456789_./=:,+-@%") == n;
    if (o) out[o++] = ' ';
    if (plain) {
      memcpy(out + o, arg, n), o += n;
    } else { /* '...' with each ' as '\'' */
      out[o++] = '\'';
      for (size_t j = 0; j < n; j++)
        if (arg[j] == '\'')
          memcpy(out + o, "'\\''", 4), o += 4;
        else
          out[o++] = arg[j];
      out[o++] = '\'';
    }
    i += n + 1;
  }
  if (out) out[o] = 0;
  free(raw);
  return out;
}

ves_status io_provenance_write(ves_io *io) {
  int count = 0;
  if (H5Lexists(io->file, "provenance", H5P_DEFAULT) > 0) { /* the runs recorded so far */
    hid_t p = H5Gopen2(io->file, "provenance", H5P_DEFAULT);
    if (p < 0 || io_attr_read(p, "count", H5T_NATIVE_INT, &count) != VES_OK || count < 0) count = 0;
    if (p >= 0) H5Gclose(p);
  }
  hid_t s, g;
  VES_CALL(io_counted_open(io->file, "provenance", count, &s, &g));
  char hdf5[32], nlopt[32] = "unknown", host[256] = "unknown";
  unsigned maj = 0, min = 0, rel = 0;
  H5get_libversion(&maj, &min, &rel);
  snprintf(hdf5, sizeof hdf5, "%u.%u.%u", maj, min, rel);
  if (nlopt_version) {
    int a = 0, b = 0, c = 0;
    nlopt_version(&a, &b, &c);
    snprintf(nlopt, sizeof nlopt, "%d.%d.%d", a, b, c);
  }
  if (gethostname(host, sizeof host) != 0) snprintf(host, sizeof host, "unknown");
  host[sizeof host - 1] = 0;
  char *cmd = command_line();
  const char *ob = openblas_get_config ? openblas_get_config() : NULL;
  const char *core = openblas_get_corename ? openblas_get_corename() : NULL;
  const struct {
    const char *name, *value;
  } a[] = {{"version", VES_VERSION},
           {"commit", VES_COMMIT},
           {"compiler",
#ifdef __VERSION__
            "cc " __VERSION__
#else
            "unknown"
#endif
           },
           {"cflags", VES_CFLAGS},
           {"hdf5", hdf5},
#ifdef MUMPS_VERSION
           {"mumps", MUMPS_VERSION},
#else
           {"mumps", "unknown"},
#endif
#ifdef IPOPT_VERSION
           {"ipopt", IPOPT_VERSION},
#else
           {"ipopt", "unknown"},
#endif
           {"nlopt", nlopt},
           {"openblas", ob ? ob : "unknown"},
           {"openblas_core", core ? core : "unknown"},
           {"host", host},
           {"started", io->started},
           {"command", cmd ? cmd : "unknown"}};
  ves_status st = VES_OK;
  for (size_t i = 0; i < sizeof a / sizeof a[0] && st == VES_OK; i++)
    st = io_attr_str(g, a[i].name, a[i].value);
  if (st == VES_OK) st = io_attr_int(g, "threads", omp_get_max_threads ? omp_get_max_threads() : 1);
  if (st == VES_OK)
    st = io_describe(s, "per member",
                     "one member per run that wrote this file (0 the first, then each restart), "
                     "in the order they ran");
  if (st == VES_OK)
    st = io_describe(g, "1",
                     "the program and machine of one run: version, commit (git describe "
                     "--always --dirty of the build, -dirty: uncommitted changes), compiler, "
                     "cflags, the library versions (hdf5, nlopt, openblas at run time; mumps, "
                     "ipopt of the headers built against), openblas_core (the kernels OpenBLAS "
                     "chose), host, threads (OpenMP), started (UTC), command (shell-quoted)");
  free(cmd);
  return io_counted_close(io->file, s, g, count, st);
}

ves_status io_provenance_pending(ves_io *io) {
  if (!io->prov_pending) return VES_OK;
  VES_CALL(io_reserve(io, IO_ROOM_MARGIN));
  VES_CALL(io_provenance_write(io));
  io->prov_pending = 0;
  return VES_OK;
}

int ves_io_provenance_runs(const ves_io *io) {
  if (!io || H5Lexists(io->file, "provenance", H5P_DEFAULT) <= 0) return 0;
  hid_t g = H5Gopen2(io->file, "provenance", H5P_DEFAULT);
  int count = 0;
  if (g < 0 || io_attr_read(g, "count", H5T_NATIVE_INT, &count) != VES_OK || count < 0) count = 0;
  if (g >= 0) H5Gclose(g);
  return count;
}

/* The items in the order written, units and description left out. */
static const char *const prov_items[] = {
    "version", "commit",   "compiler",      "cflags", "hdf5",    "mumps",   "ipopt",
    "nlopt",   "openblas", "openblas_core", "host",   "threads", "started", "command"};

ves_status ves_io_provenance(ves_io *io, int k, int i, char *key, size_t keylen, char *value,
                             size_t valuelen) {
  VES_CHECK(io && key && value && keylen > 0 && valuelen > 0, VES_ERR_ARG);
  if (k < 0 || k >= ves_io_provenance_runs(io) || i < 0 ||
      i >= (int)(sizeof prov_items / sizeof *prov_items))
    return VES_ERR_ARG;
  char name[48];
  snprintf(name, sizeof name, "provenance/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  snprintf(key, keylen, "%s", prov_items[i]);
  ves_status st;
  if (!strcmp(prov_items[i], "threads")) {
    int t = 0;
    st = io_attr_read(g, "threads", H5T_NATIVE_INT, &t);
    if (st == VES_OK) snprintf(value, valuelen, "%d", t);
  } else {
    st = io_attr_read_buf(g, prov_items[i], value, valuelen);
  }
  if (st != VES_OK) snprintf(value, valuelen, "(unreadable)"), st = VES_OK;
  H5Gclose(g);
  return st;
}
