/* vesica — the XDMF files beside the HDF5 output: FILE.xdmf, two temporal
 * collections over the snapshots (nodes as points, the triangles at the
 * material positions) for ParaView and meshio's time-series reader, and
 * FILE_last.xmf, the last snapshot as one grid for meshio.read. Layout:
 * app/io.h; docs/manual.md, "XDMF and ParaView". */
#include <stdio.h>
#include <string.h>

#include "app/io_impl.h"

void ves_io_xdmf_path(const char *h5path, char *out, size_t len) {
  size_t l = strlen(h5path);
  if (l > 3 && !strcmp(h5path + l - 3, ".h5"))
    snprintf(out, len, "%.*s.xdmf", (int)(l - 3), h5path);
  else
    snprintf(out, len, "%s.xdmf", h5path);
}

int ves_io_xdmf_name_ok(const char *h5path, char *why, size_t len) {
  const char *slash = strrchr(h5path, '/');
  const unsigned char *b = (const unsigned char *)(slash ? slash + 1 : h5path), *p = b;
  const char *bad = NULL;
  for (; *p && !bad; p++) {
    int more = *p < 0x80             ? 0
               : (*p & 0xe0) == 0xc0 ? 1
               : (*p & 0xf0) == 0xe0 ? 2
               : (*p & 0xf8) == 0xf0 ? 3
                                     : -1;
    for (int i = 1; i <= more && more > 0; i++)
      if ((p[i] & 0xc0) != 0x80) more = -1;
    if (more < 0 || (more == 1 && *p < 0xc2))
      bad = "a byte that is not UTF-8 (XML files are)";
    else if (*p == ':')
      bad = "':' (XDMF readers split NAME:/dataset at ':')";
    else if (*p == '|')
      bad = "'|' (XDMF readers split a data item's text at '|')";
    else if (*p < 0x20 || *p == 0x7f)
      bad = "a control character (XML files cannot hold it)";
    else if (p == b && *p == ' ')
      bad = "a leading space (XDMF readers strip it from the data item)";
    else if (more > 0)
      p += more;
  }
  if (bad && why) snprintf(why, len, "its name holds %s", bad);
  return !bad;
}

/* Text with the XML special characters escaped. */
static void xml_text(FILE *f, const char *s) {
  for (; *s; s++) {
    if (*s == '&')
      fputs("&amp;", f);
    else if (*s == '<')
      fputs("&lt;", f);
    else if (*s == '>')
      fputs("&gt;", f);
    else if (*s == '"')
      fputs("&quot;", f);
    else
      fputc(*s, f);
  }
}

static void xdmf_item(FILE *f, const char *h5, const char *dims, const char *num, int prec,
                      const char *dset) {
  fprintf(f, "     <DataItem Dimensions=\"%s\" NumberType=\"%s\" Precision=\"%d\" Format=\"HDF\">",
          dims, num, prec);
  xml_text(f, h5);
  fprintf(f, ":%s</DataItem>\n", dset);
}

/* One uniform grid of snapshot k: as points (nodes) or triangles (mesh) at
 * the material positions x of its node set, phi and (when stored) the flow;
 * its time unless timeless (meshio.read refuses a Time element). */
