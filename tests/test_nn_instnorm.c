/* Instance norm, affine = False (kernels/instnorm.cl): FD check of the reference; reference vs
 * nn.InstanceNorm2d (tests/data/instnorm/make_instnorm_golden.py, float64); device forward and
 * backward vs reference (large mean offsets, a constant plane, accumulate semantics), both
 * work-group shapes (SPX_TUNE_BN_WG), bit-identical reruns. */
#include "nn/instnorm.h"
#include "nn_testutil.h"

struct in_args {
  int planes, hw;
};
static void in_f(void *u, const double *in, double *out) {
  struct in_args *a = u;
  double save[64];
  spx_ref_instnorm_forward(in, a->planes, a->hw, 1e-5, save, out);
}
static void in_b(void *u, const double *in, const double *dout, double *din) {
  struct in_args *a = u;
  double save[64], y[512];
  spx_ref_instnorm_forward(in, a->planes, a->hw, 1e-5, save, y);
  spx_ref_instnorm_backward(in, a->planes, a->hw, save, dout, din);
}

static void test_reference(void) {
  struct in_args a = {3, 10};
  double x[30];
  unsigned long long s = 4;
  for (int i = 0; i < 30; i++) x[i] = 2 * spx_t_uniform(&s) - 1 + (i / 10);
  double e = spx_fd_check(in_f, in_b, &a, x, 30, 30, 1e-5, 7);
  CHECK_MSG(e < 1e-6, "fd error %.3g", e);
}

#define GOLDEN SPX_TEST_DATA "/instnorm/instnorm_golden.txt"

static void test_golden(void) {
  int cnt = 0, nx = 0, ng = 0, ny = 0, ndx = 0;
  double *shape = spx_golden_get(GOLDEN, "shape", &cnt), *x = spx_golden_get(GOLDEN, "x", &nx);
  double *g = spx_golden_get(GOLDEN, "g", &ng), *yt = spx_golden_get(GOLDEN, "y", &ny);
  double *dxt = spx_golden_get(GOLDEN, "dx", &ndx);
  CHECK(shape && x && g && yt && dxt && cnt == 4);
  if (shape && x && g && yt && dxt && cnt == 4) {
    int planes = (int)(shape[0] * shape[1]), hw = (int)(shape[2] * shape[3]);
    CHECK(nx == planes * hw && ng == nx && ny == nx && ndx == nx);
    double *y = malloc(8 * (size_t)nx), *dx = calloc((size_t)nx, 8), *save = malloc(16 * (size_t)planes);
    spx_ref_instnorm_forward(x, planes, hw, 1e-5, save, y);
    spx_ref_instnorm_backward(x, planes, hw, save, g, dx);
    double ey = 0, ed = 0;
    for (int i = 0; i < nx; i++) ey = fmax(ey, fabs(y[i] - yt[i])), ed = fmax(ed, fabs(dx[i] - dxt[i]));
    CHECK_MSG(ey < 1e-12 && ed < 1e-12, "vs torch: y %.3g dx %.3g", ey, ed);
    printf("  reference vs torch (float64): y %.3g, dx %.3g\n", ey, ed);
    free(y), free(dx), free(save);
  }
  free(shape), free(x), free(g), free(yt), free(dxt);
}

static void device_case(spx_ctx *ctx, int n, int c, int h, int w, float offset) {
  int planes = n * c, hw = h * w;
  size_t nel = (size_t)planes * hw;
  float *x = malloc(4 * nel), *g = malloc(4 * nel), *pre = malloc(4 * nel), *got = malloc(4 * nel), *got2 = malloc(4 * nel);
  double *xd = malloc(8 * nel), *gd = malloc(8 * nel), *ref = malloc(8 * nel), *save = malloc(16 * (size_t)planes);
  unsigned long long s = 17 + (unsigned long long)h;
  spx_nt_rand(x, nel, -1, 1, &s), spx_nt_rand(g, nel, -1, 1, &s), spx_nt_rand(pre, nel, -1, 1, &s);
  for (size_t i = 0; i < nel; i++) x[i] += offset * (float)(i / (size_t)hw);
  for (int i = 0; i < hw; i++) x[i] = 0.25f; /* a constant plane: var 0, y 0 */
  spx_nt_to_double(x, xd, nel), spx_nt_to_double(g, gd, nel);
  spx_tensor tx, ty, ts, tg, tdx;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, h, w, &ty));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 2 * planes, 1, 1, 1, &ts));
  CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, h, w, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
  CHECK_OK(ctx, spx_instnorm_forward(ctx, &tx, 1e-5f, &ts, &ty));
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got));
  spx_ref_instnorm_forward(xd, planes, hw, 1e-5, save, ref);
  CHECK_CLOSE_ARR(got, ref, nel, 1e-2, 1e-3); /* |err| < ~1e-5 on values ~1 */
  CHECK_OK(ctx, spx_instnorm_backward(ctx, &tx, &ts, &tg, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got));
  spx_nt_to_double(pre, ref, nel);
  spx_ref_instnorm_backward(xd, planes, hw, save, gd, ref);
  CHECK_CLOSE_ARR(got, ref, nel, 1e-2, 2e-3);
  CHECK_OK(ctx, spx_cl_write(ctx, tdx.mem, tdx.off * 4, 4 * nel, pre));
  CHECK_OK(ctx, spx_instnorm_backward(ctx, &tx, &ts, &tg, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got2));
  CHECK(memcmp(got, got2, 4 * nel) == 0);
  CHECK(spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &tdx) && spx_nt_guards_ok(ctx, &ts));
  CHECK(spx_instnorm_forward(ctx, &tx, 1e-5f, &tg, &ty) == SPX_E_ARG); /* save of the wrong size */
  spx_nt_free(&tx), spx_nt_free(&ty), spx_nt_free(&ts), spx_nt_free(&tg), spx_nt_free(&tdx);
  free(x), free(g), free(pre), free(got), free(got2), free(xd), free(gd), free(ref), free(save);
}

static void test_device(void) {
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
  if (!ctx) return;
  device_case(ctx, 2, 3, 37, 53, 10.0f);
  device_case(ctx, 1, 5, 4, 3, 0.0f);
  device_case(ctx, 2, 2, 1, 1, 1.0f);
  spx_ctx_destroy(ctx);
  setenv("SPX_TUNE_BN_WG", "64", 1); /* the strided + tree path (GPUs) */
  ctx = spx_nt_open();
  if (ctx) {
    device_case(ctx, 2, 3, 37, 53, 10.0f);
    device_case(ctx, 2, 2, 1, 1, 1.0f);
    spx_ctx_destroy(ctx);
  }
  unsetenv("SPX_TUNE_BN_WG");
}

int main(void) {
  SPX_RUN(test_reference);
  SPX_RUN(test_golden);
  SPX_RUN(test_device);
  return spx_test_summary();
}
