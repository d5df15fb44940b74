/* vesica — CGAL behind a C API: Delaunay triangulation, the local spacing
 * h_a (mean Delaunay edge length, smoothed over the neighbours), the exact
 * search |X - x_a| <= radius_a (a kd-tree on points lifted to 3D), and adapted
 * node sets: graded walls, a hexagonal strip along the axis, free nodes
 * sampled with density 2/(sqrt3 h^2) and moved by Lloyd iterations to the
 * centroids of their Voronoi cells under rho = h^-4 (docs/design.md,
 * "Discretization"). */
#include "ves/geom.h"

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Fuzzy_sphere.h>
#include <CGAL/Kd_tree.h>
#include <CGAL/Search_traits_3.h>
#include <CGAL/Search_traits_adapter.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <boost/iterator/counting_iterator.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <memory>
#include <new>
#include <utility>
#include <vector>

namespace {

typedef CGAL::Exact_predicates_inexact_constructions_kernel K2;
typedef CGAL::Triangulation_vertex_base_with_info_2<int, K2> Vb;
typedef CGAL::Triangulation_data_structure_2<Vb> Tds;
typedef CGAL::Delaunay_triangulation_2<K2, Tds> DT;
typedef K2::Point_2 Point_2;

typedef CGAL::Simple_cartesian<double> K3;
typedef K3::Point_3 Point_3;

/* Index -> lifted 3D point, the key type of the kd-tree (CGAL lvalue property map). */
struct Lift_map {
  typedef std::size_t key_type;
  typedef Point_3 value_type;
  typedef const Point_3 &reference;
  typedef boost::lvalue_property_map_tag category;
  const Point_3 *p = nullptr;
  reference operator[](key_type k) const { return p[k]; }
  friend reference get(const Lift_map &m, key_type k) { return m.p[k]; }
};

typedef CGAL::Search_traits_3<K3> Traits_base;
typedef CGAL::Search_traits_adapter<std::size_t, Lift_map, Traits_base> Traits;
typedef CGAL::Kd_tree<Traits> Tree;
typedef CGAL::Fuzzy_sphere<Traits> Sphere;

/* Thrown when the user's sizing function returns h <= 0 or a non-finite h. */
struct Bad_sizing {};

/* Thrown when the requested node set is absurdly large (h far too small). */
struct Too_many {};

/* Thrown on an unexpected geometric failure (e.g. two Lloyd nodes collapsing). */
struct Geom_error {};

/* Maps an in-flight C++ exception to a status (called inside catch (...)). */
ves_status status_of_exception() {
  try {
    throw;
  } catch (const std::bad_alloc &) {
    return VES_ERR_ALLOC;
  } catch (const Bad_sizing &) {
    return VES_ERR_ARG;
  } catch (const Too_many &) {
    return VES_ERR_ARG;
  } catch (...) {
    return VES_ERR_GEOM;
  }
}

/* All finite input coordinates? */
bool finite_points(int n, const double *x) {
  for (int i = 0; i < 2 * n; i++)
    if (!std::isfinite(x[i])) return false;
  return true;
}

/* Delaunay triangulation of x[2n] with vertex info = input index; VES_ERR_GEOM on duplicates. */
ves_status build_dt(int n, const double *x, DT &dt) {
  std::vector<std::pair<Point_2, int>> pts;
  pts.reserve((std::size_t)n);
  for (int i = 0; i < n; i++) pts.emplace_back(Point_2(x[2 * i], x[2 * i + 1]), i);
  dt.insert(pts.begin(), pts.end());                          /* spatially sorted insertion */
  if ((int)dt.number_of_vertices() != n) return VES_ERR_GEOM; /* duplicates */
  return VES_OK;
}

const int SPACING_PASSES = 2; /* smoothing passes of the measured spacing */

/* h_a = mean |x_a - x_b| over the Delaunay edges ab of a finished triangulation,
 * then smoothed over the Delaunay neighbours. Every sum runs over the neighbours
 * in increasing index order, not in CGAL's edge order: that order depends on the
 * process's history (h differs by 1 ulp between the same reset made in a run
 * and in its restart), and the spacing must be a function of the nodes
 * alone, bit for bit (a restart rebuilds the same reference). */
ves_status spacing_of_dt(const DT &dt, int n, const double *x, double *h) {
  std::vector<std::vector<int>> nb((std::size_t)n);
  for (auto e = dt.finite_edges_begin(); e != dt.finite_edges_end(); ++e) {
    int a = e->first->vertex(DT::cw(e->second))->info();
    int b = e->first->vertex(DT::ccw(e->second))->info();
    nb[a].push_back(b), nb[b].push_back(a);
  }
  for (int i = 0; i < n; i++) {
    if (nb[i].empty()) return VES_ERR_GEOM;
    std::sort(nb[i].begin(), nb[i].end());
    double s = 0.0;
    for (int b : nb[i]) s += std::hypot(x[2 * i] - x[2 * b], x[2 * i + 1] - x[2 * b + 1]);
    h[i] = s / (double)nb[i].size(); /* h_a = (1/deg a) sum_b |x_a - x_b| */
  }
  /* SPACING_PASSES passes of h_a <- (h_a + (1/2) sum_b h_b) / (1 + deg_a / 2) over
   * the Delaunay neighbours b: the raw mean edge length jitters by ~+-10% from
   * node to node where lattices meet, and that jitter in beta_a = gamma/h_a^2
   * alone multiplies the sphere's energy error by 7 (4.2e-4 vs 6.6e-5 at
   * eps = 0.04, docs/results.md, "Convergence in ε and h"). A
   * uniform lattice keeps h_a exact. */
  std::vector<double> next((std::size_t)n);
  for (int pass = 0; pass < SPACING_PASSES; pass++) {
    for (int i = 0; i < n; i++) {
      double acc = h[i];
      for (int b : nb[i]) acc += 0.5 * h[b];
      next[i] = acc / (1.0 + 0.5 * (double)nb[i].size());
    }
    for (int i = 0; i < n; i++) h[i] = next[i];
  }
  return VES_OK;
}

} // namespace

