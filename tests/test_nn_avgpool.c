/* 3x3 / stride 2 / pad 1 average pooling, count_include_pad = False (kernels/pool.cl): FD check of
 * the reference, reference vs nn.AvgPool2d (tests/data/avgpool/make_avgpool_golden.py, float64),
 * device forward and backward vs reference on odd and tiny shapes, accumulate semantics, reruns
 * bit-identical. */
#include "nn/pool.h"
#include "nn_testutil.h"

struct ap_args {
  int n, c, h, w;
};
static void ap_f(void *u, const double *in, double *out) {
  struct ap_args *a = u;
  spx_ref_avgpool3_forward(in, a->n, a->c, a->h, a->w, out);
}
static void ap_b(void *u, const double *in, const double *dout, double *din) {
  struct ap_args *a = u;
  (void)in;
  spx_ref_avgpool3_backward(dout, a->n, a->c, a->h, a->w, din);
}

static void test_reference(void) {
  struct ap_args a = {1, 2, 5, 6};
  double x[60];
  unsigned long long s = 3;
  for (int i = 0; i < 60; i++) x[i] = spx_t_uniform(&s);
  double e = spx_fd_check(ap_f, ap_b, &a, x, 60, 2 * 3 * 3, 1e-5, 9);
  CHECK_MSG(e < 1e-8, "fd error %.3g", e);
}

#define GOLDEN SPX_TEST_DATA "/avgpool/avgpool_golden.txt"

static void test_golden(void) {
  for (int k = 0; k < 3; k++) {
    char nm[5][16];
    const char *base[5] = {"shape", "x", "g", "y", "dx"};
    double *v[5];
    int cnt[5];
    for (int i = 0; i < 5; i++) {
      snprintf(nm[i], sizeof nm[i], "%s%d", base[i], k);
      v[i] = spx_golden_get(GOLDEN, nm[i], &cnt[i]);
    }
    CHECK(v[0] && v[1] && v[2] && v[3] && v[4] && cnt[0] == 4);
    if (v[0] && v[1] && v[2] && v[3] && v[4] && cnt[0] == 4) {
      int n = (int)v[0][0], c = (int)v[0][1], h = (int)v[0][2], w = (int)v[0][3];
      int ny = n * c * spx_avgpool3_out(h) * spx_avgpool3_out(w);
      CHECK(cnt[1] == n * c * h * w && cnt[3] == ny && cnt[2] == ny && cnt[4] == cnt[1]);
      if (cnt[3] == ny && cnt[4] == cnt[1]) {
        double *y = malloc(8 * (size_t)ny), *dx = calloc((size_t)cnt[1], 8), ey = 0, ed = 0;
        spx_ref_avgpool3_forward(v[1], n, c, h, w, y);
        spx_ref_avgpool3_backward(v[2], n, c, h, w, dx);
        for (int i = 0; i < ny; i++) ey = fmax(ey, fabs(y[i] - v[3][i]));
        for (int i = 0; i < cnt[1]; i++) ed = fmax(ed, fabs(dx[i] - v[4][i]));
        CHECK_MSG(ey < 1e-12 && ed < 1e-12, "case %d vs torch: y %.3g dx %.3g", k, ey, ed);
        free(y), free(dx);
      }
    }
    for (int i = 0; i < 5; i++) free(v[i]);
  }
}

static void device_case(spx_ctx *ctx, int n, int c, int h, int w) {
  int oh = spx_avgpool3_out(h), ow = spx_avgpool3_out(w);
  size_t nin = (size_t)n * c * h * w, nout = (size_t)n * c * oh * ow;
  float *x = malloc(4 * nin), *g = malloc(4 * nout), *pre = malloc(4 * nin), *got = malloc(4 * nin), *got2 = malloc(4 * nin);
  double *xd = malloc(8 * nin), *gd = malloc(8 * nout), *ref = malloc(8 * nin);
  unsigned long long s = 31 + (unsigned long long)w;
  spx_nt_rand(x, nin, -1, 1, &s), spx_nt_rand(g, nout, -1, 1, &s), spx_nt_rand(pre, nin, -1, 1, &s);
  spx_nt_to_double(x, xd, nin), spx_nt_to_double(g, gd, nout);
  spx_tensor tx, ty, tg, tdx;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, oh, ow, &ty));
  CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, oh, ow, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
  CHECK_OK(ctx, spx_avgpool3_forward(ctx, &tx, &ty));
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got));
  spx_ref_avgpool3_forward(xd, n, c, h, w, ref);
  CHECK_CLOSE_ARR(got, ref, nout, 1e-3, 1e-4); /* |err| < 1e-7: float sums of 9 */
  CHECK_OK(ctx, spx_avgpool3_backward(ctx, &tg, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got));
  spx_nt_to_double(pre, ref, nin);
  spx_ref_avgpool3_backward(gd, n, c, h, w, ref);
  CHECK_CLOSE_ARR(got, ref, nin, 1e-3, 1e-4);
  CHECK_OK(ctx, spx_cl_write(ctx, tdx.mem, tdx.off * 4, 4 * nin, pre));
  CHECK_OK(ctx, spx_avgpool3_backward(ctx, &tg, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got2));
  CHECK(memcmp(got, got2, 4 * nin) == 0);
  CHECK(spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &tdx));
  CHECK(spx_avgpool3_forward(ctx, &tx, &tx) == SPX_E_ARG);
  spx_nt_free(&tx), spx_nt_free(&ty), spx_nt_free(&tg), spx_nt_free(&tdx);
  free(x), free(g), free(pre), free(got), free(got2), free(xd), free(gd), free(ref);
}

static void test_device(void) {
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
  if (!ctx) return;
  device_case(ctx, 2, 3, 37, 53);
  device_case(ctx, 1, 7, 38, 52);
  device_case(ctx, 1, 1, 1, 2);
  device_case(ctx, 1, 2, 2, 3);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_reference);
  SPX_RUN(test_golden);
  SPX_RUN(test_device);
  return spx_test_summary();
}
