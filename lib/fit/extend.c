/* The screened-harmonic extension of a per-vertex field over a mesh (lib/fit/stage.h): values
 * known on some vertices are continued smoothly over the others, the way a membrane spans a
 * frame. Unknown values x solve, for every unknown vertex i with neighbours N(i),
 *   (deg_i (1 + eps)) x_i - sum_{j in N(i), unknown} x_j = sum_{j in N(i), known} f_j,
 * a symmetric positive definite system (eps > 0 screens it: far from every known vertex the
 * field decays to 0, and a region with no known vertex at all is 0), solved by conjugate
 * gradients. The registration continues the seen side's offsets from the body model over the
 * side no camera saw (stage_free.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/stage.h"

/* y = A x over the unknown vertices (x, y: nv entries; known ones ignored and left 0). */
static void apply(const spx_adj *nb, const unsigned char *known, double eps, const double *x, double *y) {
  for (int32_t i = 0; i < nb->n; i++) {
    if (known[i]) {
      y[i] = 0;
      continue;
    }
    int32_t deg = nb->start[i + 1] - nb->start[i];
    double s = deg * (1 + eps) * x[i];
    for (int32_t k = nb->start[i]; k < nb->start[i + 1]; k++)
      if (!known[nb->idx[k]]) s -= x[nb->idx[k]];
    y[i] = s;
  }
}

static double dot(const double *a, const double *b, int32_t n) {
  double s = 0;
  for (int32_t i = 0; i < n; i++) s += a[i] * b[i];
  return s;
}

spx_status spx_fit_harmonic_fill(spx_ctx *ctx, const spx_adj *nb, const unsigned char *known, double eps, int maxit,
                                 double *f) {
  int32_t n = nb->n;
  double *r = spx_alloc_array(ctx, (size_t)n, 4 * sizeof(double), "harmonic fill");
  if (!r) return SPX_E_NOMEM;
  double *p = r + n, *q = r + 2 * (size_t)n, *x = r + 3 * (size_t)n;
  /* right-hand side: the known neighbours' values; start from 0 */
  for (int32_t i = 0; i < n; i++) {
    double b = 0;
    if (!known[i])
      for (int32_t k = nb->start[i]; k < nb->start[i + 1]; k++)
        if (known[nb->idx[k]]) b += f[nb->idx[k]];
    r[i] = b, p[i] = b, x[i] = 0;
  }
  double rr = dot(r, r, n), r0 = rr;
  for (int it = 0; it < maxit && rr > 1e-20 * (r0 > 0 ? r0 : 1); it++) {
    apply(nb, known, eps, p, q);
    double pq = dot(p, q, n);
    if (!(pq > 0)) break;
    double a = rr / pq;
    for (int32_t i = 0; i < n; i++) x[i] += a * p[i], r[i] -= a * q[i];
    double rn = dot(r, r, n);
    for (int32_t i = 0; i < n; i++) p[i] = r[i] + (rn / rr) * p[i];
    rr = rn;
  }
  for (int32_t i = 0; i < n; i++)
    if (!known[i]) f[i] = x[i];
  free(r);
  return SPX_OK;
}
