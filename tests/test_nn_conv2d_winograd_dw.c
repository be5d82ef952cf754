/* conv2d Winograd F(4x4,3x3) weight gradient (kernels/conv2d_winograd_dw.cl): against the double
 * reference of the direct convolution's weight gradient (lib/nn/conv2d_ref.c) within a bound derived
 * from the transforms, against finite differences of the reference forward, accumulation into dw,
 * bit-identical reruns and batch splits, and the rule that picks the path.
 *
 * Tolerance, derived from the transforms (not fitted): the device computes, per weight pair,
 *   dw = G^T [ sum_n sum_t (A dY A^T) .* (B^T d B) ] G
 * in float32 (d the 6x6 input patch of tile t, dY its 4x4 output gradient). Stages: the input
 * transform 2 passes of <= 4 additions (<= ~6u relative to |B^T| |d| |B|), the output-gradient
 * transform 2 passes of <= 4 terms times exact powers of two (<= ~6u relative to |A| |dY| |A^T|),
 * the product 1 rounding, the tile sum T terms per sample (fma chains of T / CONV_VW per lane plus
 * a 4-level lane sum: <= (T + 4) u whatever CONV_VW) and one addition per sample (N u), the
 * weight-side transform 2 passes of <= 5 terms with the constants 1/6, 1/12, 1/24 rounded
 * (<= ~10u relative to |G^T| |P| |G|), u = 2^-24. To first order the error is bounded by
 *   (T + N + 30) u * W,   W = |G^T| [ sum_n sum_t (|A| |dY| |A^T|) .* (|B^T| |d| |B|) ] |G|
 * computed here in double with absolute values, plus the rounding of adding into dw (2u of the
 * result). A wrong transform or index errs by the order of dw itself, far above the bound.
 *
 * Typical error against the direct weight gradient's (test_gain): with every rounding an
 * independent relative error u, the direct dw is one sum of 16 N T products (rms ~ u sqrt(16 N T)
 * s_dy s_x); Winograd's dominant roundings are those of the 36 N T-term GEMM sums, rms
 * u sqrt(N T) |Q_ab V_ab| with E[Q_ab^2] = a2_a a2_b s_dy^2, E[V_ab^2] = b2_a b2_b s_x^2
 * (a2_a = sum_j A_aj^2, b2_a = sum_p BT_ap^2), mixed by G^T . G. So
 *   rms_wino / rms_direct = sqrt(S_k S_l) / 4,   S_k = sum_a G_ak^2 a2_a b2_a,
 * largest for k = l = 2 (S_2 = 96.8): 24.2 <= SPX_WINO_RMS_GAIN (32), so the golden tests'
 * widening by SPX_WINO_RMS_GAIN when Winograd trains covers the weight gradient too. */
#include <stdlib.h>

#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "nn_testutil.h"
#include "smplpix/smplpix.h"
#include "test.h"
#include "wino_test.h"

static unsigned long long rng = 0x13198a2e03707344ULL;

/* W (see the top of the file) for every dw element of a 3x3/s1/p1 conv, x [n][cin][h][w],
 * dy [n][cout][h][w]; out [cout][cin][9]. */
static void dw_magnitude(int n, int cin, int h, int wd, int cout, const double *x, const double *dy, double *out) {
  const int th = (h + 3) / 4, tw = (wd + 3) / 4;
  double *vd = malloc((size_t)cin * 36 * 8), *qd = malloc((size_t)cout * 36 * 8), *p = calloc((size_t)cout * cin * 36, 8);
  for (int b = 0; b < n; b++)
    for (int ty = 0; ty < th; ty++)
      for (int tx = 0; tx < tw; tx++) {
        for (int ci = 0; ci < cin; ci++) /* |B^T| |d| |B| */
          wt_input_magnitude(x + ((size_t)b * cin + ci) * h * wd, h, wd, ty, tx, vd + (size_t)ci * 36);
        for (int co = 0; co < cout; co++) { /* |A| |dY| |A^T|, A = (A^T)^T */
          double g[16];
          for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++) {
              int yy = 4 * ty + i, xx = 4 * tx + j;
              g[i * 4 + j] = yy < h && xx < wd ? fabs(dy[(((size_t)b * cout + co) * h + yy) * wd + xx]) : 0;
            }
          wt_abs_sandwich(&WT_AT[0][0], 1, 6, 6, 4, g, qd + (size_t)co * 36);
        }
        for (int co = 0; co < cout; co++)
          for (int ci = 0; ci < cin; ci++)
            for (int e = 0; e < 36; e++) p[((size_t)co * cin + ci) * 36 + e] += qd[(size_t)co * 36 + e] * vd[(size_t)ci * 36 + e];
      }
  for (size_t i = 0; i < (size_t)cout * cin; i++) /* |G^T| p |G|, G^T = G read transposed */
    wt_abs_sandwich(&WT_G[0][0], 1, 3, 3, 6, p + i * 36, out + i * 9);
  free(vd), free(qd), free(p);
}

