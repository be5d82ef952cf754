/* The registration's deterministic RNG, subsampling and the scan points' area weights
 * (lib/fit/stage.h). */
#include <math.h>
#include <stdlib.h>

#include "fit/stage.h"

uint64_t spx_fit_rng_next(uint64_t *s) {
  *s ^= *s >> 12, *s ^= *s << 25, *s ^= *s >> 27;
  return *s * 2685821657736338717ULL;
}

int32_t *spx_fit_subsample(spx_ctx *ctx, int32_t n, int32_t k, uint64_t seed, int32_t *out_k) {
  if (k <= 0 || k > n) k = n;
  int32_t *idx = spx_alloc_array(ctx, (size_t)n, sizeof(int32_t), "scan subsample");
  if (!idx) return NULL;
  for (int32_t i = 0; i < n; i++) idx[i] = i;
  uint64_t s = seed ? seed : 1;
  /* shuffled even when k == n: callers take prefixes of it, and scans from depth images come in
   * raster order (a prefix would be the top rows) */
  for (int32_t i = 0; i < k; i++) {
    int32_t j = i + (int32_t)(spx_fit_rng_next(&s) % (uint64_t)(n - i));
    int32_t t = idx[i];
    idx[i] = idx[j], idx[j] = t;
  }
  *out_k = k;
  return idx;
}

static int cmp_float(const void *a, const void *b) {
  float x = *(const float *)a, y = *(const float *)b;
  return x < y ? -1 : x > y;
}

spx_status spx_fit_area_weights(spx_ctx *ctx, const float *Q, int32_t n, int k, int threads, float *wt) {
  for (int32_t i = 0; i < n; i++) wt[i] = 1.0f;
  if (n <= k) return SPX_OK;
  spx_kdtree *t = NULL;
  int32_t *idx = spx_alloc_array(ctx, (size_t)n, (size_t)(k + 1) * sizeof(int32_t), "scan area weights");
  float *d2 = spx_alloc_array(ctx, (size_t)n, (size_t)(k + 1) * sizeof(float), "scan area weights");
  float *r2 = spx_alloc_array(ctx, (size_t)n, sizeof(float), "scan area weights"); /* sorted k-th distances */
  spx_status st = !idx || !d2 || !r2 ? SPX_E_NOMEM : spx_fit_kd_build(ctx, Q, n, &t);
  if (!st) st = spx_fit_kd_query(ctx, t, Q, n, k + 1, idx, d2, threads); /* the point itself and k others */
  if (!st) {
    for (int32_t i = 0; i < n; i++) r2[i] = wt[i] = d2[(size_t)i * (k + 1) + k];
    qsort(r2, (size_t)n, sizeof *r2, cmp_float);
    double med = r2[n / 2], sum = 0;
    for (int32_t i = 0; i < n; i++) {
      double v = med > 0 ? wt[i] / med : 1.0;
      wt[i] = (float)fmax(1.0 / SPX_FIT_AREA_W_MAX, fmin(SPX_FIT_AREA_W_MAX, v));
      sum += wt[i];
    }
    for (int32_t i = 0; i < n; i++) wt[i] = (float)(wt[i] * n / sum);
  }
  spx_kdtree_free(t);
  free(idx), free(d2), free(r2);
  return st;
}
