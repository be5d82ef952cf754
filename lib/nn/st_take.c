/* Checked float32 tensor reads from safetensors files (lib/nn/st_take.h). */
#include "nn/st_take.h"

#include "core/internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

void spx_nn_shape_str(char *buf, size_t cap, int ndim, const int64_t *shape) {
  size_t n = (size_t)snprintf(buf, cap, "[");
  for (int k = 0; k < ndim && n < cap; k++) n += (size_t)snprintf(buf + n, cap - n, k ? ", %lld" : "%lld", (long long)shape[k]);
  if (n < cap) snprintf(buf + n, cap - n, "]");
}

spx_status spx_nn_st_find_shaped(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *name, int ndim,
                                 const int64_t *shape, const spx_st_tensor **t) {
  char want[96], got[96];
  spx_nn_shape_str(want, sizeof want, ndim, shape);
  *t = spx_st_find(f, name);
  if (!*t) return spx_fail(ctx, SPX_E_FORMAT, "%s: missing tensor %s (expected shape %s)", path, name, want);
  int same = (*t)->ndim == ndim;
  for (int k = 0; k < ndim && same; k++) same = (*t)->shape[k] == shape[k];
  if (!same) {
    spx_nn_shape_str(got, sizeof got, (*t)->ndim, (*t)->shape);
    return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s has shape %s, expected %s", path, name, got, want);
  }
  return SPX_OK;
}

spx_status spx_nn_st_take_f32(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *name, int ndim,
                              const int64_t *shape, float *dst) {
  const spx_st_tensor *t;
  spx_status st = spx_nn_st_find_shaped(ctx, path, f, name, ndim, shape, &t);
  if (st) return st;
  if (t->dtype != SPX_F32)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s has dtype %s, expected F32", path, name, spx_dtype_name(t->dtype));
  size_t n = t->nbytes / 4;
  memcpy(dst, t->data, n * 4);
  for (size_t i = 0; i < n; i++)
    if (!isfinite(dst[i])) return spx_fail(ctx, SPX_E_NUMERIC, "%s: tensor %s holds NaN or Inf", path, name);
  return SPX_OK;
}
