/* conv2d Winograd F(4x4,3x3) path (kernels/conv2d_winograd.cl): forward (with the fused epilogue)
 * and backward data (accumulating) against the double reference of the direct convolution
 * (lib/nn/conv2d_ref.c), bit-identical reruns, and the rule that picks the path.
 *
 * Tolerance, derived from the transforms (not fitted): the device computes, per 4x4 output tile,
 *   y = A^T [ sum_ci (G g G^T) .* (B^T d B) ] A
 * in float32. Each stage is a short sum of products by constants: the input transform is 2 passes
 * of <= 4 additions (|error| <= ~6u relative to |B^T| |d| |B|), the weight transform 2 passes of
 * <= 3 terms and a division (<= ~8u relative to |G| |g| |G^T|), the Hadamard product 1 rounding,
 * the GEMM a sum of Cin terms (<= Cin u), the output transform 2 passes of <= 5 terms (<= ~6u
 * relative to |A^T| |M| |A|), u = 2^-24. To first order the error is therefore bounded by
 *   (Cin + 24) u * W,   W = |A^T| [ sum_ci (|G| |g| |G^T|) .* (|B^T| |d| |B|) ] |A|
 * computed here in double with absolute values of every matrix and operand. W is the
 * conditioning of the transform: B has entries up to 5 and A^T up to 8, so W is typically
 * 10-100x the direct convolution's sum of |w||x| (that is why Winograd is less accurate than the
 * direct path, whose bound is ~Cin*9 u sum |w||x|). The fused epilogue adds |scale| times that plus
 * a few roundings of the output's own size. A wrong transform or index gives errors of the
 * order of the outputs themselves, far above the bound; the observed worst error / bound ratio is
 * printed (typically ~0.01-0.05: the bound is a worst case).
 *
 * Typical error against the direct convolution's (test_gain; the factor SPX_WINO_RMS_GAIN by
 * which golden tests widen their tolerance when Winograd is on): model each rounding as an
 * independent error of relative size u. Direct: output (i, j) is one sum of 9 Cin products, rms
 * error ~ u sqrt(9 Cin) s_w s_x for i.i.d. weights / inputs of rms s_w, s_x. Winograd: the
 * dominant roundings are those of the 36 Cin-term GEMM sums, each of rms u sqrt(Cin) |U_ab V_ab|
 * with E[U_ab^2] = g2_a g2_b s_w^2, E[V_ab^2] = b2_a b2_b s_x^2 (g2_a = sum_k G_ak^2, b2_a =
 * sum_p BT_ap^2), then mixed by the output transform with weights A^T_ia A^T_jb. So
 *   rms_wino / rms_direct = sqrt(S_i S_j) / 3,   S_i = sum_a (A^T_ia)^2 g2_a b2_a,
 * largest at the tile corner i = j = 3: S_3 = 94.33, ratio 31.4 (the transform stages' own
 * roundings add terms of the same form with smaller weights). */
#include <stdlib.h>

#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "smplpix/smplpix.h"
#include "test.h"
#include "wino_test.h"

static unsigned long long rng = 0x243f6a8885a308d3ULL;
static void fill_rand(double *a, size_t n) {
  for (size_t i = 0; i < n; i++) a[i] = 2.0 * spx_t_uniform(&rng) - 1.0;
}

/* the transform matrices (tests/wino_test.h) */
#define BT WT_BT
#define G WT_G
#define AT WT_AT

/* W (see the top of the file) for every output of a 3x3/s1/p1 conv of x [n][cin][h][w] with
 * w [cout][cin][3][3], both taken in absolute value. */