/* ---------------------------------------------------------------- Delaunay */

extern "C" ves_status ves_geom_delaunay(int n, const double *x, int *ntri, int **tri) {
  VES_CHECK(n >= 3 && x && ntri && tri, VES_ERR_ARG);
  VES_CHECK(finite_points(n, x), VES_ERR_ARG);
  *ntri = 0, *tri = nullptr;
  try {
    DT dt;
    VES_CALL(build_dt(n, x, dt));
    if (dt.dimension() < 2) return VES_ERR_GEOM; /* all points collinear */
    int nf = (int)dt.number_of_faces();
    int *t = (int *)std::malloc(sizeof(int) * 3 * (std::size_t)nf);
    if (!t) return VES_ERR_ALLOC;
    int k = 0;
    for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f, k++)
      for (int i = 0; i < 3; i++) t[3 * k + i] = f->vertex(i)->info(); /* CGAL faces are CCW */
    *ntri = k, *tri = t;
    return VES_OK;
  } catch (...) {
    return status_of_exception();
  }
}

extern "C" ves_status ves_geom_spacing(int n, const double *x, double *h) {
  VES_CHECK(n >= 2 && x && h, VES_ERR_ARG);
  VES_CHECK(finite_points(n, x), VES_ERR_ARG);
  try {
    DT dt;
    VES_CALL(build_dt(n, x, dt));
    return spacing_of_dt(dt, n, x, h);
  } catch (...) {
    return status_of_exception();
  }
}

/* ---------------------------------------------------------------- search */

namespace {

/* Nodes whose radii lie within a factor SEARCH_CLASS of each other share one lifted tree:
 * the lift's pruning is only as sharp as rmax / r_a, so one tree over radii spread by 40x
 * visits ~(rmax/r_a)^2 times too many fine nodes; classes bound that by SEARCH_CLASS^2. */
const double SEARCH_CLASS = 1.5;

/* One radius class: node a lifted to (R_a, Z_a, sqrt(rmax^2 - r_a^2)), rmax the class's
 * largest radius, so |(X, 0) - lift_a| <= rmax  <=>  |X - x_a| <= r_a. */
struct Search_class {
  std::vector<int> node;     /* class-local -> input index */
  std::vector<Point_3> lift; /* the lifted nodes (the tree refers to them by local index) */
  double rq = 0.0;           /* query radius: rmax, enlarged against rounding */
  std::unique_ptr<Tree> tree;
};

Lift_map lift_map(const Point_3 *p) {
  Lift_map m;
  m.p = p;
  return m;
}

} // namespace

struct ves_geom_search {
  std::vector<double> x, r;      /* copies of the nodes and radii */
  std::vector<Search_class> cls; /* radius classes, each with its lifted kd-tree */
};

