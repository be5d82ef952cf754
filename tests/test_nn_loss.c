/* Reductions and L1 / MSE losses (kernels/loss.cl): FD check of the reference loss gradients
 * (pred and target, mean and sum); device sum/mean and loss values vs double reference for
 * n = 1 .. 10^7 (accuracy of the two-stage compensated sum), gradients with accumulate
 * semantics, bit-identical reruns. */
#include "nn/loss.h"
#include "nn_testutil.h"

struct loss_args {
  spx_loss_kind kind;
  spx_reduction r;
  size_t n;
};
static void loss_f(void *u, const double *in, double *out) {
  struct loss_args *a = u;
  out[0] = spx_ref_loss_forward(a->kind, a->r, in, in + a->n, a->n);
}
static void loss_b(void *u, const double *in, const double *dout, double *din) {
  struct loss_args *a = u;
  spx_ref_loss_backward(a->kind, a->r, in, in + a->n, a->n, dout[0], din, din + a->n);
}

static void test_reference_fd(void) {
  double in[40];
  unsigned long long s = 12;
  for (int i = 0; i < 40; i++) in[i] = 2 * spx_t_uniform(&s) - 1;
  for (int kind = 1; kind <= 2; kind++)
    for (int r = 0; r < 2; r++) {
      struct loss_args a = {(spx_loss_kind)kind, (spx_reduction)r, 20};
      double e = spx_fd_check(loss_f, loss_b, &a, in, 40, 1, 1e-6, 5);
      CHECK_MSG(e < 1e-7, "kind %d red %d: fd error %.3g", kind, r, e);
    }
  double x[3] = {1, 2, 4};
  CHECK(spx_ref_reduce(SPX_REDUCE_MEAN, x, 3) == 7.0 / 3 && spx_ref_reduce(SPX_REDUCE_SUM, x, 3) == 7);
}

static void reduce_case(spx_ctx *ctx, size_t n, float lo, float hi) {
  float *x = malloc(4 * n);
  double *xd = malloc(8 * n);
  unsigned long long s = 100 + n;
  spx_nt_rand(x, n, lo, hi, &s);
  spx_nt_to_double(x, xd, n);
  spx_tensor tx, to;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, (int)n, 1, 1, 1, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 1, 1, 1, 1, &to));
  for (int r = 0; r < 2; r++) {
    float got = 0, again = 0;
    CHECK_OK(ctx, spx_reduce(ctx, (spx_reduction)r, &tx, &to));
    CHECK_OK(ctx, spx_nt_download(ctx, &to, &got));
    CHECK_OK(ctx, spx_reduce(ctx, (spx_reduction)r, &tx, &to));
    CHECK_OK(ctx, spx_nt_download(ctx, &to, &again));
    double ref = spx_ref_reduce((spx_reduction)r, xd, n);
    CHECK_MSG(fabs(got - ref) <= 1e-6 * fabs(ref) + 1e-30, "n=%zu %s: %.9g vs %.9g (rel %.3g)", n, r ? "sum" : "mean",
              got, ref, fabs(got - ref) / fabs(ref));
    CHECK(memcmp(&got, &again, 4) == 0);
  }
  CHECK(spx_nt_guards_ok(ctx, &to));
  spx_nt_free(&tx), spx_nt_free(&to);
  free(x), free(xd);
}

static void test_reduce(spx_ctx *ctx) {
  reduce_case(ctx, 1, 0.5f, 2.0f);
  reduce_case(ctx, 2, 0.5f, 2.0f);
  reduce_case(ctx, 63, -1.0f, 3.0f);
  reduce_case(ctx, 65, -1.0f, 3.0f);
  reduce_case(ctx, 37 * 53 * 6, 0.0f, 1.0f);
  reduce_case(ctx, 10000000, 0.0f, 1.0f); /* a sequential float sum is off by ~8e-5 here */
  reduce_case(ctx, 10000019, 1000.0f, 1001.0f);
}