typedef struct dcase {
  int n, cin, h, w, cout;
} dcase;

static const dcase cases[] = {
    {1, 3, 5, 7, 4},    /* partial tiles on both sides, channels below the register tile */
    {3, 16, 13, 18, 19}, /* N=3, Cout not a multiple of CONV_DW_TM */
    {1, 33, 21, 17, 40}, /* odd channel counts */
    {2, 64, 9, 9, 8},    /* deep input */
    {1, 8, 4, 4, 8},     /* exactly one tile */
    {1, 5, 1, 1, 3},     /* 1x1 image: only the centre tap sees data */
    {1, 24, 40, 70, 24}, /* several vectors of tiles per row, several tile blocks */
};

/* Runs case c's weight gradient on the Winograd path into dw prefilled with `pre` (accumulation);
 * checks it against pre + the reference within the derived bound, and the guards around dw.
 * out (if not NULL) receives the device dw. Returns the worst error / bound. */
static double run_case(spx_ctx *ctx, const dcase *c, spx_op_workspace *ws, float **out) {
  size_t nx = (size_t)c->n * c->cin * c->h * c->w, ny = (size_t)c->n * c->cout * c->h * c->w;
  size_t nw = (size_t)c->cout * c->cin * 9;
  float *fx = malloc(nx * 4), *fdy = malloc(ny * 4), *fw = malloc(nw * 4), *pre = malloc(nw * 4), *got = malloc(nw * 4);
  double *x = malloc(nx * 8), *dy = malloc(ny * 8), *w = malloc(nw * 8), *dw = calloc(nw, 8), *mag = malloc(nw * 8);
  spx_nt_rand(fx, nx, -1, 1, &rng), spx_nt_rand(fdy, ny, -1, 1, &rng), spx_nt_rand(fw, nw, -1, 1, &rng);
  spx_nt_rand(pre, nw, -1, 1, &rng);
  spx_nt_to_double(fx, x, nx), spx_nt_to_double(fdy, dy, ny), spx_nt_to_double(fw, w, nw);
  spx_conv2d_shape s = {c->n, c->cin, c->h, c->w, c->cout, 3, 1, 1};
  spx_ref_conv2d_backward(&s, x, w, dy, NULL, dw, NULL);
  dw_magnitude(c->n, c->cin, c->h, c->w, c->cout, x, dy, mag);
  spx_tensor tx, tdy, tw, tdw;
  CHECK_OK(ctx, spx_nt_upload(ctx, fx, c->n, c->cin, c->h, c->w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, fdy, c->n, c->cout, c->h, c->w, &tdy));
  CHECK_OK(ctx, spx_nt_upload(ctx, fw, c->cout, c->cin, 3, 3, &tw));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, c->cout, c->cin, 3, 3, &tdw));
  spx_conv2d_params p = {3, 1, 1, NULL, NULL, 0, ws, {0, 0, 0}};
  CHECK(spx_conv2d_winograd_dw_applies(ctx, 3, 1, 1, c->cin, c->cout, c->h, c->w));
  CHECK_OK(ctx, spx_conv2d_backward(ctx, &tx, &tw, &tdy, NULL, &tdw, NULL, &p));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdw, got));
  CHECK(spx_nt_guards_ok(ctx, &tdw));
  const double u = ldexp(1.0, -24);
  const int T = (c->h + 3) / 4 * ((c->w + 3) / 4 + ctx->dev->tune.conv_vw); /* >= the device's tile count */
  double worst = 0, emax = 0, dmax = 0;
  for (size_t i = 0; i < nw; i++) {
    double want = pre[i] + dw[i];
    double tol = (T + c->n + 30) * u * mag[i] + 2 * u * (fabs(want) + fabs(pre[i])) + 1e-30;
    double err = fabs((double)got[i] - want);
    if (!(err / tol <= worst)) worst = err / tol;
    emax = fmax(emax, err), dmax = fmax(dmax, fabs(dw[i]));
  }
  CHECK_MSG(worst <= 1, "n=%d cin=%d %dx%d cout=%d: worst error / bound %.3g", c->n, c->cin, c->h, c->w, c->cout,
            worst);
  printf("winograd dw n=%d cin=%d %dx%d cout=%d: worst error/bound %.2e; max |err| %.2e (max |dw| %.2f)\n", c->n,
         c->cin, c->h, c->w, c->cout, worst, emax, dmax);
  if (out) *out = got;
  else free(got);
  spx_nt_free(&tx), spx_nt_free(&tdy), spx_nt_free(&tw), spx_nt_free(&tdw);
  free(fx), free(fdy), free(fw), free(pre), free(x), free(dy), free(w), free(dw), free(mag);
  return worst;
}