namespace {

/* The exact test |X - x_a| <= r_a of every query and filter. */
inline bool within(const ves_geom_search *s, int a, double X, double Z) {
  double dR = X - s->x[2 * a], dZ = Z - s->x[2 * a + 1];
  return dR * dR + dZ * dZ <= s->r[a] * s->r[a];
}

/* Output iterator of the kd-tree: filters (exactly when rho = 0, else keeps
 * |X - x_a| <= r_a + rho with a relative margin), stores up to cap indices,
 * counts all. */
struct Collect {
  typedef std::output_iterator_tag iterator_category;
  typedef void value_type;
  typedef void difference_type;
  typedef void pointer;
  typedef void reference;
  const ves_geom_search *s;
  const int *node;
  double X, Z, rho;
  int cap;
  int *idx;
  int *count;
  Collect &operator*() { return *this; }
  Collect &operator++() { return *this; }
  Collect operator++(int) { return *this; }
  Collect &operator=(std::size_t k) {
    int a = node[k];
    bool keep;
    if (rho == 0.0)
      keep = within(s, a, X, Z);
    else {
      double dR = X - s->x[2 * a], dZ = Z - s->x[2 * a + 1], t = s->r[a] + rho;
      keep = dR * dR + dZ * dZ <= t * t * (1.0 + 1e-9); /* a superset: rounding cannot drop one */
    }
    if (keep) {
      if (*count < cap) idx[*count] = a;
      (*count)++;
    }
    return *this;
  }
};

/* The nodes within r_a + rho of X (rho = 0: exactly within r_a), sorted. */
ves_status search_near(const ves_geom_search *s, const double X[2], double rho, int cap, int *idx,
                       int *count) {
  *count = 0;
  try {
    for (const Search_class &c : s->cls) {
      /* |X - x_a| <= r_a + rho puts the lift within rmax + rho of (X, 0) */
      Sphere q(Point_3(X[0], X[1], 0.0), c.rq + rho * (1.0 + 1e-10), 0.0,
               Traits(lift_map(c.lift.data())));
      c.tree->search(Collect{s, c.node.data(), X[0], X[1], rho, cap, idx, count}, q);
    }
    if (*count <= cap) std::sort(idx, idx + *count); /* increasing index order */
    return VES_OK;
  } catch (...) {
    return status_of_exception();
  }
}

} // namespace

extern "C" ves_status ves_geom_search_create(int n, const double *x, const double *radius,
                                             ves_geom_search **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = nullptr;
  VES_CHECK(n >= 1 && x && radius, VES_ERR_ARG);
  VES_CHECK(finite_points(n, x), VES_ERR_ARG);
  double scale = 0.0;
  for (int i = 0; i < n; i++) {
    VES_CHECK(std::isfinite(radius[i]) && radius[i] >= 0.0, VES_ERR_ARG);
    scale = std::max({scale, std::fabs(x[2 * i]), std::fabs(x[2 * i + 1])});
  }
  ves_geom_search *s = nullptr;
  try {
    s = new ves_geom_search;
    s->x.assign(x, x + 2 * n), s->r.assign(radius, radius + n);
    std::vector<int> ord((std::size_t)n);
    for (int i = 0; i < n; i++) ord[i] = i;
    std::sort(ord.begin(), ord.end(), [&](int a, int b) { return radius[a] < radius[b]; });
    for (int i = 0; i < n;) { /* classes r in [r_first, SEARCH_CLASS r_first] */
      int j = i;
      while (j < n && radius[ord[j]] <= SEARCH_CLASS * radius[ord[i]]) j++;
      s->cls.emplace_back();
      Search_class &c = s->cls.back();
      c.node.assign(ord.begin() + i, ord.begin() + j);
      double rmax = radius[ord[j - 1]];
      for (int a : c.node)
        c.lift.emplace_back(x[2 * a], x[2 * a + 1],
                            std::sqrt(std::max(0.0, rmax * rmax - radius[a] * radius[a])));
      /* The lift cancels rmax^2 - r_a^2 + r_a^2: relative rounding ~1e-16 of rmax^2 and of
       * the coordinates; the margin covers it by orders of magnitude, the filter is exact. */
      c.rq = rmax * (1.0 + 1e-10) + 1e-13 * scale;
      c.tree.reset(new Tree(boost::counting_iterator<std::size_t>(0),
                            boost::counting_iterator<std::size_t>(c.node.size()), Tree::Splitter(),
                            Traits(lift_map(c.lift.data()))));
      c.tree->build(); /* build now: queries are then read-only */
      i = j;
    }
    *out = s;
    return VES_OK;
  } catch (...) {
    delete s;
    return status_of_exception();
  }
}

extern "C" ves_status ves_geom_search_query(const ves_geom_search *s, const double X[2], int cap,
                                            int *idx, int *count) {
  VES_CHECK(s && X && count && cap >= 0 && (cap == 0 || idx), VES_ERR_ARG);
  VES_CHECK(std::isfinite(X[0]) && std::isfinite(X[1]), VES_ERR_ARG);
  return search_near(s, X, 0.0, cap, idx, count);
}

