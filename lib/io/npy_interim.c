/* INTERIM minimal .npy parser so the npz/body work builds before branch h/io (lib/io/npy.c,
 * the real implementation) is merged. Deleted in the merge commit. */
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/npy.h"

int64_t spx_array_numel(const spx_array *a) {
  int64_t n = 1;
  for (int i = 0; i < a->ndim; i++) n *= a->shape[i];
  return n;
}
void spx_array_free(spx_array *a) {
  if (!a) return;
  free(a->data);
  memset(a, 0, sizeof *a);
}
spx_status spx_npy_parse(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_array *out) {
  const unsigned char *d = data;
  memset(out, 0, sizeof *out);
  if (size < 10 || memcmp(d, "\x93NUMPY", 6)) return spx_fail(ctx, SPX_E_FORMAT, "%s: not an npy", name);
  size_t hl, ho;
  if (d[6] == 1) hl = d[8] | (d[9] << 8), ho = 10;
  else {
    if (size < 12) return spx_fail(ctx, SPX_E_FORMAT, "%s: short", name);
    hl = d[8] | (d[9] << 8) | ((size_t)d[10] << 16) | ((size_t)d[11] << 24), ho = 12;
  }
  if (hl > 65536 || hl > size - ho) return spx_fail(ctx, SPX_E_FORMAT, "%s: bad header", name);
  char h[65537];
  memcpy(h, d + ho, hl);
  h[hl] = 0;
  const char *p = strstr(h, "'descr'");
  if (!p || !(p = strchr(p + 7, '\''))) return spx_fail(ctx, SPX_E_FORMAT, "%s: no descr", name);
  p++;
  static const struct { const char *s; spx_dtype t; } tab[] = {
      {"<f4", SPX_F32}, {"<f8", SPX_F64}, {"|u1", SPX_U8}, {"<i4", SPX_I32}, {"<i8", SPX_I64},
      {"<u4", SPX_U32}, {"|i1", SPX_I8}, {"<u8", SPX_U64}, {"<f2", SPX_F16}, {"|b1", SPX_BOOL}};
  int found = 0;
  for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++)
    if (!strncmp(p, tab[i].s, 3) && p[3] == '\'') out->dtype = tab[i].t, found = 1;
  if (!found) return spx_fail(ctx, SPX_E_FORMAT, "%s: unsupported descr", name);
  if (!strstr(h, "'fortran_order': False")) return spx_fail(ctx, SPX_E_FORMAT, "%s: fortran order", name);
  p = strstr(h, "'shape'");
  if (!p || !(p = strchr(p, '('))) return spx_fail(ctx, SPX_E_FORMAT, "%s: no shape", name);
  p++;
  size_t numel = 1;
  while (*p && *p != ')') {
    while (*p == ' ' || *p == ',') p++;
    if (*p == ')') break;
    char *e;
    long long v = strtoll(p, &e, 10);
    if (e == p || v < 0 || out->ndim >= SPX_NPY_MAX_DIMS || !spx_mul_size(numel, (size_t)v, &numel))
      return spx_fail(ctx, SPX_E_FORMAT, "%s: bad shape", name);
    out->shape[out->ndim++] = v;
    p = e;
  }
  size_t nb;
  if (!spx_mul_size(numel, spx_dtype_size(out->dtype), &nb) || nb != size - ho - hl)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: size mismatch", name);
  out->data = malloc(nb ? nb : 1);
  if (!out->data) return spx_fail(ctx, SPX_E_NOMEM, "%s: oom", name);
  memcpy(out->data, d + ho + hl, nb);
  out->nbytes = nb;
  return SPX_OK;
}
spx_status spx_array_to_f32(spx_ctx *ctx, const spx_array *a, float **out) {
  size_t n = (size_t)spx_array_numel(a);
  float *f = spx_alloc_array(ctx, n ? n : 1, sizeof(float), "array");
  if (!f) return SPX_E_NOMEM;
  for (size_t i = 0; i < n; i++) {
    const unsigned char *b = (const unsigned char *)a->data;
    switch (a->dtype) {
      case SPX_F32: f[i] = ((const float *)(const void *)b)[i]; break;
      case SPX_F64: f[i] = (float)((const double *)(const void *)b)[i]; break;
      case SPX_I32: f[i] = (float)((const int32_t *)(const void *)b)[i]; break;
      case SPX_I64: f[i] = (float)((const int64_t *)(const void *)b)[i]; break;
      case SPX_U32: f[i] = (float)((const uint32_t *)(const void *)b)[i]; break;
      case SPX_U8: f[i] = (float)b[i]; break;
      default: free(f); return spx_fail(ctx, SPX_E_UNSUPPORTED, "array: dtype");
    }
  }
  *out = f;
  return SPX_OK;
}
