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
#include "smplpix/smplpix.h"
#include "test.h"
#include "wino_case.h"

static const wcase cases[] = {
    {1, 3, 5, 7, 4, 1, 0, 0},      /* partial tiles on both sides, channels below the GEMM tile */
    {2, 16, 13, 18, 19, 0, 1, 1},  /* N=2, fused affine + ReLU, Cout not a multiple of CONV_TM */
    {1, 33, 21, 17, 40, 1, 1, 0},  /* odd channel counts */
    {1, 64, 9, 9, 8, 1, 0, 1},     /* deep input, one GEMM tile of outputs */
    {1, 8, 4, 4, 8, 0, 0, 0},      /* exactly one tile */
    {1, 5, 1, 1, 3, 1, 0, 0},      /* 1x1 image: only the centre tap sees data */
    {1, 24, 40, 52, 24, 1, 1, 1},  /* several GEMM work-groups of tiles */
};

static void test_vs_reference(void) {
  /* every 3x3/s1/p1 layer takes the Winograd path, training calls (backward data) included */
  setenv("SPX_TUNE_CONV_WINO_MINC", "1", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  spx_op_workspace ws = {0};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) run_case(ctx, &cases[i], i % 2 ? &ws : NULL, NULL);
  spx_op_workspace_release(&ws);
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
  spx_op_workspace ws = {0};
  run_case(ctx, c, &ws, a);
  rng = keep;
  run_case(ctx, c, NULL, b);
  spx_op_workspace_release(&ws);
  size_t ny = (size_t)c->n * c->cout * c->h * c->w + 3 + 8, nx = (size_t)c->n * c->cin * c->h * c->w;
  CHECK_MSG(memcmp(a[0], b[0], ny * 4) == 0, "forward differs between runs");
  CHECK_MSG(memcmp(a[1], b[1], nx * 4) == 0, "backward data differs between runs");
  free(a[0]), free(a[1]), free(b[0]), free(b[1]);
  spx_ctx_destroy(ctx);
}

/* Case c run with the tunable `name` at v0 and at v1 (a fresh context each): forward and backward
 * data must give the same bits. */
static void same_bits_under(const wcase *c, const char *name, const char *v0, const char *v1, const char *what) {
  setenv("SPX_TUNE_CONV_WINO_MINC", "1", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  float *r[2][2];
  unsigned long long keep = rng;
  for (int k = 0; k < 2; k++) {
    setenv(name, k ? v1 : v0, 1);
    spx_ctx *ctx;
    CHECK(spx_ctx_create(&ctx) == SPX_OK);
    CHECK_OK(ctx, spx_device_open(ctx, NULL));
    rng = keep;
    spx_op_workspace ws = {0};
    run_case(ctx, c, &ws, r[k]);
    spx_op_workspace_release(&ws);
    spx_ctx_destroy(ctx);
  }
  unsetenv(name);
  size_t ny = (size_t)c->n * c->cout * c->h * c->w + 3 + 8, nx = (size_t)c->n * c->cin * c->h * c->w;
  CHECK_MSG(memcmp(r[0][0], r[1][0], ny * 4) == 0, "%dx%dx%dx%d: forward differs %s", c->n, c->cin, c->h, c->w, what);
  CHECK_MSG(memcmp(r[0][1], r[1][1], nx * 4) == 0, "%dx%dx%dx%d: backward data differs %s", c->n, c->cin, c->h, c->w,
            what);
  for (int k = 0; k < 2; k++) free(r[k][0]), free(r[k][1]);
}

/* Passes over the batch (CONV_WINO_CHUNK: 0 = one sample per pass) give the same bits as one pass
 * over the whole batch (case 1 has N = 2). */
static void test_chunked(void) {
  same_bits_under(&cases[1], "SPX_TUNE_CONV_WINO_CHUNK", "32", "0", "with one sample per pass");
}

/* Packed tiles (CONV_WINO_PACK 1: no GEMM columns for the padding of tile rows to CONV_VW) give
 * the same bits as row-padded ones (0), forward and backward data, on every case (with CONV_VW
 * 16 the rows of 2, 5, 5, 3, 1, 1 and 13 tiles are all packed: work-items span several tile
 * rows, a row's last work-item is partial) and at 38x51 (13 -> 16), 77x102 (26 -> 32), N = 2. */
static void test_packed(void) {
  const wcase extra[] = {{2, 16, 38, 51, 24, 1, 1, 0}, {1, 32, 77, 102, 16, 0, 0, 1}};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
    same_bits_under(&cases[i], "SPX_TUNE_CONV_WINO_PACK", "0", "1", "with packed tiles");
  for (size_t i = 0; i < 2; i++) same_bits_under(&extra[i], "SPX_TUNE_CONV_WINO_PACK", "0", "1", "with packed tiles");
}

/* The rule: only 3x3 / stride 1 / pad 1 with both channel counts >= CONV_WINO_MINC, or in
 * inference >= half of it on images of at most CONV_WINO_SMALL_HW pixels; 0 = never; training
 * calls only with CONV_WINO_TRAIN. */
static void test_rule(void) {
  /* tunables are read when the device opens: each setting reopens it */
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  const int big = 1 << 30;
  setenv("SPX_TUNE_CONV_WINO_MINC", "32", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "0", 1);
  setenv("SPX_TUNE_CONV_WINO_SMALL_HW", "1000", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(spx_conv2d_winograd_applies(ctx, 3, 1, 1, 32, 64, big, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 32, 64, big, 0));
  /* small images: from 16 channels in inference, never in training */
  CHECK(spx_conv2d_winograd_applies(ctx, 3, 1, 1, 16, 64, 1000, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 15, 64, 1000, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 16, 64, 1001, 1));
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(spx_conv2d_winograd_applies(ctx, 3, 1, 1, 32, 64, big, 0));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 16, 64, 1000, 0));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 31, 64, big, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 64, 16, big, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 2, 1, 64, 64, big, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 0, 64, 64, big, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 1, 1, 0, 64, 64, big, 1));
  CHECK(!spx_conv2d_winograd_applies(ctx, 5, 1, 1, 64, 64, 1000, 1));
  setenv("SPX_TUNE_CONV_WINO_SMALL_HW", "0", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 16, 64, 1, 1));
  setenv("SPX_TUNE_CONV_WINO_MINC", "0", 1);
  setenv("SPX_TUNE_CONV_WINO_SMALL_HW", "1000", 1);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(!spx_conv2d_winograd_applies(ctx, 3, 1, 1, 64, 64, 1000, 1));
  unsetenv("SPX_TUNE_CONV_WINO_MINC");
  unsetenv("SPX_TUNE_CONV_WINO_SMALL_HW");
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
  SPX_RUN(test_packed);
  SPX_RUN(test_rule);
  return spx_test_summary();
}
