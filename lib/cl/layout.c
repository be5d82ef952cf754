/* HWC <-> NCHW conversion on the device (kernels/layout.cl), with a plain-C reference. */
#include "cl/cl_internal.h"
#include "cl/layout.h"

static spx_status run_layout(spx_ctx *ctx, spx_kernel_id kid, cl_mem src, cl_mem dst, int n, int c, int h, int w) {
  cl_kernel k;
  const char *kname = spx_cl_kernel_name(kid);
  spx_status st = spx_cl_kernel(ctx, kid, &k);
  if (st) return st;
  cl_int e = SPX_ARG(k, 0, src) | SPX_ARG(k, 1, dst) | SPX_ARG(k, 2, n) | SPX_ARG(k, 3, c) | SPX_ARG(k, 4, h) |
             SPX_ARG(k, 5, w);
  if ((st = spx_cl_check(ctx, e, kname))) return st;
  size_t g = (size_t)n * c * h * w, l = (size_t)ctx->tune.wg;
  return spx_cl_run(ctx, k, 1, &g, &l, kname);
}

spx_status spx_cl_hwc_to_nchw(spx_ctx *ctx, cl_mem src, cl_mem dst, int n, int c, int h, int w) {
  return run_layout(ctx, SPX_K_HWC_TO_NCHW, src, dst, n, c, h, w);
}
spx_status spx_cl_nchw_to_hwc(spx_ctx *ctx, cl_mem src, cl_mem dst, int n, int c, int h, int w) {
  return run_layout(ctx, SPX_K_NCHW_TO_HWC, src, dst, n, c, h, w);
}

void spx_ref_hwc_to_nchw(const float *src, float *dst, int n, int c, int h, int w) {
  for (int b = 0; b < n; b++)
    for (int ch = 0; ch < c; ch++)
      for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
          dst[((b * c + ch) * h + y) * w + x] = src[((b * h + y) * w + x) * c + ch];
}
void spx_ref_nchw_to_hwc(const float *src, float *dst, int n, int c, int h, int w) {
  for (int b = 0; b < n; b++)
    for (int ch = 0; ch < c; ch++)
      for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
          dst[((b * h + y) * w + x) * c + ch] = src[((b * c + ch) * h + y) * w + x];
}