static void wino_magnitude(int n, int cin, int h, int wd, int cout, const double *x, const double *w, double *out) {
  int th = (h + 3) / 4, tw = (wd + 3) / 4;
  double *uw = malloc((size_t)cout * cin * 36 * sizeof(double));
  for (int co = 0; co < cout; co++)
    for (int ci = 0; ci < cin; ci++) {
      const double *g = w + ((size_t)co * cin + ci) * 9;
      double t[6][3];
      for (int a = 0; a < 6; a++)
        for (int j = 0; j < 3; j++) {
          t[a][j] = 0;
          for (int k = 0; k < 3; k++) t[a][j] += fabs(G[a][k]) * fabs(g[k * 3 + j]);
        }
      for (int a = 0; a < 6; a++)
        for (int b = 0; b < 6; b++) {
          double s = 0;
          for (int k = 0; k < 3; k++) s += t[a][k] * fabs(G[b][k]);
          uw[((size_t)co * cin + ci) * 36 + a * 6 + b] = s;
        }
    }
  double *vd = malloc((size_t)cin * 36 * sizeof(double));
  for (int b = 0; b < n; b++)
    for (int ty = 0; ty < th; ty++)
      for (int tx = 0; tx < tw; tx++) {
        for (int ci = 0; ci < cin; ci++)
          wt_input_magnitude(x + ((size_t)b * cin + ci) * h * wd, h, wd, ty, tx, vd + (size_t)ci * 36);
        for (int co = 0; co < cout; co++) {
          double m[36] = {0}, r[4][6];
          for (int ci = 0; ci < cin; ci++)
            for (int e = 0; e < 36; e++) m[e] += uw[((size_t)co * cin + ci) * 36 + e] * vd[(size_t)ci * 36 + e];
          for (int i = 0; i < 4; i++)
            for (int j = 0; j < 6; j++) {
              r[i][j] = 0;
              for (int k = 0; k < 6; k++) r[i][j] += fabs(AT[i][k]) * m[k * 6 + j];
            }
          for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++) {
              int oy = 4 * ty + i, ox = 4 * tx + j;
              if (oy >= h || ox >= wd) continue;
              double s = 0;
              for (int k = 0; k < 6; k++) s += r[i][k] * fabs(AT[j][k]);
              out[(((size_t)b * cout + co) * h + oy) * wd + ox] = s;
            }
        }
      }
  free(uw);
  free(vd);
}

static cl_mem upload(spx_ctx *ctx, const double *a, size_t n, size_t off) {
  float *f = malloc((n + off) * sizeof(float));
  for (size_t i = 0; i < off; i++) f[i] = 1234.5f;
  for (size_t i = 0; i < n; i++) f[off + i] = (float)a[i];
  cl_mem m = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, (n + off) * sizeof(float), "test", &m));
  if (m) CHECK_OK(ctx, spx_cl_write(ctx, m, 0, (n + off) * sizeof(float), f));
  free(f);
  return m;
}

typedef struct wcase {
  int n, cin, h, w, cout, bias, affine, relu;
} wcase;

static const wcase cases[] = {
    {1, 3, 5, 7, 4, 1, 0, 0},      /* partial tiles on both sides, channels below the GEMM tile */
    {2, 16, 13, 18, 19, 0, 1, 1},  /* N=2, fused affine + ReLU, Cout not a multiple of CONV_TM */
    {1, 33, 21, 17, 40, 1, 1, 0},  /* odd channel counts */
    {1, 64, 9, 9, 8, 1, 0, 1},     /* deep input, one GEMM tile of outputs */
    {1, 8, 4, 4, 8, 0, 0, 0},      /* exactly one tile */
    {1, 5, 1, 1, 3, 1, 0, 0},      /* 1x1 image: only the centre tap sees data */
    {1, 24, 40, 52, 24, 1, 1, 1},  /* several GEMM work-groups of tiles */
};

/* Runs case c (forward into y, then backward data accumulating into dx prefilled with ones) on
 * the Winograd path; checks both against the reference within the derived bound. outs (if not
 * NULL) receive the device y and dx. */
