/* Max pool 2x2/2 floor mode (kernels/pool.cl): FD check of the reference; device forward and
 * backward vs reference on odd shapes (dropped last row/col), with many ties (first max in
 * row-major order wins) and accumulate semantics; bit-identical reruns. */
#include "nn/pool.h"
#include "nn_testutil.h"

struct pool_args {
  int n, c, h, w;
};
static void pool_f(void *u, const double *in, double *out) {
  struct pool_args *a = u;
  spx_ref_maxpool_forward(in, a->n, a->c, a->h, a->w, out);
}
static void pool_b(void *u, const double *in, const double *dout, double *din) {
  struct pool_args *a = u;
  spx_ref_maxpool_backward(in, dout, a->n, a->c, a->h, a->w, din);
}

static void test_reference(void) {
  struct pool_args a = {2, 2, 5, 7};
  int nin = 2 * 2 * 5 * 7, nout = 2 * 2 * 2 * 3;
  double x[140];
  unsigned long long s = 3;
  for (int i = 0; i < nin; i++) x[i] = spx_t_uniform(&s) + i * 1e-3; /* distinct values */
  double e = spx_fd_check(pool_f, pool_b, &a, x, nin, nout, 1e-6, 9);
  CHECK_MSG(e < 1e-7, "fd error %.3g", e);
  /* ties: the first in row-major order gets the gradient; NaN wins */
  double t[4] = {1, 1, 1, 1}, g = 2, d[4] = {0}, y;
  spx_ref_maxpool_backward(t, &g, 1, 1, 2, 2, d);
  CHECK(d[0] == 2 && d[1] == 0 && d[2] == 0 && d[3] == 0);
  double t2[4] = {0, 3, 3, 1}, d2[4] = {0};
  spx_ref_maxpool_backward(t2, &g, 1, 1, 2, 2, d2);
  CHECK(d2[1] == 2 && d2[2] == 0);
  double t3[4] = {0, NAN, 3, 1};
  spx_ref_maxpool_forward(t3, 1, 1, 2, 2, &y);
  CHECK(isnan(y));
}

#define GOLDEN SPX_TEST_DATA "/pool/pool_golden.txt"

/* reference vs F.max_pool2d with ties (tests/data/pool/make_pool_golden.py): exact */
static void test_golden(void) {
  int cnt = 0, nx = 0, ng = 0, ny = 0, ndx = 0;
  double *shape = spx_golden_get(GOLDEN, "shape", &cnt), *x = spx_golden_get(GOLDEN, "x", &nx);
  double *g = spx_golden_get(GOLDEN, "g", &ng), *yt = spx_golden_get(GOLDEN, "y", &ny);
  double *dxt = spx_golden_get(GOLDEN, "dx", &ndx);
  CHECK(shape && x && g && yt && dxt && cnt == 4);
  if (shape && x && g && yt && dxt && cnt == 4) {
    int n = (int)shape[0], c = (int)shape[1], h = (int)shape[2], w = (int)shape[3];
    CHECK(nx == n * c * h * w && ndx == nx && ny == n * c * (h / 2) * (w / 2) && ng == ny);
    double *y = malloc(8 * (size_t)ny), *dx = calloc((size_t)nx, 8);
    spx_ref_maxpool_forward(x, n, c, h, w, y);
    spx_ref_maxpool_backward(x, g, n, c, h, w, dx);
    int ok = 1;
    for (int i = 0; i < ny; i++) ok &= y[i] == yt[i];
    CHECK(ok);
    ok = 1;
    for (int i = 0; i < nx; i++) ok &= (float)dx[i] == (float)dxt[i];
    CHECK_MSG(ok, "gradient routing differs from torch");
    free(y), free(dx);
  }
  free(shape), free(x), free(g), free(yt), free(dxt);
}

static void device_case(spx_ctx *ctx, int n, int c, int h, int w, int levels) {
  int oh = h / 2, ow = w / 2;
  size_t nin = (size_t)n * c * h * w, nout = (size_t)n * c * oh * ow;
  float *x = malloc(4 * nin), *g = malloc(4 * nout), *pre = malloc(4 * nin), *got = malloc(4 * nin), *got2 = malloc(4 * nin);
  double *xd = malloc(8 * nin), *gd = malloc(8 * nout), *ref = malloc(8 * nin);
  unsigned long long s = 31 + levels;
  spx_nt_rand(x, nin, -1, 1, &s), spx_nt_rand(g, nout, -1, 1, &s), spx_nt_rand(pre, nin, -1, 1, &s);
  if (levels)
    for (size_t i = 0; i < nin; i++) x[i] = floorf((x[i] + 1) * 0.5f * levels); /* many ties */
  x[0] = x[1] = x[w] = x[w + 1] = -INFINITY;                                    /* an all -inf window */
  spx_nt_to_double(x, xd, nin), spx_nt_to_double(g, gd, nout);
  spx_tensor tx, ty, tg, tdx;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, oh, ow, &ty));
  CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, oh, ow, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
  CHECK_OK(ctx, spx_maxpool_forward(ctx, &tx, &ty));
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got));
  spx_ref_maxpool_forward(xd, n, c, h, w, ref);
  CHECK_CLOSE_ARR(got, ref, nout, 0, 0);
  CHECK_OK(ctx, spx_maxpool_backward(ctx, &tx, &tg, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got));
  spx_nt_to_double(pre, ref, nin);
  spx_ref_maxpool_backward(xd, gd, n, c, h, w, ref);
  CHECK_CLOSE_ARR(got, ref, nin, 1e-6, 1e-6); /* one float add per element */
  CHECK_OK(ctx, spx_cl_write(ctx, tdx.mem, tdx.off * 4, 4 * nin, pre));
  CHECK_OK(ctx, spx_maxpool_backward(ctx, &tx, &tg, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got2));
  CHECK(memcmp(got, got2, 4 * nin) == 0);
  CHECK(spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &tdx));
  CHECK(spx_maxpool_forward(ctx, &tx, &tx) == SPX_E_ARG);
  spx_nt_free(&tx), spx_nt_free(&ty), spx_nt_free(&tg), spx_nt_free(&tdx);
  free(x), free(g), free(pre), free(got), free(got2), free(xd), free(gd), free(ref);
}

static void test_device(void) {
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
  if (!ctx) return;
  device_case(ctx, 2, 3, 37, 53, 0);
  device_case(ctx, 2, 3, 37, 53, 3);
  device_case(ctx, 1, 2, 38, 51, 2);
  device_case(ctx, 1, 1, 3, 2, 0);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_reference);
  SPX_RUN(test_golden);
  SPX_RUN(test_device);
  return spx_test_summary();
}
