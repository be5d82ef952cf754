/* The open device's roofline, measured (smplpix/device.h: spx_device_measure_peak): the float32
 * FMA peak of kernels/peak.cl's spx_peak_fma and the streaming bandwidth of its spx_peak_triad,
 * each the best of PEAK_BEST_OF timed launches sized to take at least PEAK_MIN_S: long enough
 * that launch overhead is under a percent on a GPU (a few percent on PoCL), short and many enough
 * that a shared CPU's best timing is seldom interrupted. The result is kept on the device for the profiles and benchmarks that report
 * shares of it (spx_device_peak_known). Times are wall time around launch + clFinish, so no
 * profiling queue is needed. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cl/cl_internal.h"

#define PEAK_MIN_S 0.002
#define PEAK_BEST_OF 20
#define PEAK_CHAINS 8 /* SPX_PEAK_CHAINS of kernels/peak.cl, float16 each */
#define PEAK_B (1.0f - 1.0f / 1024.0f)
#define PEAK_C (1.0f / 1024.0f)

float spx_ref_peak_fma(int i, int quads, float b, float c) {
  float x[PEAK_CHAINS][16];
  for (int j = 0; j < PEAK_CHAINS; j++)
    for (int l = 0; l < 16; l++) x[j][l] = 1.0f + (float)((i + 16 * j + l) & 63) * 0.015625f;
  for (int q = 0; q < 4 * quads; q++)
    for (int j = 0; j < PEAK_CHAINS; j++)
      for (int l = 0; l < 16; l++) x[j][l] = fmaf(x[j][l], b, c);
  /* the kernel's order: chains in a tree, then halves of the vector (lo + hi) down to one lane */
  float v[16];
  for (int l = 0; l < 16; l++)
    v[l] = ((x[0][l] + x[1][l]) + (x[2][l] + x[3][l])) + ((x[4][l] + x[5][l]) + (x[6][l] + x[7][l]));
  for (int w = 8; w >= 1; w /= 2)
    for (int l = 0; l < w; l++) v[l] = v[l] + v[l + w];
  return v[0];
}

/* launch sizes rounded up to the work-group the kernel takes (the generic SPX_WG, at most its limit) */
static size_t peak_wg(spx_ctx *ctx, cl_kernel k) {
  size_t wg = (size_t)ctx->dev->tune.wg, lim = spx_cl_kernel_wg_limit(ctx, k);
  return lim && wg > lim ? lim : wg;
}

/* One launch of a peak kernel k over n items, its arguments' status e checked first (`what`
 * names the kernel in the messages). */
static spx_status peak_launch(spx_ctx *ctx, cl_kernel k, cl_int e, int n, const char *what) {
  char msg[64];
  snprintf(msg, sizeof msg, "%s args", what);
  spx_status st = spx_cl_check(ctx, e, msg);
  if (st) return st;
  size_t gl = (size_t)n, lo = peak_wg(ctx, k);
  return spx_cl_run(ctx, k, 1, &gl, &lo, what);
}

spx_status spx_cl_peak_fma(spx_ctx *ctx, cl_mem out, int n, int quads, float b, float c) {
  cl_kernel k;
  spx_status st = spx_cl_kernel(ctx, SPX_K_PEAK_FMA, &k);
  if (!st)
    st = peak_launch(ctx, k,
                     SPX_ARG(k, 0, out) | SPX_ARG(k, 1, n) | SPX_ARG(k, 2, quads) | SPX_ARG(k, 3, b) | SPX_ARG(k, 4, c), n,
                     "spx_peak_fma");
  return st;
}

spx_status spx_cl_peak_triad(spx_ctx *ctx, cl_mem a, cl_mem b, cl_mem c, int n4, float s) {
  cl_kernel k;
  spx_status st = spx_cl_kernel(ctx, SPX_K_PEAK_TRIAD, &k);
  if (!st)
    st = peak_launch(ctx, k, SPX_ARG(k, 0, a) | SPX_ARG(k, 1, b) | SPX_ARG(k, 2, c) | SPX_ARG(k, 3, n4) | SPX_ARG(k, 4, s),
                     n4, "spx_peak_triad");
  return st;
}

/* Seconds of `reps` back-to-back launches of one kind (0: FMA with quads, 1: triad), finished. */
struct peak_job {
  cl_mem m[3];
  int n, quads;
};
static spx_status peak_time(spx_ctx *ctx, const struct peak_job *j, int triad, int reps, double *s) {
  double t0 = spx_now();
  spx_status st = SPX_OK;
  for (int r = 0; r < reps && !st; r++)
    st = triad ? spx_cl_peak_triad(ctx, j->m[0], j->m[1], j->m[2], j->n, 3.0f)
               : spx_cl_peak_fma(ctx, j->m[0], j->n, j->quads, PEAK_B, PEAK_C);
  if (!st) st = spx_device_finish(ctx);
  *s = spx_now() - t0;
  return st;
}