extern "C" ves_status ves_geom_search_query_near(const ves_geom_search *s, const double X[2],
                                                 double rho, int cap, int *idx, int *count) {
  VES_CHECK(s && X && count && cap >= 0 && (cap == 0 || idx), VES_ERR_ARG);
  VES_CHECK(std::isfinite(X[0]) && std::isfinite(X[1]), VES_ERR_ARG);
  VES_CHECK(std::isfinite(rho) && rho >= 0.0, VES_ERR_ARG);
  return search_near(s, X, rho, cap, idx, count);
}

extern "C" ves_status ves_geom_search_filter(const ves_geom_search *s, const double X[2], int ncand,
                                             const int *cand, int *idx, int *count) {
  VES_CHECK(s && X && count && ncand >= 0 && (ncand == 0 || (cand && idx)), VES_ERR_ARG);
  VES_CHECK(std::isfinite(X[0]) && std::isfinite(X[1]), VES_ERR_ARG);
  const int n = (int)s->r.size();
  int c = 0;
  for (int k = 0; k < ncand; k++) {
    VES_CHECK(cand[k] >= 0 && cand[k] < n, VES_ERR_ARG);
    if (within(s, cand[k], X[0], X[1])) idx[c++] = cand[k];
  }
  *count = c;
  return VES_OK;
}

extern "C" void ves_geom_search_destroy(ves_geom_search **s) {
  if (!s) return;
  delete *s;
  *s = nullptr;
}

/* ---------------------------------------------------------------- adapted nodes */

namespace {

const double SQ3 = 1.7320508075688772; /* sqrt(3) */

/* Density exponent of the Lloyd centroids: rho = h^-RHO_EXP. A CVT with density rho has
 * cell size ~ rho^(-1/(d+2)) (Du, Faber & Gunzburger 1999), so spacing ~ h needs rho = h^-4
 * in 2D; rho = h^-2 drifts nodes out of the fine band (docs/results.md, "Approaches
 * measured and not adopted"). */
const double RHO_EXP = 4.0;

/* splitmix64: deterministic seeded uniform numbers in [0, 1). */
struct Rng {
  std::uint64_t s;
  double uniform() {
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
  }
};

/* The user's sizing h(R, Z) > 0, checked. */
struct Sizing {
  ves_sizing_fn f;
  void *ctx;
  double operator()(double R, double Z) const {
    double X[2] = {R, Z};
    double h = f(X, ctx);
    if (!(h > 0.0) || !std::isfinite(h)) throw Bad_sizing();
    return h;
  }
};

/* Largest node count we agree to build (guards against a sizing far too small). */
const double MAX_NODES = 2e7;

/* 1D graded placement on [0, L] along P(t) = A + t (B - A)/L: t_{i+1} = t_i + c h(mid),
 * c chosen (bisection) so that an integer number of steps lands on L; returns t_0..t_M. */
std::vector<double> place_1d(const Sizing &h, double RA, double ZA, double RB, double ZB) {
  double L = std::hypot(RB - RA, ZB - ZA), eR = (RB - RA) / L, eZ = (ZB - ZA) / L;
  auto hs = [&](double t) { return h(RA + t * eR, ZA + t * eZ); };
  /* midpoint step c h(t + c h(t)/2) */
  auto step = [&](double t, double c) { return c * hs(std::min(L, t + 0.5 * c * hs(t))); };
  /* fractional number of steps F(c) to reach L with steps c h(midpoint) */
  auto steps = [&](double c, std::vector<double> *t) {
    double s = 0.0, F = 0.0;
    if (t) t->assign(1, 0.0);
    for (;;) {
      double d = step(s, c);
      if (s + d >= L) return F + (L - s) / d;
      s += d, F += 1.0;
      if (t) t->push_back(s);
      if (F > MAX_NODES) throw Too_many();
    }
  };
  double F1 = steps(1.0, nullptr);
  double M = std::max(1.0, std::round(F1));
  double lo = 0.25, hi = 4.0; /* F(lo) > M > F(hi) for any reasonable grading */
  for (int it = 0; it < 60; it++) {
    double c = 0.5 * (lo + hi);
    if (steps(c, nullptr) > M)
      lo = c;
    else
      hi = c;
  }
  std::vector<double> t;
  double c = 0.5 * (lo + hi);
  steps(c, &t);
  /* t has M or M+1 entries up to bisection round-off: keep M interior + the end point */
  while ((double)t.size() > M) t.pop_back();
  double last = t.back() + step(t.back(), c);
  double scale = L / std::max(last, 1e-300);
  for (double &v : t) v *= scale; /* rescale so the last node lands exactly on B */
  t.push_back(L);
  return t;
}

/* The node set under construction with the geometry of the strip and the free region. */
struct Builder {
  double LR, LZ;
  Sizing h;
  std::vector<double> rz, rH, rend; /* strip rows (levels and level midpoints): Z, spacing H,
                                       R of the row's last lattice node */
  ves_region_fn reserved;           /* region left to the caller's nodes (may be NULL) */
  void *reserved_ctx;
  std::vector<double> x; /* 2n positions */
  std::vector<int> flag; /* n flags */

