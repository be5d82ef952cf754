/* conv2d benchmark: the UNet-64 convolution shapes at 4x308x410 on the open device (forward,
 * backward-data, backward-weights: ms and GFLOP/s), plus the plain-C double reference on one
 * thread on a small shape. Peer: benchmarks/peer_conv_torch.py times the same shapes in PyTorch.
 *
 *   bench_conv2d [reps]          (default 3; the minimum over reps is reported)
 *   bench_conv2d --unet [reps]   also time every conv of a UNet-64 eval forward (sum)
 *   bench_conv2d --w16 [reps]    also time every conv of a UNet-16 eval forward, wall and process
 *                                CPU per layer (SPX_BENCH_UNET filters)
 * SPX_KERNEL_PROFILE=1 (bench_profiles_from_env): every kernel's own device time, summed per
 * kernel name, on stderr at the end (the shapes' pad copies, weight packs and GEMMs apart). */
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "bench_common.h"
#include "smplpix/smplpix.h"

typedef struct shape {
  const char *name;
  int cin, cout, h, w, k, pad;
} shape;

static const shape shapes[] = {
    {"inc.conv1 4->64", 4, 64, 308, 410, 3, 1},   {"inc.conv2 64->64", 64, 64, 308, 410, 3, 1},
    {"down1 128->128", 128, 128, 154, 205, 3, 1}, {"down4 512->512", 512, 512, 19, 25, 3, 1},
    {"up4.conv1 128->64", 128, 64, 308, 410, 3, 1}, {"outc 1x1 64->3", 64, 3, 308, 410, 1, 0},
};

/* every conv of the milesial UNet (bilinear, width 64) at 308x410 */
static const shape unet[] = {
    {"inc1", 4, 64, 308, 410, 3, 1},     {"inc2", 64, 64, 308, 410, 3, 1},     {"d1a", 64, 128, 154, 205, 3, 1},
    {"d1b", 128, 128, 154, 205, 3, 1},   {"d2a", 128, 256, 77, 102, 3, 1},     {"d2b", 256, 256, 77, 102, 3, 1},
    {"d3a", 256, 512, 38, 51, 3, 1},     {"d3b", 512, 512, 38, 51, 3, 1},      {"d4a", 512, 512, 19, 25, 3, 1},
    {"d4b", 512, 512, 19, 25, 3, 1},     {"u1a", 1024, 512, 38, 51, 3, 1},     {"u1b", 512, 256, 38, 51, 3, 1},
    {"u2a", 512, 256, 77, 102, 3, 1},    {"u2b", 256, 128, 77, 102, 3, 1},     {"u3a", 256, 128, 154, 205, 3, 1},
    {"u3b", 128, 64, 154, 205, 3, 1},    {"u4a", 128, 64, 308, 410, 3, 1},     {"u4b", 64, 64, 308, 410, 3, 1},
    {"outc", 64, 3, 308, 410, 1, 0},
};

/* every conv of the width-16 UNet at 308x410, in pass order (the algorithm as the defaults pick
 * it: direct below CONV_WINO_MINC channels, Winograd above) */
static const shape unet16[] = {
    {"inc1", 4, 16, 308, 410, 3, 1},    {"inc2", 16, 16, 308, 410, 3, 1},   {"d1a", 16, 32, 154, 205, 3, 1},
    {"d1b", 32, 32, 154, 205, 3, 1},    {"d2a", 32, 64, 77, 102, 3, 1},     {"d2b", 64, 64, 77, 102, 3, 1},
    {"d3a", 64, 128, 38, 51, 3, 1},     {"d3b", 128, 128, 38, 51, 3, 1},    {"d4a", 128, 128, 19, 25, 3, 1},
    {"d4b", 128, 128, 19, 25, 3, 1},    {"u1a", 256, 128, 38, 51, 3, 1},    {"u1b", 128, 64, 38, 51, 3, 1},
    {"u2a", 128, 64, 77, 102, 3, 1},    {"u2b", 64, 32, 77, 102, 3, 1},     {"u3a", 64, 32, 154, 205, 3, 1},
    {"u3b", 32, 16, 154, 205, 3, 1},    {"u4a", 32, 16, 308, 410, 3, 1},    {"u4b", 16, 16, 308, 410, 3, 1},
    {"outc", 16, 3, 308, 410, 1, 0},
};