static spx_ctx *open_wino(const char *chunk) {
  setenv("SPX_TUNE_CONV_WINO_DW", "1", 1);
  setenv("SPX_TUNE_CONV_WINO_DW_MINHW", "0", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  if (chunk) setenv("SPX_TUNE_CONV_WINO_CHUNK", chunk, 1);
  else unsetenv("SPX_TUNE_CONV_WINO_CHUNK");
  return spx_nt_open();
}

static void test_vs_reference(void) {
  spx_ctx *ctx = open_wino(NULL);
  CHECK(ctx != NULL);
  if (!ctx) return;
  spx_op_workspace ws = {0};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) run_case(ctx, &cases[i], i % 2 ? &ws : NULL, NULL);
  spx_op_workspace_release(&ws);
  spx_ctx_destroy(ctx);
}

/* Same bits on a rerun, with or without a workspace, and with one sample per pass
 * (CONV_WINO_CHUNK = 0) as with the whole batch in one pass (case 1 has N = 3). */
static void test_deterministic(void) {
  const dcase *c = &cases[1];
  size_t nw = (size_t)c->cout * c->cin * 9;
  float *r[3] = {0};
  unsigned long long keep = rng;
  for (int k = 0; k < 3; k++) {
    spx_ctx *ctx = open_wino(k == 2 ? "0" : "32");
    CHECK(ctx != NULL);
    if (!ctx) continue;
    CHECK(k < 2 || spx_conv2d_winograd_dw_need(ctx, c->n, c->cin, c->cout, c->h, c->w, (size_t[3]){0}) == 1);
    CHECK(k == 2 || spx_conv2d_winograd_dw_need(ctx, c->n, c->cin, c->cout, c->h, c->w, (size_t[3]){0}) == c->n);
    spx_op_workspace ws = {0};
    rng = keep;
    run_case(ctx, c, k == 1 ? NULL : &ws, &r[k]);
    spx_op_workspace_release(&ws);
    spx_ctx_destroy(ctx);
  }
  unsetenv("SPX_TUNE_CONV_WINO_CHUNK");
  CHECK_MSG(r[0] && r[1] && !memcmp(r[0], r[1], nw * 4), "dw differs between runs");
  CHECK_MSG(r[0] && r[2] && !memcmp(r[0], r[2], nw * 4), "dw differs with one sample per pass");
  for (int k = 0; k < 3; k++) free(r[k]);
}

/* The device gradient (Winograd) against central differences of the double reference forward's
 * loss L(w) = sum dy .* conv(x, w): L is linear in w, so the differences are exact up to double
 * rounding and the device's float32 error (bounded by run_case's derivation) dominates. */
static void test_finite_differences(void) {
  spx_ctx *ctx = open_wino(NULL);
  CHECK(ctx != NULL);
  if (!ctx) return;
  const int n = 2, cin = 4, h = 7, wd = 9, cout = 3;
  spx_conv2d_shape s = {n, cin, h, wd, cout, 3, 1, 1};
  size_t nx = (size_t)n * cin * h * wd, ny = (size_t)n * cout * h * wd, nw = (size_t)cout * cin * 9;
  float *fx = malloc(nx * 4), *fdy = malloc(ny * 4), *fw = malloc(nw * 4), *got = malloc(nw * 4);
  double *x = malloc(nx * 8), *dy = malloc(ny * 8), *w = malloc(nw * 8), *y = malloc(ny * 8), *mag = malloc(nw * 8);
  spx_nt_rand(fx, nx, -1, 1, &rng), spx_nt_rand(fdy, ny, -1, 1, &rng), spx_nt_rand(fw, nw, -1, 1, &rng);
  spx_nt_to_double(fx, x, nx), spx_nt_to_double(fdy, dy, ny), spx_nt_to_double(fw, w, nw);
  dw_magnitude(n, cin, h, wd, cout, x, dy, mag);
  spx_tensor tx, tdy, tw, tdw;
  CHECK_OK(ctx, spx_nt_upload(ctx, fx, n, cin, h, wd, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, fdy, n, cout, h, wd, &tdy));
  CHECK_OK(ctx, spx_nt_upload(ctx, fw, cout, cin, 3, 3, &tw));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, cout, cin, 3, 3, &tdw));
  spx_conv2d_params p = {3, 1, 1, NULL, NULL, 0, NULL, {0, 0, 0}};
  CHECK_OK(ctx, spx_conv2d_backward(ctx, &tx, &tw, &tdy, NULL, &tdw, NULL, &p));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdw, got));
  const double hstep = 1e-3, u = ldexp(1.0, -24);
  const int T = (h + 3) / 4 * ((wd + 3) / 4 + ctx->dev->tune.conv_vw);
  double worst = 0;
  for (size_t i = 0; i < nw; i++) {
    double keep = w[i], l[2];
    for (int sgn = 0; sgn < 2; sgn++) {
      w[i] = keep + (sgn ? -hstep : hstep);
      spx_ref_conv2d_forward(&s, x, w, NULL, NULL, NULL, 0, y);
      l[sgn] = 0;
      for (size_t j = 0; j < ny; j++) l[sgn] += dy[j] * y[j];
    }
    w[i] = keep;
    double num = (l[0] - l[1]) / (2 * hstep);
    double tol = (T + n + 30) * u * mag[i] + 1e-9 * (1 + fabs(num));
    double e = fabs((double)got[i] - num) / tol;
    if (!(e <= worst)) worst = e;
  }
  CHECK_MSG(worst <= 1, "device dw vs finite differences: worst error / bound %.3g", worst);
  printf("winograd dw vs finite differences: worst error/bound %.3f\n", worst);
  spx_nt_free(&tx), spx_nt_free(&tdy), spx_nt_free(&tw), spx_nt_free(&tdw);
  free(fx), free(fdy), free(fw), free(got), free(x), free(dy), free(w), free(y), free(mag);
  spx_ctx_destroy(ctx);
}

