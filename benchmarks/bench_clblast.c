/* The CLBlast baseline of the convolution shapes (benchmark code: a peer, never in the library):
 * the UNet-64 layer shapes of bench_conv2d, forward, batch 1, NCHW float32, on the same OpenCL
 * device, context and queue as the library (SPX_DEVICE), through CLBlast's two convolution routes:
 *   convgemm       CLBlastSconvgemm (cross-correlation, as a convolution layer computes)
 *   im2col + GEMM  CLBlastSim2col into a (cin k k) x (h w) column buffer, then CLBlastSgemm
 *                  (row-major: weights [cout][cin k k] times columns = the output [cout][h w])
 * First both are checked against the plain-C double reference on a small shape (exit 1 when
 * either is wrong: a wrong baseline flatters nobody). Times: the minimum of reps after a warm-up
 * (which compiles CLBlast's kernels), with the work model and roofline shares of bench_conv2d
 * (benchmarks/roofline.h). Machine-readable lines, one per shape and route:
 *   CONV impl=clblast_convgemm|clblast_im2col_gemm mode=fwd cin= cout= h= w= k= ms= gflop= ... pct_roof=
 * CLBlast 1.5.3 (Debian) has no tuned parameters for every device (e.g. none for sm_90): it then
 * runs its defaults, which is what a user of it gets.
 *   bench_clblast [reps] [--div N]    (default 3; --div divides every image side by N) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <clblast_c.h>

#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "roofline.h"

typedef bench_conv_shape shape;
enum { CONVGEMM, IM2COL_GEMM };
static const char *const route_name[2] = {"clblast_convgemm", "clblast_im2col_gemm"};

struct bufs {
  cl_mem x, w, y, col;
};

/* one forward by route r; 0, or the CLBlast status (nonzero) */
static int run_route(spx_ctx *ctx, const shape *s, const struct bufs *b, int r) {
  cl_command_queue q = ctx->dev->queue;
  const size_t k = (size_t)s->k, pad = (size_t)s->pad, kdim = (size_t)s->cin * k * k, hw = (size_t)s->h * s->w;
  CLBlastStatusCode st;
  if (r == CONVGEMM) {
    st = CLBlastSconvgemm(CLBlastKernelModeCrossCorrelation, (size_t)s->cin, (size_t)s->h, (size_t)s->w, k, k, pad, pad,
                          1, 1, 1, 1, (size_t)s->cout, 1, b->x, 0, b->w, 0, b->y, 0, &q, NULL);
  } else {
    st = CLBlastSim2col(CLBlastKernelModeCrossCorrelation, (size_t)s->cin, (size_t)s->h, (size_t)s->w, k, k, pad, pad, 1,
                        1, 1, 1, b->x, 0, b->col, 0, &q, NULL);
    if (st == CLBlastSuccess)
      st = CLBlastSgemm(CLBlastLayoutRowMajor, CLBlastTransposeNo, CLBlastTransposeNo, (size_t)s->cout, hw, kdim, 1.0f,
                        b->w, 0, kdim, b->col, 0, hw, 0.0f, b->y, 0, hw, &q, NULL);
  }
  if (st == CLBlastSuccess && clFinish(q) != CL_SUCCESS) return -1;
  return (int)st;
}

static int alloc_bufs(spx_ctx *ctx, const shape *s, struct bufs *b) {
  size_t hw = (size_t)s->h * s->w, kk = (size_t)s->k * s->k;
  memset(b, 0, sizeof *b);
  return spx_cl_alloc(ctx, (size_t)s->cin * hw * 4, "x", &b->x) || spx_cl_alloc(ctx, (size_t)s->cout * s->cin * kk * 4, "w", &b->w) ||
         spx_cl_alloc(ctx, (size_t)s->cout * hw * 4, "y", &b->y) || spx_cl_alloc(ctx, (size_t)s->cin * kk * hw * 4, "col", &b->col);
}

static void free_bufs(struct bufs *b) { spx_cl_free(&b->x), spx_cl_free(&b->w), spx_cl_free(&b->y), spx_cl_free(&b->col); }

/* both routes against spx_ref_conv2d_forward on a small 3x3 and a 1x1 shape: the largest error
 * relative to the output's largest magnitude, per route; -1 when a route fails to run */