static void run_case(spx_ctx *ctx, const wcase *c, spx_conv2d_workspace *ws, float **outs) {
  const size_t off = 3;
  size_t nx = (size_t)c->n * c->cin * c->h * c->w, ny = (size_t)c->n * c->cout * c->h * c->w;
  size_t nw = (size_t)c->cout * c->cin * 9, nb = (size_t)c->cout;
  double *x = malloc(nx * 8), *w = malloc(nw * 8), *b = malloc(nb * 8), *sc = malloc(nb * 8), *sh = malloc(nb * 8);
  double *dy = malloc(ny * 8), *y = malloc(ny * 8), *dx = calloc(nx, 8), *wy = malloc(ny * 8), *wdx = malloc(nx * 8);
  double *wt = malloc(nw * 8);
  fill_rand(x, nx), fill_rand(w, nw), fill_rand(b, nb), fill_rand(sc, nb), fill_rand(sh, nb), fill_rand(dy, ny);
  spx_conv2d_shape s = {c->n, c->cin, c->h, c->w, c->cout, 3, 1, 1};
  spx_ref_conv2d_forward(&s, x, w, c->bias ? b : NULL, c->affine ? sc : NULL, c->affine ? sh : NULL, c->relu, y);
  spx_ref_conv2d_backward(&s, x, w, dy, dx, NULL, NULL);
  wino_magnitude(c->n, c->cin, c->h, c->w, c->cout, x, w, wy);
  /* backward data = conv of dy with the flipped, transposed weights */
  for (int co = 0; co < c->cout; co++)
    for (int ci = 0; ci < c->cin; ci++)
      for (int k = 0; k < 9; k++) wt[((size_t)ci * c->cout + co) * 9 + k] = w[((size_t)co * c->cin + ci) * 9 + 8 - k];
  wino_magnitude(c->n, c->cout, c->h, c->w, c->cin, dy, wt, wdx);

  cl_mem mx = upload(ctx, x, nx, off), mw = upload(ctx, w, nw, off), mb = upload(ctx, b, nb, off);
  cl_mem msc = upload(ctx, sc, nb, off), msh = upload(ctx, sh, nb, off), mdy = upload(ctx, dy, ny, off);
  cl_mem my = NULL, mdx = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, (ny + off + 8) * 4, "y", &my));
  CHECK_OK(ctx, spx_cl_alloc(ctx, (nx + off) * 4, "dx", &mdx));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, my, 0, ny + off + 8, -7.0f));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, mdx, 0, nx + off, 1.0f));
  spx_tensor tx = spx_tensor_view(mx, off, c->n, c->cin, c->h, c->w);
  spx_tensor tw = spx_tensor_view(mw, off, c->cout, c->cin, 3, 3);
  spx_tensor tb = spx_tensor_view(mb, off, c->cout, 1, 1, 1);
  spx_tensor tsc = spx_tensor_view(msc, off, c->cout, 1, 1, 1), tsh = spx_tensor_view(msh, off, c->cout, 1, 1, 1);
  spx_tensor ty = spx_tensor_view(my, off, c->n, c->cout, c->h, c->w);
  spx_tensor tdy = spx_tensor_view(mdy, off, c->n, c->cout, c->h, c->w);
  spx_tensor tdx = spx_tensor_view(mdx, off, c->n, c->cin, c->h, c->w);
  spx_conv2d_params p = {3, 1, 1, c->affine ? &tsc : NULL, c->affine ? &tsh : NULL, c->relu, ws};
  CHECK(spx_conv2d_winograd_applies(ctx, 3, 1, 1, c->cin, c->cout, 0));
  CHECK_OK(ctx, spx_conv2d_forward(ctx, &tx, &tw, c->bias ? &tb : NULL, &p, &ty));
  CHECK_OK(ctx, spx_conv2d_backward(ctx, &tx, &tw, &tdy, &tdx, NULL, NULL, &p));
  float *fy = malloc((ny + off + 8) * 4), *fdx = malloc(nx * 4);
  CHECK_OK(ctx, spx_cl_read(ctx, my, 0, (ny + off + 8) * 4, fy));
  CHECK_OK(ctx, spx_cl_read(ctx, mdx, off * 4, nx * 4, fdx));
  const double u = ldexp(1.0, -24);
  double worst_y = 0, worst_dx = 0, rel_y = 0, ymax = 0;
  for (size_t i = 0; i < ny; i++) {
    int co = (int)(i / ((size_t)c->h * c->w) % (size_t)c->cout);
    double sa = c->affine ? fabs(sc[co]) : 1.0;
    double tol = sa * (c->cin + 24) * u * wy[i] + 4 * u * (fabs(y[i]) + sa * fabs(b[co]) + fabs(sh[co])) + 1e-30;
    double err = fabs((double)fy[off + i] - y[i]);
    if (!(err / tol <= worst_y)) worst_y = err / tol;
    if (err > rel_y) rel_y = err;
    if (fabs(y[i]) > ymax) ymax = fabs(y[i]);
  }
  CHECK_MSG(worst_y <= 1, "forward: worst error / bound %.3g", worst_y);
  for (size_t i = 0; i < off; i++) CHECK(fy[i] == -7.0f);
  for (size_t i = 0; i < 8; i++) CHECK(fy[off + ny + i] == -7.0f);
  for (size_t i = 0; i < nx; i++) {
    /* + the rounding of adding into the ones already there */
    double tol = (c->cout + 24) * u * wdx[i] + 2 * u * (1 + fabs(dx[i])) + 1e-30;
    double err = fabs((double)fdx[i] - (1.0 + dx[i]));
    if (!(err / tol <= worst_dx)) worst_dx = err / tol;
  }
  CHECK_MSG(worst_dx <= 1, "backward data: worst error / bound %.3g", worst_dx);
  printf("winograd n=%d cin=%d %dx%d cout=%d%s%s%s: worst error/bound y %.3f dx %.3f; max |y err| %.2e (max |y| %.2f)\n",
         c->n, c->cin, c->h, c->w, c->cout, c->bias ? " bias" : "", c->affine ? " affine" : "",
         c->relu ? " relu" : "", worst_y, worst_dx, rel_y, ymax);
  if (outs) {
    outs[0] = fy, outs[1] = fdx;
  } else {
    free(fy), free(fdx);
  }
  spx_cl_free(&mx), spx_cl_free(&mw), spx_cl_free(&mb), spx_cl_free(&msc), spx_cl_free(&msh), spx_cl_free(&mdy);
  spx_cl_free(&my), spx_cl_free(&mdx);
  free(x), free(w), free(b), free(sc), free(sh), free(dy), free(y), free(dx), free(wy), free(wdx), free(wt);
}