static void xdmf_grid(FILE *f, const ves_io *io, const char *h5, int k, int mesh, int timeless) {
  char y[64], phi[64], v[64], dims[64], tri[64] = "/mesh/triangles", vert[64] = "/mesh/vertices";
  int n = io->info.n, nt = io->info.ntri;
  const int j = ves_io_snapshot_mesh(io, k, &n, &nt); /* after remeshings: their node sets */
  if (j >= 0) {
    snprintf(tri, sizeof tri, "/remeshes/%d/triangles", j);
    snprintf(vert, sizeof vert, "/remeshes/%d/vertices", j);
  }
  snprintf(y, sizeof y, "/snapshots/%d/x", k);
  snprintf(phi, sizeof phi, "/snapshots/%d/phi", k);
  fprintf(f, "   <Grid Name=\"%s_%d\" GridType=\"Uniform\">\n", mesh ? "mesh" : "nodes", k);
  if (!timeless) fprintf(f, "    <Time Value=\"%.17g\"/>\n", io->snap_t[k]);
  if (mesh) {
    fprintf(f,
            "    <Topology TopologyType=\"Triangle\" NumberOfElements=\"%d\" "
            "NodesPerElement=\"3\">\n",
            nt);
    snprintf(dims, sizeof dims, "%d 3", nt);
    xdmf_item(f, h5, dims, "Int", 4, tri);
  } else {
    fprintf(f,
            "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"%d\" "
            "NodesPerElement=\"1\">\n",
            n);
    snprintf(dims, sizeof dims, "%d", n);
    xdmf_item(f, h5, dims, "Int", 4, vert);
  }
  fprintf(f, "    </Topology>\n    <Geometry GeometryType=\"XY\">\n");
  snprintf(dims, sizeof dims, "%d 2", n);
  xdmf_item(f, h5, dims, "Float", 8, y);
  fprintf(f, "    </Geometry>\n    <Attribute Name=\"phi\" AttributeType=\"Scalar\" "
             "Center=\"Node\">\n");
  snprintf(dims, sizeof dims, "%d", n);
  xdmf_item(f, h5, dims, "Float", 8, phi);
  fprintf(f, "    </Attribute>\n");
  snprintf(v, sizeof v, "/snapshots/%d/velocity", k);
  if (H5Lexists(io->file, v, H5P_DEFAULT) > 0) { /* not the first snapshot's */
    fprintf(f, "    <Attribute Name=\"velocity\" AttributeType=\"Vector\" "
               "Center=\"Node\">\n");
    snprintf(dims, sizeof dims, "%d 2", n);
    xdmf_item(f, h5, dims, "Float", 8, v);
    fprintf(f, "    </Attribute>\n");
  }
  fprintf(f, "   </Grid>\n");
}

/* Write path through path.tmp and a rename, so a reader never sees half a
 * file: the time series (two temporal collections) or, last, the last
 * snapshot's triangles alone. */
static ves_status xdmf_file(const ves_io *io, const char *path, int last) {
  const char *slash = strrchr(io->path, '/');
  const char *h5 = slash ? slash + 1 : io->path; /* relative: the pair moves together */
  char tmp[PATH_MAX + 16];
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  FILE *f = fopen(tmp, "w");
  if (!f) return VES_ERR_IO;
  fprintf(f, "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
             "<Xdmf Version=\"3.0\">\n <Domain>\n");
  if (last)
    xdmf_grid(f, io, h5, io->nsnap - 1, 1, 1);
  else
    for (int pass = 1; pass >= 0; pass--) { /* meshio reads the last collection: the mesh */
      fprintf(f, "  <Grid Name=\"%s\" GridType=\"Collection\" CollectionType=\"Temporal\">\n",
              pass ? "nodes" : "mesh");
      for (int k = 0; k < io->nsnap; k++) xdmf_grid(f, io, h5, k, !pass, 0);
      fprintf(f, "  </Grid>\n");
    }
  fprintf(f, " </Domain>\n</Xdmf>\n");
  int bad = ferror(f);
  if (fclose(f) != 0 || bad || rename(tmp, path) != 0) {
    remove(tmp);
    return VES_ERR_IO;
  }
  return VES_OK;
}

/* FILE_last.xmf for FILE.h5 (FILE.xdmf's name with _last.xmf for .xdmf):
 * another extension, so that no run's FILE.xdmf has its name (a run
 * a_last.h5 writes a_last.xdmf); meshio and ParaView take .xmf as XDMF. */
void ves_io_xdmf_last_path(const char *h5path, char *out, size_t len) {
  char x[PATH_MAX];
  ves_io_xdmf_path(h5path, x, sizeof x);
  snprintf(out, len, "%.*s_last.xmf", (int)(strlen(x) - 5), x);
}

/* Two files: FILE.xdmf, two temporal collections over the snapshots — the
 * nodes alone as points, and the reference triangles at the material
 * positions x of their nodes, with phi and, from the second snapshot on, the
 * flow (velocity) at the nodes (XDMF 3 with the XDMF 2 attribute names,
 * which ParaView's readers and meshio's time-series reader take; meshio
 * reads the last collection) — and FILE_last.xmf, the last snapshot's
 * triangles as one grid: meshio.read takes a file of one grid only and
 * stops on the time series ("Only supports one grid right now"). */
ves_status io_xdmf_write(const ves_io *io) {
  if (!ves_io_xdmf_name_ok(io->path, NULL, 0)) return VES_ERR_ARG; /* never a broken XDMF */
  char last[PATH_MAX];
  ves_io_xdmf_last_path(io->path, last, sizeof last);
  ves_status st = io->nsnap > 0 ? xdmf_file(io, last, 1) : VES_OK;
  return st == VES_OK ? xdmf_file(io, io->xdmf, 0) : st;
}