static int fail(spx_ctx *ctx, const char *what) {
  fprintf(stderr, "bench_conv2d: %s: %s\n", what, spx_ctx_message(ctx));
  return 1;
}

static double flops(const shape *s) { return 2.0 * s->cout * s->h * s->w * (double)s->cin * s->k * s->k; }

/* mode 0 forward (with fused affine+relu), 1 backward-data, 2 backward-weights; returns min ms */
static spx_op_workspace ws;
static double cpu_ms_sum; /* process CPU time of the best reps (all threads): less sensitive to other load */

static double cpu_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int time_op(spx_ctx *ctx, const shape *s, int mode, int reps, double *ms, double *cpu) {
  size_t nx = (size_t)s->cin * s->h * s->w, ny = (size_t)s->cout * s->h * s->w;
  size_t nw = (size_t)s->cout * s->cin * s->k * s->k;
  cl_mem mx = NULL, my = NULL, mw = NULL, mv = NULL;
  int rc = 1;
  if (spx_cl_alloc(ctx, nx * 4, "x", &mx) || spx_cl_alloc(ctx, ny * 4, "y", &my) ||
      spx_cl_alloc(ctx, nw * 4, "w", &mw) || spx_cl_alloc(ctx, (size_t)s->cout * 4, "v", &mv))
    goto done;
  if (spx_cl_fill_f32(ctx, mx, 0, nx, 0.5f) || spx_cl_fill_f32(ctx, my, 0, ny, 0.25f) ||
      spx_cl_fill_f32(ctx, mw, 0, nw, 0.01f) || spx_cl_fill_f32(ctx, mv, 0, (size_t)s->cout, 1.0f))
    goto done;
  spx_tensor x = spx_tensor_view(mx, 0, 1, s->cin, s->h, s->w), y = spx_tensor_view(my, 0, 1, s->cout, s->h, s->w);
  spx_tensor w = spx_tensor_view(mw, 0, s->cout, s->cin, s->k, s->k), v = spx_tensor_view(mv, 0, s->cout, 1, 1, 1);
  spx_conv2d_params p = {s->k, 1, s->pad, &v, &v, 1, &ws, {0, 0, 0}};
  double best = 1e30, best_cpu = 0;
  for (int r = 0; r < reps + 1; r++) { /* first run warms up (kernel build, page faults) */
    double t0 = spx_now(), c0 = cpu_now();
    spx_status st = mode == 0   ? spx_conv2d_forward(ctx, &x, &w, NULL, &p, &y)
                    : mode == 1 ? spx_conv2d_backward(ctx, &x, &w, &y, &x, NULL, NULL, &p)
                                : spx_conv2d_backward(ctx, &x, &w, &y, NULL, &w, NULL, &p);
    if (st || clFinish(ctx->dev->queue) != CL_SUCCESS) goto done;
    double t = (spx_now() - t0) * 1e3, c = (cpu_now() - c0) * 1e3;
    if (r > 0 && t < best) best = t, best_cpu = c;
  }
  *ms = best;
  cpu_ms_sum += best_cpu;
  if (cpu) *cpu = best_cpu;
  rc = 0;
done:
  spx_cl_free(&mx), spx_cl_free(&my), spx_cl_free(&mw), spx_cl_free(&mv);
  return rc;
}