static void test_vs_reference(void) {
  /* every 3x3/s1/p1 layer takes the Winograd path, training calls (backward data) included */
  setenv("SPX_TUNE_CONV_WINO_MINC", "1", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  spx_conv2d_workspace ws = {0};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) run_case(ctx, &cases[i], i % 2 ? &ws : NULL, NULL);
  spx_conv2d_workspace_release(&ws);
  spx_ctx_destroy(ctx);
}

static void test_deterministic(void) {
  setenv("SPX_TUNE_CONV_WINO_MINC", "1", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  const wcase *c = &cases[2];
  float *a[2], *b[2];
  unsigned long long keep = rng;
  spx_conv2d_workspace ws = {0};
  run_case(ctx, c, &ws, a);
  rng = keep;
  run_case(ctx, c, NULL, b);
  spx_conv2d_workspace_release(&ws);
  size_t ny = (size_t)c->n * c->cout * c->h * c->w + 3 + 8, nx = (size_t)c->n * c->cin * c->h * c->w;
  CHECK_MSG(memcmp(a[0], b[0], ny * 4) == 0, "forward differs between runs");
  CHECK_MSG(memcmp(a[1], b[1], nx * 4) == 0, "backward data differs between runs");
  free(a[0]), free(a[1]), free(b[0]), free(b[1]);
  spx_ctx_destroy(ctx);
}

/* Passes over the batch (CONV_WINO_CHUNK: 0 = one sample per pass) give the same bits as one pass
 * over the whole batch (case 1 has N = 2). */
static void test_chunked(void) {
  setenv("SPX_TUNE_CONV_WINO_MINC", "1", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  const wcase *c = &cases[1];
  float *r[2][2];
  unsigned long long keep = rng;
  for (int k = 0; k < 2; k++) {
    setenv("SPX_TUNE_CONV_WINO_CHUNK", k ? "0" : "32", 1);
    spx_ctx *ctx;
    CHECK(spx_ctx_create(&ctx) == SPX_OK);
    CHECK_OK(ctx, spx_device_open(ctx, NULL));
    rng = keep;
    spx_conv2d_workspace ws = {0};
    run_case(ctx, c, &ws, r[k]);
    spx_conv2d_workspace_release(&ws);
    spx_ctx_destroy(ctx);
  }
  unsetenv("SPX_TUNE_CONV_WINO_CHUNK");
  size_t ny = (size_t)c->n * c->cout * c->h * c->w + 3 + 8, nx = (size_t)c->n * c->cin * c->h * c->w;
  CHECK_MSG(memcmp(r[0][0], r[1][0], ny * 4) == 0, "forward differs with one sample per pass");
  CHECK_MSG(memcmp(r[0][1], r[1][1], nx * 4) == 0, "backward data differs with one sample per pass");
  for (int k = 0; k < 2; k++) free(r[k][0]), free(r[k][1]);
}

/* The rule: only 3x3 / stride 1 / pad 1 with both channel counts >= CONV_WINO_MINC; 0 = never;
 * training calls only with CONV_WINO_TRAIN. */
static void test_rule(void) {
  /* tunables are read when the device opens: each setting reopens it */
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  setenv("SPX_TUNE_CONV_WINO_MINC", "32", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "0", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(spx_conv2d_winograd_applies(ctx, 3, 1, 1, 32, 64, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 32, 64, 0));
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(spx_conv2d_winograd_applies(ctx, 3, 1, 1, 32, 64, 0));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 31, 64, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 64, 16, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 2, 1, 64, 64, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 0, 64, 64, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 1, 1, 0, 64, 64, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 5, 1, 1, 64, 64, 1));
  setenv("SPX_TUNE_CONV_WINO_MINC", "0", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 64, 64, 1));
  unsetenv("SPX_TUNE_CONV_WINO_MINC");
  unsetenv("SPX_TUNE_CONV_WINO_TRAIN");
  spx_ctx_destroy(ctx);
}

