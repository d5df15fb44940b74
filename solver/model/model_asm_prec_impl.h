/* vesica — the precision-dependent part of the triangle assembly
 * (model_assemble.c includes this file twice): the stacked B and its
 * products with the local Hessians (triangle_xy), the symmetric products
 * (upper_product) and the scatter of the triangle's block matrix into the
 * pattern (triangle_scatter), with ASM_REAL the type of X, Y and M (double,
 * or float for a matrix factored in single precision: model_assemble's
 * single), ASM_SFX(name) the functions' names for that type and ASM_GEMM
 * its BLAS product. The local Hessians (Hs) and the pattern's blocks (blk)
 * stay double: only the per-triangle products are rounded. No include
 * guard: included once per type. docs/design.md, "Discretization". */
/* The triangle's matrices B over its union, stacked point by point, and
 * their products with the local Hessians (workspace X, Y; nu x K
 * column-major: one contiguous column per row (p, k) of B, over the union
 * nodes j):
 *   Xr[(p nr + k) nu + j] = b_r(p, k; j),  Xz[(p nz + k) nu + j] = b_z(p, k; j)
 * (the folded table rows of map mp; zero where point p does not see node j),
 * Kr = NPT nr, Kz = NPT nz columns, and with cH_p = c_p d2e/dq2 at point p
 * split by the map into its rr, rz and zz parts,
 *   Yrr = Xr diag_p(cH_rr),  Yrz = Xz diag_p(cH_zr),  Yzz = Xz diag_p(cH_zz)
 * (axpys over the union, vectorized).
 * Hs holds the NPT local matrices (nl x nl each, c included). */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
ASM_SFX(triangle_xy_n)(const local_map *mp, const int nr, const int nz, const folded f[NPT],
                       const int *slot, int nu, const double *Hs, ASM_REAL *X, ASM_REAL *Y) {
  const int nl = mp->nl, Kr = NPT * nr, Kz = NPT * nz;
  ASM_REAL *Xr = X, *Xz = X + (size_t)Kr * nu;
  ASM_REAL *Yrr = Y, *Yrz = Y + (size_t)Kr * nu, *Yzz = Y + 2 * (size_t)Kr * nu;
  memset(X, 0, (size_t)(Kr + Kz) * nu * sizeof *X);
  for (int p = 0; p < NPT; p++) {
    const folded *fp = f + p;
    const int mu = fp->mu;
    for (int v = 0; v < mu; v++) {
      const int j = slot[fp->un[v]];
      for (int k = 0; k < nr; k++) Xr[(size_t)(p * nr + k) * nu + j] = fp->Tr[mp->rr[k] * mu + v];
      for (int k = 0; k < nz; k++) Xz[(size_t)(p * nz + k) * nu + j] = fp->Tz[mp->rz[k] * mu + v];
    }
  }
  for (int p = 0; p < NPT; p++) {
    const double *H = Hs + (size_t)p * nl * nl;
    const ASM_REAL *xr = Xr + (size_t)p * nr * nu, *xz = Xz + (size_t)p * nz * nu;
    for (int k = 0; k < nr; k++) { /* row (p, k) of Yrr and Yrz: axpys over the union */
      ASM_REAL *yrr = Yrr + (size_t)(p * nr + k) * nu, *yrz = Yrz + (size_t)(p * nr + k) * nu;
      for (int j = 0; j < nu; j++) yrr[j] = yrz[j] = 0.0;
      for (int l = 0; l < nr; l++) {
        const ASM_REAL h = (ASM_REAL)H[mp->qr[k] * nl + mp->qr[l]], *x = xr + (size_t)l * nu;
        OMP_SIMD
        for (int j = 0; j < nu; j++) yrr[j] += h * x[j];
      }
      for (int l = 0; l < nz; l++) {
        const ASM_REAL h = (ASM_REAL)H[mp->qr[k] * nl + mp->qz[l]], *x = xz + (size_t)l * nu;
        OMP_SIMD
        for (int j = 0; j < nu; j++) yrz[j] += h * x[j];
      }
    }
    for (int k = 0; k < nz; k++) {
      ASM_REAL *yzz = Yzz + (size_t)(p * nz + k) * nu;
      for (int j = 0; j < nu; j++) yzz[j] = 0.0;
      for (int l = 0; l < nz; l++) {
        const ASM_REAL h = (ASM_REAL)H[mp->qz[k] * nl + mp->qz[l]], *x = xz + (size_t)l * nu;
        OMP_SIMD
        for (int j = 0; j < nu; j++) yzz[j] += h * x[j];
      }
    }
  }
}

/* triangle_xy_n with the map's sizes as constants (the small products
 * unrolled). */
static void ASM_SFX(triangle_xy)(const local_map *mp, const folded f[NPT], const int *slot, int nu,
                                 const double *Hs, ASM_REAL *X, ASM_REAL *Y) {
  if (mp->nr == 6 && mp->nz == 5)
    ASM_SFX(triangle_xy_n)(mp, 6, 5, f, slot, nu, Hs, X, Y);
  else if (mp->nr == 3 && mp->nz == 2)
    ASM_SFX(triangle_xy_n)(mp, 3, 2, f, slot, nu, Hs, X, Y);
  else
    ASM_SFX(triangle_xy_n)(mp, mp->nr, mp->nz, f, slot, nu, Hs, X, Y);
}