static int check_routes(spx_ctx *ctx, double err[2]) {
  static const shape small[2] = {{"check 3x3", 5, 7, 9, 11, 3, 1}, {"check 1x1", 6, 3, 8, 5, 1, 0}};
  err[0] = err[1] = 0;
  for (int c = 0; c < 2; c++) {
    const shape *s = &small[c];
    size_t nx = (size_t)s->cin * s->h * s->w, nw = (size_t)s->cout * s->cin * s->k * s->k, ny = (size_t)s->cout * s->h * s->w;
    float *fx = malloc(nx * 4), *fw = malloc(nw * 4), *fy = malloc(ny * 4);
    double *dx = malloc(nx * 8), *dw = malloc(nw * 8), *dy = malloc(ny * 8);
    struct bufs b;
    int rc = !fx || !fw || !fy || !dx || !dw || !dy || alloc_bufs(ctx, s, &b);
    for (size_t i = 0; !rc && i < nx; i++) fx[i] = (float)((int)(i * 37 % 23) - 11) / 8.0f, dx[i] = fx[i];
    for (size_t i = 0; !rc && i < nw; i++) fw[i] = (float)((int)(i * 53 % 19) - 9) / 16.0f, dw[i] = fw[i];
    if (!rc) {
      spx_conv2d_shape cs = {1, s->cin, s->h, s->w, s->cout, s->k, 1, s->pad};
      spx_ref_conv2d_forward(&cs, dx, dw, NULL, NULL, NULL, 0, dy);
      double big = 1e-30;
      for (size_t i = 0; i < ny; i++) big = big > fabs(dy[i]) ? big : fabs(dy[i]);
      rc = spx_cl_write(ctx, b.x, 0, nx * 4, fx) || spx_cl_write(ctx, b.w, 0, nw * 4, fw);
      for (int r = 0; r < 2 && !rc; r++) {
        rc = spx_cl_fill_f32(ctx, b.y, 0, ny, -999.0f) || run_route(ctx, s, &b, r) || spx_cl_read(ctx, b.y, 0, ny * 4, fy);
        for (size_t i = 0; !rc && i < ny; i++) err[r] = fmax(err[r], fabs(fy[i] - dy[i]) / big);
      }
      free_bufs(&b);
    }
    free(fx), free(fw), free(fy), free(dx), free(dw), free(dy);
    if (rc) return -1;
  }
  return 0;
}

int main(int argc, char **argv) {
  int reps = 3, div = 1;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--div") && i + 1 < argc) div = atoi(argv[++i]) > 0 ? atoi(argv[i]) : 1;
    else reps = atoi(argv[i]) > 0 ? atoi(argv[i]) : 3;
  }
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 1;
  if (spx_device_open(ctx, NULL)) {
    fprintf(stderr, "bench_clblast: device: %s\n", spx_ctx_message(ctx));
    return 1;
  }
  printf("device: %s; CLBlast (convgemm, im2col + GEMM), forward, batch 1\n", ctx->dev->info.name);
  bench_roof roof;
  bench_roof_measure(ctx, &roof);
  double err[2];
  if (check_routes(ctx, err) || err[0] > 1e-5 || err[1] > 1e-5) {
    fprintf(stderr, "bench_clblast: CLBlast's convolution does not match the reference (relative errors %.3g, %.3g%s)\n",
            err[0], err[1], spx_ctx_message(ctx)[0] ? "; " : "");
    spx_ctx_destroy(ctx);
    return 1;
  }
  printf("check against the plain-C reference (3x3 and 1x1): convgemm %.2g, im2col + GEMM %.2g of the largest output\n",
         err[0], err[1]);
  printf("%-18s %7s %7s | %9s %-21s | %9s %-21s\n", "shape (1x)", "HxW", "GFLOP", "convgemm", "ms", "im2col+GEMM", "ms");
  int rc = 0;
  for (size_t i = 0; i < sizeof bench_unet64_layers / sizeof bench_unet64_layers[0] && !rc; i++) {
    const shape sh = bench_conv_scaled(&bench_unet64_layers[i], div), *s = &sh;
    struct bufs b;
    if (alloc_bufs(ctx, s, &b) || spx_cl_fill_f32(ctx, b.x, 0, (size_t)s->cin * s->h * s->w, 0.5f) ||
        spx_cl_fill_f32(ctx, b.w, 0, (size_t)s->cout * s->cin * s->k * s->k, 0.01f)) {
      fprintf(stderr, "bench_clblast: %s: %s\n", s->name, spx_ctx_message(ctx));
      free_bufs(&b);
      rc = 1;
      break;
    }
    double ms[2];
    char cell[2][64], line[2][640];
    for (int r = 0; r < 2; r++) {
      ms[r] = 1e30;
      for (int k = 0; k <= reps; k++) { /* k == 0: warm-up, CLBlast compiles its kernels */
        double t0 = spx_now();
        int st = run_route(ctx, s, &b, r);
        double t = (spx_now() - t0) * 1e3;
        if (st) {
          printf("%s %s: CLBlast status %d\n", s->name, route_name[r], st);
          ms[r] = -1;
          break;
        }
        if (k && t < ms[r]) ms[r] = t;
      }
      if (ms[r] > 0) {
        char f[512];
        bench_roof_fields(&roof, bench_conv_gflop(s), bench_conv_gbyte(s), ms[r], f, sizeof f);
        snprintf(line[r], sizeof line[r], "CONV impl=%s mode=fwd cin=%d cout=%d h=%d w=%d k=%d ms=%.4f %s\n",
                 route_name[r], s->cin, s->cout, s->h, s->w, s->k, ms[r], f);
        bench_roof_short(&roof, bench_conv_gflop(s), bench_conv_gbyte(s), ms[r], cell[r], sizeof cell[r]);
      } else {
        snprintf(cell[r], sizeof cell[r], "%21s", "failed");
        line[r][0] = 0;
      }
    }
    printf("%-18s %3dx%-3d %7.2f | %9.2f %s | %9.2f %s\n%s%s", s->name, s->h, s->w, bench_conv_gflop(s), ms[0], cell[0],
           ms[1], cell[1], line[0], line[1]);
    fflush(stdout);
    free_bufs(&b);
  }
  spx_ctx_destroy(ctx);
  return rc;
}