/* The rule: only 3x3 / stride 1 / pad 1 with both channel counts >= CONV_WINO_DW, in training
 * with CONV_WINO_TRAIN, on images of at least CONV_WINO_DW_MINHW pixels; 0 = never. */
static void test_rule(void) {
  spx_ctx *ctx;
  unsetenv("SPX_TUNE_CONV_WINO_DW_MINHW");
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  setenv("SPX_TUNE_CONV_WINO_DW", "32", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(spx_conv2d_winograd_dw_applies(ctx, 3, 1, 1, 32, 64, 40, 40));
  CHECK(!spx_conv2d_winograd_dw_applies(ctx, 3, 1, 1, 31, 64, 40, 40));
  CHECK(!spx_conv2d_winograd_dw_applies(ctx, 3, 1, 1, 64, 16, 40, 40));
  CHECK(!spx_conv2d_winograd_dw_applies(ctx, 3, 2, 1, 64, 64, 40, 40));
  CHECK(!spx_conv2d_winograd_dw_applies(ctx, 3, 1, 0, 64, 64, 40, 40));
  CHECK(!spx_conv2d_winograd_dw_applies(ctx, 1, 1, 0, 64, 64, 40, 40));
  setenv("SPX_TUNE_CONV_WINO_DW_MINHW", "1600", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(spx_conv2d_winograd_dw_applies(ctx, 3, 1, 1, 64, 64, 40, 40));
  CHECK(!spx_conv2d_winograd_dw_applies(ctx, 3, 1, 1, 64, 64, 40, 39));
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "0", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(!spx_conv2d_winograd_dw_applies(ctx, 3, 1, 1, 64, 64, 40, 40));
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  setenv("SPX_TUNE_CONV_WINO_DW", "0", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(!spx_conv2d_winograd_dw_applies(ctx, 3, 1, 1, 64, 64, 40, 40));
  unsetenv("SPX_TUNE_CONV_WINO_DW");
  unsetenv("SPX_TUNE_CONV_WINO_DW_MINHW");
  unsetenv("SPX_TUNE_CONV_WINO_TRAIN");
  spx_ctx_destroy(ctx);
}

/* A G B^T multiply out to the 3-tap correlation, and the rms error gain of this direction (see
 * the top of the file) is within SPX_WINO_RMS_GAIN. */
static void test_gain(void) {
  double ident = wt_identity_error(), worst = 0;
  CHECK_MSG(ident < 1e-12, "A G B^T is off the correlation by %g", ident);
  for (int k = 0; k < 3; k++) {
    double sk = 0;
    for (int a = 0; a < 6; a++) /* a2_a: row a of A = column a of A^T */
      sk += WT_G[a][k] * WT_G[a][k] * wt_row_sq(&WT_AT[0][0], 1, 6, a, 4) * wt_row_sq(&WT_BT[0][0], 6, 1, a, 6);
    worst = fmax(worst, sk);
  }
  double gain = worst / 4.0; /* sqrt(S_2 S_2) / 4 */
  printf("winograd dw rms error gain over direct: %.2f (SPX_WINO_RMS_GAIN %d)\n", gain, SPX_WINO_RMS_GAIN);
  CHECK(gain > 24.0 && gain <= SPX_WINO_RMS_GAIN);
}

int main(void) {
  SPX_RUN(test_gain);
  SPX_RUN(test_rule);
  SPX_RUN(test_vs_reference);
  SPX_RUN(test_deterministic);
  SPX_RUN(test_finite_differences);
  return spx_test_summary();
}