/* FMA: quads doubled (from 4) until one launch takes PEAK_MIN_S, then the best of PEAK_BEST_OF */
static spx_status measure_fma(spx_ctx *ctx, spx_device_peak *p) {
  const spx_device_info *in = &ctx->dev->info;
  long items = (long)(in->compute_units ? in->compute_units : 1) * 4096;
  if (items > (1L << 22)) items = 1L << 22; /* lane starts stay exact in float (kernels/peak.cl) */
  struct peak_job j = {{NULL, NULL, NULL}, (int)items, 4};
  spx_status st = spx_cl_alloc(ctx, (size_t)items * sizeof(float), "peak: FMA sums", &j.m[0]);
  double s = 0, best = INFINITY;
  while (!st && !(st = peak_time(ctx, &j, 0, 1, &s)) && s < PEAK_MIN_S && j.quads < (1 << 22))
    j.quads *= s < PEAK_MIN_S / 16 ? 8 : 2;
  for (int r = 0; r < PEAK_BEST_OF && !st; r++)
    if (!(st = peak_time(ctx, &j, 0, 1, &s)) && s < best) best = s;
  spx_cl_free(&j.m[0]);
  if (st) return st;
  p->fma_gflop = 2.0 * PEAK_CHAINS * 16.0 * 4.0 * j.quads * (double)items * 1e-9;
  p->fma_gflops = p->fma_gflop / best;
  return SPX_OK;
}

/* triad: arrays of min(256 MiB, the largest allocation, 1/16 of the device memory) each;
 * launches per timing grown until they take PEAK_MIN_S, then the best of PEAK_BEST_OF */
static spx_status measure_triad(spx_ctx *ctx, spx_device_peak *p) {
  const spx_device_info *in = &ctx->dev->info;
  uint64_t bytes = 256ull << 20;
  if (bytes > in->max_alloc) bytes = in->max_alloc;
  if (bytes > in->global_mem / 16) bytes = in->global_mem / 16;
  int n4 = (int)(bytes / 16 > (1u << 30) ? (1u << 30) : bytes / 16);
  if (n4 < 1) return spx_fail(ctx, SPX_E_DEVMEM, "peak: the device has no room for the bandwidth arrays");
  struct peak_job j = {{NULL, NULL, NULL}, n4, 0};
  spx_status st = SPX_OK;
  for (int i = 0; i < 3 && !st; i++) st = spx_cl_alloc(ctx, (size_t)n4 * 16, "peak: bandwidth arrays", &j.m[i]);
  if (!st) st = spx_cl_fill_f32(ctx, j.m[1], 0, (size_t)n4 * 4, 1.0f);
  if (!st) st = spx_cl_fill_f32(ctx, j.m[2], 0, (size_t)n4 * 4, 2.0f);
  double s = 0, best = INFINITY;
  int reps = 1;
  if (!st) st = peak_time(ctx, &j, 1, 1, &s); /* first touch of the arrays */
  while (!st && !(st = peak_time(ctx, &j, 1, reps, &s)) && s < PEAK_MIN_S && reps < 4096) reps *= 2;
  for (int r = 0; r < PEAK_BEST_OF && !st; r++)
    if (!(st = peak_time(ctx, &j, 1, reps, &s)) && s < best) best = s;
  for (int i = 0; i < 3; i++) spx_cl_free(&j.m[i]);
  if (st) return st;
  p->triad_gbyte = 48.0 * (double)n4 * 1e-9;
  p->triad_gbs = p->triad_gbyte * reps / best;
  return SPX_OK;
}

spx_status spx_device_measure_peak(spx_ctx *ctx, spx_device_peak *out) {
  spx_status st = spx_cl_require(ctx, "spx_device_measure_peak");
  if (st) return st;
  spx_device_peak p;
  memset(&p, 0, sizeof p);
  double t0 = spx_now();
  /* the measurement's own launches stay out of the kernel profile (SPX_PROFILE_KERNELS) */
  struct spx_cl_kprof *kp = ctx->dev->kprof;
  ctx->dev->kprof = NULL;
  if (!(st = measure_fma(ctx, &p))) st = measure_triad(ctx, &p);
  ctx->dev->kprof = kp;
  if (st) return st;
  p.seconds = spx_now() - t0;
  ctx->dev->peak = p;
  ctx->dev->peak_known = 1;
  if (out) *out = p;
  return SPX_OK;
}

int spx_device_peak_known(const spx_ctx *ctx, spx_device_peak *out) {
  if (!ctx || !ctx->dev || !ctx->dev->peak_known) return 0;
  if (out) *out = ctx->dev->peak;
  return 1;
}