  void add(double R, double Z, int f) {
    x.push_back(R), x.push_back(Z);
    flag.push_back(f);
  }
  /* free region: beyond the Voronoi edge of the strip (last node + (sqrt3/4) H of the two
   * rows around Z), and half a spacing off the walls */
  bool is_reserved(double R, double Z) const {
    double X[2] = {R, Z};
    return reserved && reserved(X, reserved_ctx);
  }
  bool in_free(double R, double Z, double hX) const {
    if (!(R < LR - 0.5 * hX && std::fabs(Z) < LZ - 0.5 * hX)) return false;
    if (is_reserved(R, Z)) return false;
    std::size_t i = (std::size_t)(std::upper_bound(rz.begin(), rz.end(), Z) - rz.begin());
    i = std::min(std::max<std::size_t>(i, 1), rz.size() - 1);
    double edge = std::max(rend[i - 1] + SQ3 / 4 * rH[i - 1], rend[i] + SQ3 / 4 * rH[i]);
    return R > edge;
  }
  bool in_free(double R, double Z) const { return in_free(R, Z, h(R, Z)); }
};

/* Wall nodes: Z = -LZ and Z = +LZ for R in [0, LR], R = LR for Z in (-LZ, LZ), graded by h. */
void make_walls(Builder &b) {
  for (int side = -1; side <= 1; side += 2) {
    std::vector<double> t = place_1d(b.h, 0.0, side * b.LZ, b.LR, side * b.LZ);
    for (std::size_t i = 0; i < t.size(); i++) {
      double R = (i + 1 == t.size()) ? b.LR : t[i];
      b.add(R, side * b.LZ, i == 0 ? (VES_NODE_WALL | VES_NODE_AXIS) : VES_NODE_WALL);
    }
  }
  std::vector<double> t = place_1d(b.h, b.LR, -b.LZ, b.LR, b.LZ);
  for (std::size_t i = 1; i + 1 < t.size(); i++) b.add(b.LR, -b.LZ + t[i], VES_NODE_WALL);
}

/* Strip tolerances: a row stops at the first column where h(X) leaves [H/(1+TAU_H), H(1+TAU_H)]
 * (h varies across the strip) or where the shear k |H - H_adjacent row| passes TAU_S H (h
 * varies along the axis); where h is constant neither triggers and the lattice is exact hex. */
const double TAU_H = 0.2, TAU_S = 0.2;

/* The axis strip: levels z_j graded by h(0, z); rows at the levels (even columns k) and at
 * their midpoints (odd k), nodes at R = k (sqrt3/2) H_row, k <= K = ceil(2 axis_spacings/sqrt3);
 * each row truncated by TAU_H / TAU_S; nodes within 0.6 H of a wall dropped. */
void make_strip(Builder &b, double axis_spacings) {
  std::vector<double> t = place_1d(b.h, 0.0, -b.LZ, 0.0, b.LZ);
  std::vector<double> z(t.size());
  for (std::size_t j = 0; j < t.size(); j++) z[j] = -b.LZ + t[j];
  z.back() = b.LZ;
  const std::size_t J = z.size() - 1;
  const int K = (int)std::ceil(axis_spacings * 2.0 / SQ3);
  /* rows r = 0..2J: even r = level r/2 (centred spacing), odd r = midpoint of its interval */
  b.rz.resize(2 * J + 1), b.rH.resize(2 * J + 1), b.rend.assign(2 * J + 1, 0.0);
  for (std::size_t r = 0; r <= 2 * J; r++) {
    std::size_t j = r / 2;
    if (r % 2) {
      b.rz[r] = 0.5 * (z[j] + z[j + 1]), b.rH[r] = z[j + 1] - z[j];
    } else {
      b.rz[r] = z[j];
      b.rH[r] = j == 0 ? z[1] - z[0] : (j == J ? z[J] - z[J - 1] : 0.5 * (z[j + 1] - z[j - 1]));
    }
  }
  const double drop = 0.6; /* closer than 0.6 H to a wall: the wall row takes the place */
  for (std::size_t r = 1; r < 2 * J; r++) { /* rows 0 and 2J lie on the walls */
    double H = b.rH[r], Z = b.rz[r];
    double dH = std::max(std::fabs(H - b.rH[r - 1]), std::fabs(H - b.rH[r + 1]));
    for (int k = (int)(r % 2); k <= K; k += 2) {
      double R = k * (SQ3 / 2) * H;
      if (k == 0) { /* the axis: R exactly 0 */
        if (!b.is_reserved(0.0, Z)) b.add(0.0, Z, VES_NODE_AXIS | VES_NODE_LATTICE);
        continue;
      }
      double hX = b.h(R, Z);
      if (hX > (1 + TAU_H) * H || hX * (1 + TAU_H) < H || k * dH > TAU_S * H) break;
      if (std::min({Z + b.LZ, b.LZ - Z, b.LR - R}) < drop * H) break;
      if (b.is_reserved(R, Z)) continue; /* the caller's band nodes are there */
      b.add(R, Z, VES_NODE_LATTICE);
      b.rend[r] = R;
    }
  }
  /* wall rows: their "last node" is the wall itself (free nodes stay 0.5 h off the wall) */
}

/* A leaf cell of the sampling quadtree with its expected node count. */
struct Cell {
  double R0, Z0, dR, dZ, c;
};

/* Quadtree of the box, refined until cells are <= h/2; leaves in Morton order. */
void quadtree(const Builder &b, double R0, double Z0, double dR, double dZ, int depth,
              std::vector<Cell> &leaves, double &visits) {
  if (++visits > 8 * MAX_NODES) throw Too_many();
  double hmin = INFINITY;
  double hv[4];
  for (int i = 0; i < 4; i++) { /* 2x2 interior sample points */
    double R = R0 + (0.25 + 0.5 * (i % 2)) * dR, Z = Z0 + (0.25 + 0.5 * (i / 2)) * dZ;
    hv[i] = b.h(R, Z);
    hmin = std::min(hmin, hv[i]);
  }
  if (std::max(dR, dZ) > 0.5 * hmin && depth < 30) {
    int nR = dR > 1.5 * dZ ? 2 : (dZ > 1.5 * dR ? 1 : 2);
    int nZ = dZ > 1.5 * dR ? 2 : (dR > 1.5 * dZ ? 1 : 2);
    for (int j = 0; j < nZ; j++)
      for (int i = 0; i < nR; i++)
        quadtree(b, R0 + i * dR / nR, Z0 + j * dZ / nZ, dR / nR, dZ / nZ, depth + 1, leaves,
                 visits);
    return;
  }
  double c = 0.0;
  for (int i = 0; i < 4; i++) {
    double R = R0 + (0.25 + 0.5 * (i % 2)) * dR, Z = Z0 + (0.25 + 0.5 * (i / 2)) * dZ;
    if (b.in_free(R, Z, hv[i])) c += 0.25 * dR * dZ * 2.0 / (SQ3 * hv[i] * hv[i]); /* hex density */
  }
  if (c > 0.0) leaves.push_back(Cell{R0, Z0, dR, dZ, c});
}

/* Initial free nodes: systematic sampling of the leaves, N ~ int 2/(sqrt3 h^2) over the free
 * region. */
void sample_free(Builder &b, Rng &rng) {
  std::vector<Cell> leaves;
  double visits = 0.0;
  quadtree(b, 0.0, -b.LZ, b.LR, 2 * b.LZ, 0, leaves, visits);
  double acc = rng.uniform();
  for (const Cell &cl : leaves) {
    acc += cl.c;
    while (acc >= 1.0) {
      acc -= 1.0;
      for (int tries = 0; tries < 32; tries++) {
        double R = cl.R0 + rng.uniform() * cl.dR, Z = cl.Z0 + rng.uniform() * cl.dZ;
        if (b.in_free(R, Z)) {
          b.add(R, Z, 0);
          break;
        }
      }
    }
  }
}

/* Sutherland-Hodgman: keep the part of polygon p with s*(coord_i - v) <= 0. */
void clip(std::vector<double> &p, std::vector<double> &tmp, int i, double v, double s) {
  tmp.clear();
  std::size_t m = p.size() / 2;
  for (std::size_t a = 0; a < m; a++) {
    std::size_t b = (a + 1) % m;
    double fa = s * (p[2 * a + i] - v), fb = s * (p[2 * b + i] - v);
    if (fa <= 0) tmp.push_back(p[2 * a]), tmp.push_back(p[2 * a + 1]);
    if ((fa < 0 && fb > 0) || (fa > 0 && fb < 0)) {
      double t = fa / (fa - fb);
      tmp.push_back(p[2 * a] + t * (p[2 * b] - p[2 * a]));
      tmp.push_back(p[2 * a + 1] + t * (p[2 * b + 1] - p[2 * a + 1]));
    }
  }
  p.swap(tmp);
}

/* Lloyd: move each free node to the rho-weighted centroid of its Voronoi cell (clipped to
 * the box), rho = h^-RHO_EXP; fixed nodes stay. Stops at max move < 1e-3 h. The cells of
 * an iteration are independent reads of one triangulation: they run on the OpenMP threads
 * (a node's new position is its own, the max move order-free: the same nodes for any
 * thread count). */
void lloyd(Builder &b, int nfixed, int iters) {
  const int n = (int)b.flag.size();
  std::vector<DT::Vertex_handle> vh((std::size_t)n);
  /* degree-2 rule on a triangle: barycentres (2/3, 1/6, 1/6) and permutations, weights 1/3 */
  const double bw[3][3] = {
      {2. / 3, 1. / 6, 1. / 6}, {1. / 6, 2. / 3, 1. / 6}, {1. / 6, 1. / 6, 2. / 3}};
  for (int it = 0; it < iters; it++) {
    DT dt;
    if (build_dt(n, b.x.data(), dt) != VES_OK) throw Geom_error(); /* two nodes collapsed */
    for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v) vh[v->info()] = v;
    double maxmove = 0.0;
    std::vector<double> nx(b.x);
    /* an exception cannot leave the parallel region: caught, rethrown after it */
    bool bad = false, oom = false;
#pragma omp parallel reduction(max : maxmove) reduction(|| : bad, oom)
    {
      std::vector<double> poly, tmp;
#pragma omp for schedule(dynamic, 256)
      for (int a = nfixed; a < n; a++) {
        try {
          DT::Face_circulator fc = dt.incident_faces(vh[a]), done = fc;
          poly.clear();
          bool ok = true;
          do {
            if (dt.is_infinite(fc)) {
              ok = false;
              break;
            }
            Point_2 c = dt.circumcenter(fc);
            poly.push_back(c.x()), poly.push_back(c.y());
          } while (++fc != done);
          if (!ok) continue;
          clip(poly, tmp, 0, b.LR, 1.0), clip(poly, tmp, 0, 0.0, -1.0);
          clip(poly, tmp, 1, b.LZ, 1.0), clip(poly, tmp, 1, -b.LZ, -1.0);
          double Ra = b.x[2 * a], Za = b.x[2 * a + 1];
          double M = 0.0, MR = 0.0, MZ = 0.0; /* int rho, int rho X over the cell */
          std::size_t m = poly.size() / 2;
          for (std::size_t i = 0; i < m; i++) { /* fan triangles (X_a, c_i, c_i+1) */
            std::size_t j = (i + 1) % m;
            double R1 = poly[2 * i], Z1 = poly[2 * i + 1], R2 = poly[2 * j], Z2 = poly[2 * j + 1];
            double A = 0.5 * ((R1 - Ra) * (Z2 - Za) - (R2 - Ra) * (Z1 - Za));
            for (int q = 0; q < 3; q++) {
              double R = bw[q][0] * Ra + bw[q][1] * R1 + bw[q][2] * R2;
              double Z = bw[q][0] * Za + bw[q][1] * Z1 + bw[q][2] * Z2;
              double w = A / 3.0 * std::pow(b.h(std::max(R, 0.0), Z), -RHO_EXP);
              M += w, MR += w * R, MZ += w * Z;
            }
          }
          if (!(M > 0.0)) continue;
          double dR = MR / M - Ra, dZ = MZ / M - Za;
          /* keep the node in the free region: halve the move until inside, else stay */
          for (int half = 0; half < 5; half++, dR *= 0.5, dZ *= 0.5) {
            if (b.in_free(Ra + dR, Za + dZ)) {
              nx[2 * a] = Ra + dR, nx[2 * a + 1] = Za + dZ;
              maxmove = std::max(maxmove, std::hypot(dR, dZ) / b.h(Ra, Za));
              break;
            }
          }
        } catch (const Bad_sizing &) {
          bad = true;
        } catch (const std::bad_alloc &) {
          oom = true;
        }
      }
    }
    if (bad) throw Bad_sizing();
    if (oom) throw std::bad_alloc();
    b.x.swap(nx);
    if (maxmove < 1e-3) break;
  }
}

