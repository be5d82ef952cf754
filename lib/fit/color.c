/* Colour transfer of the registration: each registered vertex takes the inverse-distance
 * weighted colour of its (up to) 4 nearest scan points (lib/fit/stage.h). */
#include <math.h>
#include <stdlib.h>

#include "fit/stage.h"

static spx_status transfer(spx_ctx *ctx, const spx_mesh *scan, const float *Sc, const spx_fit_result *r,
                           const float *Vs, int threads, float *col) {
  enum { KC = 4 };
  int k = scan->nv < KC ? scan->nv : KC;
  spx_kdtree *t = NULL;
  spx_status st = spx_fit_kd_build(ctx, Sc, scan->nv, &t);
  if (st) return st;
  int32_t *idx = spx_alloc_array(ctx, (size_t)r->nv * KC, sizeof(int32_t), "colour transfer");
  float *d2 = spx_alloc_array(ctx, (size_t)r->nv * KC, sizeof(float), "colour transfer");
  if (!idx || !d2) st = SPX_E_NOMEM;
  if (!st) st = spx_fit_kd_query(ctx, t, Vs, r->nv, k, idx, d2, threads);
  for (int32_t i = 0; !st && i < r->nv; i++) {
    double acc[3] = {0, 0, 0}, ws = 0;
    for (int j = 0; j < k; j++) {
      double wgt = 1.0 / (sqrt(d2[i * k + j]) + 1e-3);
      const float *c = scan->col + (size_t)idx[i * k + j] * 3;
      for (int d = 0; d < 3; d++) acc[d] += wgt * c[d];
      ws += wgt;
    }
    for (int d = 0; d < 3; d++) col[i * 3 + d] = (float)(acc[d] / ws);
  }
  free(idx), free(d2);
  spx_kdtree_free(t);
  return st;
}

spx_status spx_fit_transfer_colors(spx_ctx *ctx, const spx_mesh *scan, const float *Sc, int threads, spx_fit_result *r) {
  int32_t nv = r->nv;
  float *Vs = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(float), "colour transfer");
  r->colors = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(float), "colour transfer");
  if (!Vs || !r->colors) {
    free(Vs);
    return SPX_E_NOMEM;
  }
  for (int32_t i = 0; i < nv * 3; i++) Vs[i] = (float)(r->verts_scan[i] * r->unit_scale);
  spx_status st = transfer(ctx, scan, Sc, r, Vs, threads, r->colors);
  free(Vs);
  return st;
}
