/* The public device tensor (smplpix/device.h): a float32 NCHW buffer on the open device. */
#include "cl/tensor.h"

#include <stdlib.h>

static int count_of(int n, int c, int h, int w, size_t *out) {
  if (n < 1 || c < 1 || h < 1 || w < 1) return 0;
  size_t a, b;
  return spx_mul_size((size_t)n, (size_t)c, &a) && spx_mul_size((size_t)h, (size_t)w, &b) && spx_mul_size(a, b, out) &&
         *out <= SIZE_MAX / sizeof(float);
}

spx_status spx_device_tensor_check(spx_ctx *ctx, const spx_device_tensor *t, const char *what) {
  if (!t) return spx_fail(ctx, SPX_E_ARG, "%s: NULL device tensor", what);
  if (t->ctx != ctx) return spx_fail(ctx, SPX_E_ARG, "%s: the device tensor belongs to another context", what);
  return SPX_OK;
}

spx_status spx_device_tensor_create(spx_ctx *ctx, int n, int c, int h, int w, spx_device_tensor **out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "spx_device_tensor_create: NULL output");
  *out = NULL;
  size_t count;
  if (!count_of(n, c, h, w, &count))
    return spx_fail(ctx, SPX_E_ARG, "spx_device_tensor_create: shape %dx%dx%dx%d (every dimension must be >= 1)", n, c,
                    h, w);
  spx_status st = spx_cl_require(ctx, "spx_device_tensor_create");
  if (st) return st;
  spx_device_tensor *t = calloc(1, sizeof *t);
  if (!t) return spx_fail(ctx, SPX_E_NOMEM, "spx_device_tensor_create: out of memory");
  if ((st = spx_cl_alloc(ctx, count * sizeof(float), "device tensor", &t->mem))) {
    free(t);
    return st;
  }
  t->ctx = ctx;
  t->capacity = count;
  t->shape[0] = n, t->shape[1] = c, t->shape[2] = h, t->shape[3] = w;
  *out = t;
  return SPX_OK;
}

void spx_device_tensor_free(spx_device_tensor *t) {
  if (!t) return;
  spx_cl_free(&t->mem);
  free(t);
}

void spx_device_tensor_shape(const spx_device_tensor *t, int shape[4]) {
  for (int i = 0; i < 4; i++) shape[i] = t ? t->shape[i] : 0;
}

size_t spx_device_tensor_count(const spx_device_tensor *t) {
  if (!t) return 0;
  return (size_t)t->shape[0] * (size_t)t->shape[1] * (size_t)t->shape[2] * (size_t)t->shape[3];
}

size_t spx_device_tensor_capacity(const spx_device_tensor *t) { return t ? t->capacity : 0; }

spx_status spx_device_tensor_reshape(spx_ctx *ctx, spx_device_tensor *t, int n, int c, int h, int w) {
  spx_status st = spx_device_tensor_check(ctx, t, "spx_device_tensor_reshape");
  if (st) return st;
  size_t count;
  if (!count_of(n, c, h, w, &count) || count > t->capacity)
    return spx_fail(ctx, SPX_E_ARG, "spx_device_tensor_reshape: shape %dx%dx%dx%d does not fit the tensor's %zu floats",
                    n, c, h, w, t->capacity);
  t->shape[0] = n, t->shape[1] = c, t->shape[2] = h, t->shape[3] = w;
  return SPX_OK;
}

spx_status spx_device_tensor_write(spx_ctx *ctx, spx_device_tensor *t, const float *src) {
  spx_status st = spx_device_tensor_check(ctx, t, "spx_device_tensor_write");
  if (st) return st;
  if (!src) return spx_fail(ctx, SPX_E_ARG, "spx_device_tensor_write: NULL source");
  return spx_cl_write(ctx, t->mem, 0, spx_device_tensor_count(t) * sizeof(float), src);
}

spx_status spx_device_tensor_read(spx_ctx *ctx, const spx_device_tensor *t, float *dst) {
  spx_status st = spx_device_tensor_check(ctx, t, "spx_device_tensor_read");
  if (st) return st;
  if (!dst) return spx_fail(ctx, SPX_E_ARG, "spx_device_tensor_read: NULL destination");
  return spx_cl_read(ctx, t->mem, 0, spx_device_tensor_count(t) * sizeof(float), dst);
}