int main(int argc, char **argv) {
  int reps = 3, do_unet = 0;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--unet")) do_unet = 1;
    else if (!strcmp(argv[i], "--w16")) do_unet = 2;
    else reps = atoi(argv[i]) > 0 ? atoi(argv[i]) : 3;
  }
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 1;
  bench_profiles_from_env(ctx); /* SPX_KERNEL_PROFILE=1 */
  if (spx_device_open(ctx, NULL)) return fail(ctx, "device");
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  printf("device: %s; tiles TMxTNxVW %dx%dx%d LWS %d; dw %dx%d chunk %d\n", info.name, ctx->dev->tune.conv_tm,
         ctx->dev->tune.conv_tn, ctx->dev->tune.conv_vw, ctx->dev->tune.conv_lws,
         ctx->dev->tune.conv_dw_tm, ctx->dev->tune.conv_dw_tn, ctx->dev->tune.conv_dw_qc);
  printf("%-22s %9s | %9s %7s | %9s %7s | %9s %7s\n", "shape (1x, HxW)", "GFLOP", "fwd ms", "GF/s", "bwd-x ms",
         "GF/s", "bwd-w ms", "GF/s");
  double wall_sum = 0;
  cpu_ms_sum = 0;
  for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++) {
    const shape *s = &shapes[i];
    const char *only = getenv("SPX_BENCH_ONLY"); /* e.g. "12": shapes 1 and 2 */
    if (only && !strchr(only, '0' + (int)i)) continue;
    double ms[3], cpu[3];
    for (int m = 0; m < 3; m++)
      if (time_op(ctx, s, m, reps, &ms[m], &cpu[m])) return fail(ctx, s->name);
    double gf = flops(s) * 1e-9;
    printf("%-18s %3dx%-3d %7.2f | %9.1f %7.1f | %9.1f %7.1f | %9.1f %7.1f\n", s->name, s->h, s->w, gf, ms[0],
           gf / ms[0] * 1e3, ms[1], gf / ms[1] * 1e3, ms[2], gf / ms[2] * 1e3);
    wall_sum += ms[0] + ms[1] + ms[2];
    if (getenv("SPX_BENCH_CPU")) printf("   cpu ms: %.1f %.1f %.1f\n", cpu[0], cpu[1], cpu[2]);
    fflush(stdout);
  }
  printf("sum of the table: %.1f ms wall, %.1f ms CPU (all threads; wall x cores when the machine is idle)\n", wall_sum,
         cpu_ms_sum);
  if (do_unet) {
    const shape *tab = do_unet == 2 ? unet16 : unet;
    size_t nt = do_unet == 2 ? sizeof unet16 / sizeof unet16[0] : sizeof unet / sizeof unet[0];
    double tot = 0, gtot = 0, ctot = 0;
    for (size_t i = 0; i < nt; i++) {
      const char *only = getenv("SPX_BENCH_UNET"); /* comma list of layer names */
      if (only && !strstr(only, tab[i].name)) continue;
      double ms, cpu;
      if (time_op(ctx, &tab[i], 0, reps, &ms, &cpu)) return fail(ctx, tab[i].name);
      tot += ms, gtot += flops(&tab[i]) * 1e-9, ctot += cpu;
      if (getenv("SPX_BENCH_CPU") || do_unet == 2)
        printf("  %-5s %4d->%-4d %3dx%-3d wall %7.2f ms cpu %7.2f ms  %6.1f GFLOP/s (cpu)\n", tab[i].name, tab[i].cin,
               tab[i].cout, tab[i].h, tab[i].w, ms, cpu, flops(&tab[i]) * 1e-6 / cpu);
    }
    printf("UNet-%d convs, eval forward: %.1f ms, %.1f GFLOP, %.1f GFLOP/s (CPU %.1f ms)\n", do_unet == 2 ? 16 : 64,
           tot, gtot, gtot / tot * 1e3, ctot);
  }
  /* plain-C double reference, one thread */
  {
    spx_conv2d_shape s = {1, 16, 32, 40, 16, 3, 1, 1};
    size_t nx = 16 * 32 * 40, nw = 16 * 16 * 9;
    double *x = calloc(nx, 8), *w = calloc(nw, 8), *y = calloc(nx, 8);
    if (!x || !w || !y) return 1;
    for (size_t i = 0; i < nx; i++) x[i] = (double)(i % 7) * 0.1;
    for (size_t i = 0; i < nw; i++) w[i] = (double)(i % 5) * 0.01;
    double t0 = spx_now();
    spx_ref_conv2d_forward(&s, x, w, NULL, NULL, NULL, 0, y);
    double t = spx_now() - t0, gf = 2.0 * 16 * 32 * 40 * 16 * 9 * 1e-9;
    printf("plain-C reference (double, 1 thread) [1,16->16,32x40] 3x3: %.1f ms, %.2f GFLOP/s\n", t * 1e3, gf / t);
    free(x), free(w), free(y);
  }
  spx_op_workspace_release(&ws);
  spx_ctx_destroy(ctx);
  return 0;
}
