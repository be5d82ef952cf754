/* conv2d benchmark: the UNet-64 convolution shapes at 4x308x410 on the open device (forward,
 * backward-data, backward-weights: ms, GFLOP/s and the share of the device's roofline, measured at
 * the start as `smplpix devices --peak` does), plus the plain-C double reference on one thread on
 * a small shape. Peers: benchmarks/peer_conv_torch.py times the same shapes in PyTorch,
 * bench_clblast in CLBlast (convgemm, im2col + GEMM).
 *
 *   bench_conv2d [reps] [--div N]  (default 3; the minimum over reps is reported; --div divides
 *                                  every image side by N, for a quick run)
 *   bench_conv2d --unet [reps]     also time every conv of a UNet-64 eval forward (sum)
 *   bench_conv2d --w16 [reps]      also time every conv of a UNet-16 eval forward, wall and process
 *                                  CPU per layer (SPX_BENCH_UNET filters)
 * Work model (benchmarks/roofline.h): FLOPs = 2 x multiply-adds; bytes = input, weights and output
 * once. Each time cell is followed by GF/s and its share of the FMA peak (%pk) or, for a
 * memory-bound shape (flops per byte below the ridge), GB/s and its share of the bandwidth (%bw).
 * Every (shape, pass) also prints one machine-readable line (scripts/device/run.sh reads them):
 *   CONV impl=smplpix mode=fwd|bwd_data|bwd_weights cin= cout= h= w= k= ms= gflop= gbyte= gflops= gbs=
 *        peak_gflops= peak_gbs= pct_peak= pct_bw= bound=compute|memory pct_roof=
 * SPX_KERNEL_PROFILE=1 (bench_profiles_from_env): every kernel's own device time, summed per
 * kernel name, on stderr at the end (the shapes' pad copies, weight packs and GEMMs apart). */
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "bench_common.h"
#include "roofline.h"
#include "smplpix/smplpix.h"

typedef bench_conv_shape shape;
static bench_roof roof;
static const char *const mode_name[3] = {"fwd", "bwd_data", "bwd_weights"};

static int fail(spx_ctx *ctx, const char *what) {
  fprintf(stderr, "bench_conv2d: %s: %s\n", what, spx_ctx_message(ctx));
  return 1;
}

static double flops(const shape *s) { return bench_conv_gflop(s) * 1e9; }

/* the machine-readable line of one timed pass */
static void conv_line(const shape *s, int mode, double ms) {
  char f[512];
  bench_roof_fields(&roof, bench_conv_gflop(s), bench_conv_gbyte(s), ms, f, sizeof f);
  printf("CONV impl=smplpix mode=%s cin=%d cout=%d h=%d w=%d k=%d ms=%.4f %s\n", mode_name[mode], s->cin, s->cout, s->h,
         s->w, s->k, ms, f);
}

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
  int reps = 3, do_unet = 0, div = 1;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--unet")) do_unet = 1;
    else if (!strcmp(argv[i], "--w16")) do_unet = 2;
    else if (!strcmp(argv[i], "--div") && i + 1 < argc) div = atoi(argv[++i]) > 0 ? atoi(argv[i]) : 1;
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
  bench_roof_measure(ctx, &roof);
  printf("%-18s %7s %7s %7s | %9s %-21s | %9s %-21s | %9s %-21s\n", "shape (1x)", "HxW", "GFLOP", "MB", "fwd ms",
         " (% of the roof)", "bwd-x ms", "", "bwd-w ms", "");
  double wall_sum = 0, all_gf = 0, all_gb = 0;
  cpu_ms_sum = 0;
  for (size_t i = 0; i < sizeof bench_unet64_layers / sizeof bench_unet64_layers[0]; i++) {
    const shape sh = bench_conv_scaled(&bench_unet64_layers[i], div), *s = &sh;
    const char *only = getenv("SPX_BENCH_ONLY"); /* e.g. "12": shapes 1 and 2 */
    if (only && !strchr(only, '0' + (int)i)) continue;
    double ms[3], cpu[3];
    char cell[3][64];
    for (int m = 0; m < 3; m++) {
      if (time_op(ctx, s, m, reps, &ms[m], &cpu[m])) return fail(ctx, s->name);
      bench_roof_short(&roof, bench_conv_gflop(s), bench_conv_gbyte(s), ms[m], cell[m], sizeof cell[m]);
    }
    printf("%-18s %3dx%-3d %7.2f %7.1f | %9.2f %s | %9.2f %s | %9.2f %s\n", s->name, s->h, s->w, bench_conv_gflop(s),
           bench_conv_gbyte(s) * 1e3, ms[0], cell[0], ms[1], cell[1], ms[2], cell[2]);
    for (int m = 0; m < 3; m++) conv_line(s, m, ms[m]);
    wall_sum += ms[0] + ms[1] + ms[2];
    all_gf += 3 * bench_conv_gflop(s), all_gb += 3 * bench_conv_gbyte(s);
    if (getenv("SPX_BENCH_CPU")) printf("   cpu ms: %.1f %.1f %.1f\n", cpu[0], cpu[1], cpu[2]);
    fflush(stdout);
  }
  bench_roof_cell c = bench_roof_eval(&roof, all_gf, all_gb, wall_sum);
  printf("sum of the table: %.1f ms wall, %.1f ms CPU (all threads; wall x cores when the machine is idle); "
         "%.2f GFLOP, %.1f MB: %.1f GF/s, %.1f%% of the FMA peak\n",
         wall_sum, cpu_ms_sum, all_gf, all_gb * 1e3, c.gflops, c.pct_peak);
  if (do_unet) {
    double tot = 0, gtot = 0, btot = 0, ctot = 0;
    for (int i = 0; i < BENCH_UNET_CONVS; i++) {
      const shape layer = bench_unet_conv(i, do_unet == 2 ? 16 : 64);
      const char *only = getenv("SPX_BENCH_UNET"); /* comma list of layer names */
      if (only && !strstr(only, layer.name)) continue;
      const shape sh = bench_conv_scaled(&layer, div);
      double ms, cpu;
      char cell[64];
      if (time_op(ctx, &sh, 0, reps, &ms, &cpu)) return fail(ctx, sh.name);
      tot += ms, gtot += bench_conv_gflop(&sh), btot += bench_conv_gbyte(&sh), ctot += cpu;
      bench_roof_short(&roof, bench_conv_gflop(&sh), bench_conv_gbyte(&sh), ms, cell, sizeof cell);
      printf("  %-5s %4d->%-4d %3dx%-3d wall %7.2f ms %s  cpu %7.2f ms  %6.1f GFLOP/s (cpu)\n", sh.name, sh.cin, sh.cout,
             sh.h, sh.w, ms, cell, cpu, flops(&sh) * 1e-6 / cpu);
      conv_line(&sh, 0, ms);
    }
    c = bench_roof_eval(&roof, gtot, btot, tot);
    printf("UNet-%d convs, eval forward: %.1f ms, %.1f GFLOP, %.1f MB, %.1f GFLOP/s, %.1f%% of the FMA peak (CPU %.1f ms)\n",
           do_unet == 2 ? 16 : 64, tot, gtot, btot * 1e3, gtot / tot * 1e3, c.pct_peak, ctot);
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