static void loss_case(spx_ctx *ctx, size_t n) {
  float *p = malloc(4 * n), *t = malloc(4 * n), *pre = malloc(4 * n), *got = malloc(4 * n), *got2 = malloc(4 * n);
  double *pd = malloc(8 * n), *td = malloc(8 * n), *dp = malloc(8 * n), *dt = malloc(8 * n);
  unsigned long long s = 7 + n;
  spx_nt_rand(p, n, -1, 1, &s), spx_nt_rand(t, n, -1, 1, &s), spx_nt_rand(pre, n, -1, 1, &s);
  if (n > 3) t[3] = p[3]; /* a zero difference: L1 gradient 0 like torch's sgn */
  spx_nt_to_double(p, pd, n), spx_nt_to_double(t, td, n);
  spx_tensor tp, tt, to, tg, tdp, tdt;
  float g = 0.75f;
  CHECK_OK(ctx, spx_nt_upload(ctx, p, 1, 1, 1, (int)n, &tp));
  CHECK_OK(ctx, spx_nt_upload(ctx, t, 1, 1, 1, (int)n, &tt));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 1, 1, 1, 1, &to));
  CHECK_OK(ctx, spx_nt_upload(ctx, &g, 1, 1, 1, 1, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, 1, 1, 1, (int)n, &tdp));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, 1, 1, 1, (int)n, &tdt));
  for (int kind = 1; kind <= 2; kind++)
    for (int r = 0; r < 2; r++) {
      float v;
      CHECK_OK(ctx, spx_loss_forward(ctx, (spx_loss_kind)kind, (spx_reduction)r, &tp, &tt, &to));
      CHECK_OK(ctx, spx_nt_download(ctx, &to, &v));
      double ref = spx_ref_loss_forward((spx_loss_kind)kind, (spx_reduction)r, pd, td, n);
      CHECK_MSG(fabs(v - ref) <= 1e-6 * fabs(ref), "n=%zu kind %d red %d: %.9g vs %.9g", n, kind, r, v, ref);
      CHECK_OK(ctx, spx_cl_write(ctx, tdp.mem, tdp.off * 4, 4 * n, pre));
      CHECK_OK(ctx, spx_cl_write(ctx, tdt.mem, tdt.off * 4, 4 * n, pre));
      CHECK_OK(ctx, spx_loss_backward(ctx, (spx_loss_kind)kind, (spx_reduction)r, &tp, &tt, &tg, &tdp, &tdt));
      spx_nt_to_double(pre, dp, n), spx_nt_to_double(pre, dt, n);
      spx_ref_loss_backward((spx_loss_kind)kind, (spx_reduction)r, pd, td, n, g, dp, dt);
      CHECK_OK(ctx, spx_nt_download(ctx, &tdp, got));
      CHECK_CLOSE_ARR(got, dp, n, 1.0, 1e-6); /* O(1) prefill: float rounding is absolute */
      CHECK_OK(ctx, spx_nt_download(ctx, &tdt, got));
      CHECK_CLOSE_ARR(got, dt, n, 1.0, 1e-6);
      CHECK_OK(ctx, spx_cl_write(ctx, tdt.mem, tdt.off * 4, 4 * n, pre));
      CHECK_OK(ctx, spx_loss_backward(ctx, (spx_loss_kind)kind, (spx_reduction)r, &tp, &tt, &tg, NULL, &tdt));
      CHECK_OK(ctx, spx_nt_download(ctx, &tdt, got2));
      CHECK(memcmp(got, got2, 4 * n) == 0);
    }
  CHECK(spx_nt_guards_ok(ctx, &to) && spx_nt_guards_ok(ctx, &tdp) && spx_nt_guards_ok(ctx, &tdt));
  if (n > 1) CHECK(spx_loss_forward(ctx, SPX_LOSS_L1, SPX_REDUCE_MEAN, &tp, &to, &to) == SPX_E_ARG);
  spx_nt_free(&tp), spx_nt_free(&tt), spx_nt_free(&to), spx_nt_free(&tg), spx_nt_free(&tdp), spx_nt_free(&tdt);
  free(p), free(t), free(pre), free(got), free(got2), free(pd), free(td), free(dp), free(dt);
}

static void test_device(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  test_reduce(ctx);
  loss_case(ctx, 1);
  loss_case(ctx, 1001);
  loss_case(ctx, 2 * 3 * 37 * 53);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_reference_fd);
  SPX_RUN(test_device);
  return spx_test_summary();
}
