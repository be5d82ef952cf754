/* The registration's deterministic RNG and subsampling (lib/fit/stage.h). */
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