/* Add the owned rows of the triangle's block matrix to the pattern: block
 * (U[i], U[j]), j <= i, with entries (rr, rz, zr, zz) =
 * (Mrr[j + i nu], Mrz[i + j nu], Mrz[j + i nu], Mzz[j + i nu]) (Mrr and Mzz
 * are symmetric: column i is read, rows j <= i, the triangle upper_product
 * forms), by one forward walk along the pattern row of U[i] (ascending, as
 * U is). Pairs of the union that share no point
 * are not in the pattern; their sums are exactly zero (X is zero where a
 * point does not see the node) and are skipped. */
static void ASM_SFX(triangle_scatter)(const ves_model *m, const int *U, int nu, int k,
                                      const ASM_REAL *M, double *blk) {
  const ves_pattern *pat = m->pat;
  const ASM_REAL *Mrr = M, *Mrz = M + (size_t)nu * nu, *Mzz = M + 2 * (size_t)nu * nu;
  for (int i = 0; i < nu; i++) {
    const int a = U[i];
    if (m->owner[a] != k) continue;
    const ASM_REAL *crr = Mrr + (size_t)i * nu, *czr = Mrz + (size_t)i * nu,
                   *czz = Mzz + (size_t)i * nu;
    int lo = pat->ptr[a], hi = pat->ptr[a + 1] - 1;
    while (lo < hi) { /* first column >= U[0] in row a */
      int mid = (lo + hi) / 2;
      if (pat->col[mid] < U[0])
        lo = mid + 1;
      else
        hi = mid;
    }
    for (int j = 0, t = lo; j <= i; j++) {
      const int b = U[j];
      while (pat->col[t] < b) t++; /* the diagonal (a, a) ends the walk */
      const double rz = Mrz[i + (size_t)j * nu];
      if (pat->col[t] != b) {
        assert(crr[j] == 0 && rz == 0 && czr[j] == 0 && czz[j] == 0);
        continue;
      }
      double *dst = blk + 4 * (size_t)t;
      dst[0] += crr[j], dst[1] += rz, dst[2] += czr[j], dst[3] += czz[j];
    }
  }
}

/* The upper triangle (rows i <= column j, column-major, leading dimension
 * nu) of the symmetric M = X Y^T (X, Y: nu x K, column-major), by
 * ASM_PANELS column panels, panel c its columns [c0, c1) over rows [0, c1):
 * (P + 1) / 2P of the full product's flops (5/8 for 4 panels). Entries
 * below the diagonal are partly left unset: triangle_scatter reads Mrr and
 * Mzz only at rows <= column. Each entry is the same dot product over K
 * as in the full product (the Hessian is bitwise the same:
 * docs/results.md, "Performance and its scaling"). */
static void ASM_SFX(upper_product)(int nu, int K, const ASM_REAL *X, const ASM_REAL *Y,
                                   ASM_REAL *M) {
  for (int c = 0; c < ASM_PANELS; c++) {
    const int c0 = c * nu / ASM_PANELS, c1 = (c + 1) * nu / ASM_PANELS;
    if (c1 > c0) /* M[0:c1, c0:c1] = X[0:c1, :] Y[c0:c1, :]^T */
      ASM_GEMM(CblasColMajor, CblasNoTrans, CblasTrans, c1, c1 - c0, K, 1.0, X, nu, Y + c0, nu, 0.0,
               M + (size_t)c0 * nu, nu);
  }
}

/* The block matrix of a triangle from its points' local matrices Hs (c
 * included) over its union U (nu nodes), its owned rows (slab k) added to
 * blk: the three products of triangle_blocks in ASM_REAL. */
static void ASM_SFX(triangle_products)(const ves_model *m, model_ws *w, const local_map *mp,
                                       const folded f[NPT], const int *U, int nu, const double *Hs,
                                       int k, double *blk) {
  ASM_REAL *X = (ASM_REAL *)w->X, *Y = (ASM_REAL *)w->Y, *M = (ASM_REAL *)w->M;
  ASM_SFX(triangle_xy)(mp, f, w->slot, nu, Hs, X, Y);
  const int Kr = NPT * mp->nr, Kz = NPT * mp->nz;
  const ASM_REAL *Xr = X, *Xz = X + (size_t)Kr * nu;
  const ASM_REAL *Yrr = Y, *Yrz = Y + (size_t)Kr * nu, *Yzz = Y + 2 * (size_t)Kr * nu;
  ASM_SFX(upper_product)(nu, Kr, Xr, Yrr, M); /* Mrr = Xr Yrr^T, upper triangle */
  ASM_GEMM(CblasColMajor, CblasNoTrans, CblasTrans, nu, nu, Kr, 1.0, Xr, nu, Yrz, nu, 0.0,
           M + (size_t)nu * nu, nu);                                /* Mrz = Xr Yrz^T */
  ASM_SFX(upper_product)(nu, Kz, Xz, Yzz, M + 2 * (size_t)nu * nu); /* Mzz, upper triangle */
  ASM_SFX(triangle_scatter)(m, U, nu, k, M, blk);
}
