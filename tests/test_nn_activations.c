/* Activations (kernels/activations.cl), every kind of SPX_ACT_LIST: FD check of every reference
 * backward; device forward and backward (accumulating, from the documented saved tensor) vs the
 * double reference on an odd shape at an offset; two runs bit-identical; in place. */
#include "nn/activations.h"
#include "nn_testutil.h"

struct act_args {
  spx_act_kind kind;
  double slope;
  size_t n;
};
static void act_f(void *u, const double *in, double *out) {
  struct act_args *a = u;
  spx_ref_act_forward(a->kind, a->slope, in, out, a->n);
}
static void act_b(void *u, const double *in, const double *dout, double *din) {
  struct act_args *a = u;
  double y[64];
  spx_ref_act_forward(a->kind, a->slope, in, y, a->n);
  spx_ref_act_backward(a->kind, a->slope, spx_act_saves_output(a->kind) ? y : in, dout, din, a->n);
}

static void test_reference_fd(void) {
  double x[64];
  unsigned long long s = 5;
  for (int i = 0; i < 64; i++) {
    x[i] = 6 * spx_t_uniform(&s) - 3;
    if (fabs(x[i]) < 1e-3) x[i] = 0.5; /* keep away from the kink */
  }
  for (int k = 0; k < SPX_ACT_COUNT; k++) {
    struct act_args a = {(spx_act_kind)k, 0.2, 64};
    double e = spx_fd_check(act_f, act_b, &a, x, 64, 64, 1e-6, 7 + k);
    CHECK_MSG(e < 1e-7, "%s: fd error %.3g", spx_act_name((spx_act_kind)k), e);
  }
  /* PyTorch's choices at exactly 0: relu' = 0, leaky' = slope */
  double z = 0, one = 1, d = 0;
  spx_ref_act_backward(SPX_ACT_RELU, 0, &z, &one, &d, 1);
  CHECK(d == 0);
  spx_ref_act_backward(SPX_ACT_LEAKY_RELU, 0.01, &z, &one, &d, 1);
  CHECK(d == 0.01);
}

static void test_device(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  int n = 2, c = 3, h = 37, w = 53;
  size_t cnt = (size_t)n * c * h * w;
  float *x = malloc(4 * cnt), *g = malloc(4 * cnt), *pre = malloc(4 * cnt), *got = malloc(4 * cnt), *got2 = malloc(4 * cnt);
  double *xd = malloc(8 * cnt), *yd = malloc(8 * cnt), *gd = malloc(8 * cnt), *dx = malloc(8 * cnt);
  float *yf = malloc(4 * cnt);
  unsigned long long s = 21;
  spx_nt_rand(x, cnt, -5, 5, &s), spx_nt_rand(g, cnt, -1, 1, &s), spx_nt_rand(pre, cnt, -1, 1, &s);
  x[0] = 0.0f;
  spx_nt_to_double(x, xd, cnt), spx_nt_to_double(g, gd, cnt);
  for (int k = 0; k < SPX_ACT_COUNT; k++) {
    spx_act_kind kind = (spx_act_kind)k;
    float slope = 0.01f;
    spx_tensor tx, ty, tg, tdx;
    CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
    CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, h, w, &ty));
    CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, h, w, &tg));
    CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
    CHECK_OK(ctx, spx_act_forward(ctx, kind, slope, &tx, &ty));
    CHECK_OK(ctx, spx_nt_download(ctx, &ty, yf));
    spx_ref_act_forward(kind, slope, xd, yd, cnt);
    /* exp/tanh are within a few ulp in OpenCL */
    CHECK_MSG(spx_nt_err(yf, yd, cnt, 1e-7) < 2e-6, "%s forward: %.3g", spx_act_name(kind),
              spx_nt_err(yf, yd, cnt, 1e-7));
    /* backward from the saved tensor; the reference uses the device's float y like training would */
    const spx_tensor *saved = spx_act_saves_output(kind) ? &ty : &tx;
    double *sd = malloc(8 * cnt);
    if (spx_act_saves_output(kind))
      spx_nt_to_double(yf, sd, cnt);
    else
      memcpy(sd, xd, 8 * cnt);
    spx_nt_to_double(pre, dx, cnt);
    spx_ref_act_backward(kind, slope, sd, gd, dx, cnt);
    CHECK_OK(ctx, spx_act_backward(ctx, kind, slope, saved, &tg, &tdx));
    CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got));
    /* float rounding of (1 - y*y) etc. is absolute (~1e-7), hence the atol */
    CHECK_MSG(spx_nt_err(got, dx, cnt, 0.1) < 1e-5, "%s backward: %.3g", spx_act_name(kind),
              spx_nt_err(got, dx, cnt, 0.1));
    /* determinism: a second identical run gives the same bits */
    CHECK_OK(ctx, spx_cl_write(ctx, tdx.mem, tdx.off * 4, 4 * cnt, pre));
    CHECK_OK(ctx, spx_act_backward(ctx, kind, slope, saved, &tg, &tdx));
    CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got2));
    CHECK(memcmp(got, got2, 4 * cnt) == 0);
    CHECK(spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &tdx));
    /* in place */
    CHECK_OK(ctx, spx_act_forward(ctx, kind, slope, &tx, &tx));
    CHECK_OK(ctx, spx_nt_download(ctx, &tx, got));
    CHECK(memcmp(got, yf, 4 * cnt) == 0);
    free(sd);
    spx_nt_free(&tx), spx_nt_free(&ty), spx_nt_free(&tg), spx_nt_free(&tdx);
  }
  spx_tensor a, b;
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 1, 1, 2, 3, &a));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 1, 1, 3, 2, &b));
  CHECK(spx_act_forward(ctx, SPX_ACT_RELU, 0, &a, &b) == SPX_E_ARG);
  CHECK(spx_act_forward(ctx, SPX_ACT_COUNT, 0, &a, &a) == SPX_E_ARG);
  CHECK(!strcmp(spx_act_name(SPX_ACT_COUNT), "?"));
  spx_nt_free(&a), spx_nt_free(&b);
  free(x), free(g), free(pre), free(got), free(got2), free(xd), free(yd), free(gd), free(dx), free(yf);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_reference_fd);
  SPX_RUN(test_device);
  return spx_test_summary();
}