/* malloc'd copy of a vector (nullptr on failure, or for an empty vector a 1-byte block). */
template <class T> T *c_copy(const std::vector<T> &v) {
  T *p = (T *)std::malloc(sizeof(T) * std::max<std::size_t>(1, v.size()));
  if (p && !v.empty()) std::memcpy(p, v.data(), sizeof(T) * v.size());
  return p;
}

} // namespace

extern "C" void ves_nodes_params_default(ves_nodes_params *par) {
  if (!par) return;
  par->axis_spacings = 10.0;
  par->lloyd_iter = 60;
  par->seed = 1u;
  par->nfixed = 0;
  par->xfixed = nullptr;
  par->fixed_flag = nullptr;
  par->reserved = nullptr;
  par->reserved_ctx = nullptr;
}

extern "C" ves_status ves_nodes_generate(const ves_nodes_params *par, ves_nodes **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = nullptr;
  VES_CHECK(par && par->h, VES_ERR_ARG);
  VES_CHECK(std::isfinite(par->LR) && par->LR > 0 && std::isfinite(par->LZ) && par->LZ > 0,
            VES_ERR_ARG);
  VES_CHECK(std::isfinite(par->axis_spacings) && par->axis_spacings > 0, VES_ERR_ARG);
  VES_CHECK(par->lloyd_iter >= 0, VES_ERR_ARG);
  VES_CHECK(par->nfixed >= 0 && (par->nfixed == 0 || (par->xfixed && par->fixed_flag)),
            VES_ERR_ARG);
  for (int a = 0; a < par->nfixed; a++) { /* caller's nodes strictly inside the box */
    double R = par->xfixed[2 * a], Z = par->xfixed[2 * a + 1];
    VES_CHECK(std::isfinite(R) && std::isfinite(Z) && R >= 0 && R < par->LR &&
                  std::fabs(Z) < par->LZ,
              VES_ERR_ARG);
  }
  ves_nodes *nd = nullptr;
  try {
    Builder b{par->LR, par->LZ,       Sizing{par->h, par->h_ctx}, {}, {},
              {},      par->reserved, par->reserved_ctx,          {}, {}};
    Rng rng{(std::uint64_t)par->seed * 0x2545F4914F6CDD1Dull + 0x1234567ull};
    make_walls(b);
    make_strip(b, par->axis_spacings);
    for (int a = 0; a < par->nfixed; a++) /* the caller's fixed nodes */
      b.add(par->xfixed[2 * a], par->xfixed[2 * a + 1], par->fixed_flag[a] | VES_NODE_BAND);
    int nfixed = (int)b.flag.size();
    sample_free(b, rng);
    if ((double)b.flag.size() > MAX_NODES) throw Too_many();
    lloyd(b, nfixed, par->lloyd_iter);

    const int n = (int)b.flag.size();
    std::vector<int> ghost_of;
    std::vector<double> xe(b.x);
    for (int a = 0; a < n; a++)
      if (b.x[2 * a] > 0.0) { /* ghost (-R_a, Z_a) */
        ghost_of.push_back(a);
        xe.push_back(-b.x[2 * a]), xe.push_back(b.x[2 * a + 1]);
      }
    std::vector<double> he(xe.size() / 2);
    VES_CALL(ves_geom_spacing((int)he.size(), xe.data(), he.data()));
    he.resize((std::size_t)n);

    nd = (ves_nodes *)std::calloc(1, sizeof(ves_nodes));
    if (!nd) return VES_ERR_ALLOC;
    nd->LR = par->LR, nd->LZ = par->LZ, nd->n = n, nd->ng = (int)ghost_of.size();
    nd->x = c_copy(b.x), nd->h = c_copy(he), nd->flag = c_copy(b.flag);
    nd->ghost_of = c_copy(ghost_of);
    if (!nd->x || !nd->h || !nd->flag || !nd->ghost_of) {
      ves_nodes_destroy(&nd);
      return VES_ERR_ALLOC;
    }
    *out = nd;
    return VES_OK;
  } catch (...) {
    ves_nodes_destroy(&nd);
    return status_of_exception();
  }
}

extern "C" void ves_nodes_destroy(ves_nodes **nodes) {
  if (!nodes || !*nodes) return;
  std::free((*nodes)->x), std::free((*nodes)->h), std::free((*nodes)->flag);
  std::free((*nodes)->ghost_of);
  std::free(*nodes);
  *nodes = nullptr;
}

extern "C" void ves_nodes_extended(const ves_nodes *nodes, double *xe) {
  if (!nodes || !xe) return;
  std::memcpy(xe, nodes->x, sizeof(double) * 2 * (std::size_t)nodes->n);
  for (int k = 0; k < nodes->ng; k++) { /* ghost k = (-R, Z) of node ghost_of[k] */
    int a = nodes->ghost_of[k];
    xe[2 * (nodes->n + k)] = -nodes->x[2 * a];
    xe[2 * (nodes->n + k) + 1] = nodes->x[2 * a + 1];
  }
}
