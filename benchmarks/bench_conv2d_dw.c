/* conv2d weight gradient, direct (kernels/conv2d_bwd.cl) against Winograd F(4x4,3x3)
 * (kernels/conv2d_winograd_dw.cl), on every 3x3 convolution of the width-64 UNet at 308x410: the
 * two run alternately in the same process (same load), reps times each; the minimum wall ms and
 * that run's process CPU ms of each, and their ratio. The numbers behind the tunable CONV_WINO_DW.
 *
 *   bench_conv2d_dw [--batch N] [--reps R]      (defaults 1 and 3)                           */
#include <stdlib.h>
#include <string.h>

#include "bench_common.h"
#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "smplpix/smplpix.h"

typedef struct layer {
  const char *name;
  int cin, cout, h, w;
} layer;

/* the 3x3 convolutions of the milesial UNet (bilinear, width 64) at 308x410 */
static const layer layers[] = {
    {"inc1", 4, 64, 308, 410},    {"inc2", 64, 64, 308, 410},   {"d1a", 64, 128, 154, 205},
    {"d1b", 128, 128, 154, 205},  {"d2a", 128, 256, 77, 102},   {"d2b", 256, 256, 77, 102},
    {"d3a", 256, 512, 38, 51},    {"d3b", 512, 512, 38, 51},    {"d4a", 512, 512, 19, 25},
    {"d4b", 512, 512, 19, 25},    {"u1a", 1024, 512, 38, 51},   {"u1b", 512, 256, 38, 51},
    {"u2a", 512, 256, 77, 102},   {"u2b", 256, 128, 77, 102},   {"u3a", 256, 128, 154, 205},
    {"u3b", 128, 64, 154, 205},   {"u4a", 128, 64, 308, 410},   {"u4b", 64, 64, 308, 410},
};

/* One weight gradient of layer l (batch n) with CONV_WINO_DW = minc; wall and CPU ms. */
static int run_dw(spx_ctx *ctx, spx_op_workspace *ws, const spx_tensor *x, const spx_tensor *w,
                  const spx_tensor *dy, const spx_tensor *dw, int minc, double *ms, double *cpu) {
  ctx->dev->tune.conv_wino_dw = minc; /* host-side only: no program depends on them */
  ctx->dev->tune.conv_wino_dw_minhw = 0;
  spx_conv2d_params p = {3, 1, 1, NULL, NULL, 0, ws, {0, 0, 0}};
  double t0 = spx_now(), c0 = bench_cpu_now();
  if (spx_conv2d_backward(ctx, x, w, dy, NULL, dw, NULL, &p) || clFinish(ctx->dev->queue) != CL_SUCCESS) return 1;
  *ms = 1e3 * (spx_now() - t0), *cpu = 1e3 * (bench_cpu_now() - c0);
  return 0;
}

int main(int argc, char **argv) {
  int batch = 1, reps = 3;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--batch") && i + 1 < argc) batch = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
    else {
      fprintf(stderr, "usage: bench_conv2d_dw [--batch N] [--reps R]\n");
      return 2;
    }
  }
  if (batch < 1 || batch > 16 || reps < 1 || reps > 100) {
    fprintf(stderr, "bench_conv2d_dw: --batch 1..16, --reps 1..100\n");
    return 2;
  }
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 1;
  if (spx_device_open(ctx, NULL)) BENCH_DIE("bench_conv2d_dw", ctx, "device");
  if (!ctx->dev->tune.conv_wino_train) {
    fprintf(stderr, "bench_conv2d_dw: CONV_WINO_TRAIN is 0 on this device (set SPX_TUNE_CONV_WINO_TRAIN=1)\n");
    spx_ctx_destroy(ctx);
    return 1;
  }
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  printf("device: %s; batch %d; dw tile %dx%d G %d QB %d VW %d; min of %d alternating runs\n", info.name, batch,
         ctx->dev->tune.conv_dw_tm, ctx->dev->tune.conv_dw_tn, ctx->dev->tune.conv_dw_g, ctx->dev->tune.conv_dw_qb,
         ctx->dev->tune.conv_vw, reps);
  printf("%-5s %10s %8s | %9s %9s | %9s %9s | %6s %6s\n", "layer", "channels", "HxW", "direct ms", "cpu ms",
         "wino ms", "cpu ms", "wall", "cpu");
  spx_op_workspace ws = {0};
  double tot[4] = {0};
  int rc = 0;
  for (size_t i = 0; i < sizeof layers / sizeof layers[0] && !rc; i++) {
    const layer *l = &layers[i];
    size_t nx = (size_t)batch * l->cin * l->h * l->w, ny = (size_t)batch * l->cout * l->h * l->w;
    size_t nw = (size_t)l->cout * l->cin * 9;
    cl_mem mx = NULL, mdy = NULL, mw = NULL, mdw = NULL;
    rc = spx_cl_alloc(ctx, nx * 4, "x", &mx) || spx_cl_alloc(ctx, ny * 4, "dy", &mdy) ||
         spx_cl_alloc(ctx, nw * 4, "w", &mw) || spx_cl_alloc(ctx, nw * 4, "dw", &mdw) ||
         spx_cl_fill_f32(ctx, mx, 0, nx, 0.5f) || spx_cl_fill_f32(ctx, mdy, 0, ny, 0.25f) ||
         spx_cl_fill_f32(ctx, mw, 0, nw, 0.01f) || spx_cl_fill_f32(ctx, mdw, 0, nw, 0.0f);
    spx_tensor x = spx_tensor_view(mx, 0, batch, l->cin, l->h, l->w);
    spx_tensor dy = spx_tensor_view(mdy, 0, batch, l->cout, l->h, l->w);
    spx_tensor w = spx_tensor_view(mw, 0, l->cout, l->cin, 3, 3), dw = spx_tensor_view(mdw, 0, l->cout, l->cin, 3, 3);
    double best[2] = {1e30, 1e30}, bcpu[2] = {0, 0}, ms, cpu;
    for (int r = 0; r <= reps && !rc; r++) /* run 0 warms up (kernel build, page faults) */
      for (int k = 0; k < 2 && !rc; k++) {
        rc = run_dw(ctx, &ws, &x, &w, &dy, &dw, k ? 1 : 0, &ms, &cpu);
        if (!rc && r > 0 && ms < best[k]) best[k] = ms, bcpu[k] = cpu;
      }
    spx_cl_free(&mx), spx_cl_free(&mdy), spx_cl_free(&mw), spx_cl_free(&mdw);
    if (rc) break;
    char ch[24];
    snprintf(ch, sizeof ch, "%d->%d", l->cin, l->cout);
    printf("%-5s %10s %3dx%-4d | %9.1f %9.1f | %9.1f %9.1f | %6.2f %6.2f\n", l->name, ch, l->h, l->w, best[0],
           bcpu[0], best[1], bcpu[1], best[1] / best[0], bcpu[1] / bcpu[0]);
    fflush(stdout);
    tot[0] += best[0], tot[1] += bcpu[0], tot[2] += best[1], tot[3] += bcpu[1];
  }
  if (rc) fprintf(stderr, "bench_conv2d_dw: %s\n", spx_ctx_message(ctx));
  else
    printf("total: direct %.1f ms (cpu %.1f), winograd %.1f ms (cpu %.1f): %.2f wall, %.2f cpu\n", tot[0], tot[1],
           tot[2], tot[3], tot[2] / tot[0], tot[3] / tot[1]);
  spx_op_workspace_release(&ws);
  spx_ctx_destroy(ctx);
  return rc;
}