/* The transform matrices multiply out to the 3-tap correlation (sum_a A^T_ia G_ak B^T_ap = 1 iff
 * p = i + k), and their rms error gain (see the top of the file) is what SPX_WINO_RMS_GAIN says. */
static void test_gain(void) {
  double worst = 0, ident = wt_identity_error();
  CHECK_MSG(ident < 1e-12, "A^T G B^T is off the correlation by %g", ident);
  for (int i = 0; i < 4; i++) {
    double si = 0;
    for (int a = 0; a < 6; a++)
      si += AT[i][a] * AT[i][a] * wt_row_sq(&G[0][0], 3, 1, a, 3) * wt_row_sq(&BT[0][0], 6, 1, a, 6);
    if (si > worst) worst = si;
  }
  double gain = worst / 3.0; /* sqrt(S_3 S_3) / 3 */
  printf("winograd rms error gain over direct: %.2f (SPX_WINO_RMS_GAIN %d)\n", gain, SPX_WINO_RMS_GAIN);
  CHECK(gain > 31.0 && gain <= SPX_WINO_RMS_GAIN);
}

int main(void) {
  SPX_RUN(test_gain);
  SPX_RUN(test_vs_reference);
  SPX_RUN(test_deterministic);
  SPX_RUN(test_chunked);
  SPX_RUN(test_rule);
  return spx_test_summary();
}
