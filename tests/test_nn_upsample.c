/* Bilinear x2 upsampling (kernels/upsample.cl), align_corners true and false: FD check of the
 * reference backward; reference vs PyTorch's F.interpolate golden (tests/data/upsample); device
 * forward/backward vs reference on odd shapes incl. 1-pixel sides, accumulate semantics,
 * bit-identical reruns. */
#include "nn/upsample.h"
#include "nn_testutil.h"

#define GOLDEN SPX_TEST_DATA "/upsample/upsample_golden.txt"

struct up_args {
  int n, c, h, w, ac;
};
static void up_f(void *u, const double *in, double *out) {
  struct up_args *a = u;
  spx_ref_upsample2x_forward(in, a->n, a->c, a->h, a->w, a->ac, out);
}
static void up_b(void *u, const double *in, const double *dout, double *din) {
  struct up_args *a = u;
  (void)in;
  spx_ref_upsample2x_backward(dout, a->n, a->c, a->h, a->w, a->ac, din);
}

static void test_reference_fd(void) {
  int shapes[][2] = {{3, 5}, {1, 4}, {4, 1}, {2, 2}};
  for (int s = 0; s < 4; s++)
    for (int ac = 0; ac < 2; ac++) {
      struct up_args a = {2, 1, shapes[s][0], shapes[s][1], ac};
      int nin = 2 * a.h * a.w, nout = 8 * a.h * a.w;
      double x[40];
      unsigned long long seed = 3 + s;
      for (int i = 0; i < nin; i++) x[i] = 2 * spx_t_uniform(&seed) - 1;
      double e = spx_fd_check(up_f, up_b, &a, x, nin, nout, 1e-3, 4 + s);
      CHECK_MSG(e < 1e-8, "%dx%d ac=%d: fd error %.3g", a.h, a.w, ac, e);
    }
}

static void test_golden(void) {
  for (int cs = 0; cs < 2; cs++) {
    char name[32];
    int cnt = 0, nx = 0, ng = 0;
    snprintf(name, sizeof name, "shape%d", cs);
    double *shape = spx_golden_get(GOLDEN, name, &cnt);
    snprintf(name, sizeof name, "x%d", cs);
    double *x = spx_golden_get(GOLDEN, name, &nx);
    snprintf(name, sizeof name, "g%d", cs);
    double *g = spx_golden_get(GOLDEN, name, &ng);
    CHECK(shape && x && g);
    if (!shape || !x || !g) return;
    int n = (int)shape[0], c = (int)shape[1], h = (int)shape[2], w = (int)shape[3];
    CHECK(nx == n * c * h * w && ng == 4 * nx);
    for (int ac = 1; ac >= 0; ac--) {
      int ny = 0, ndx = 0;
      snprintf(name, sizeof name, "y%d_%s", cs, ac ? "ac" : "noac");
      double *yt = spx_golden_get(GOLDEN, name, &ny);
      snprintf(name, sizeof name, "dx%d_%s", cs, ac ? "ac" : "noac");
      double *dxt = spx_golden_get(GOLDEN, name, &ndx);
      CHECK(yt && dxt && ny == ng && ndx == nx);
      if (!yt || !dxt) return;
      double *y = malloc(8 * ny), *dx = calloc(nx, 8);
      float *yf = malloc(4 * ny);
      spx_ref_upsample2x_forward(x, n, c, h, w, ac, y);
      spx_ref_upsample2x_backward(g, n, c, h, w, ac, dx);
      for (int i = 0; i < ny; i++) yf[i] = (float)y[i];
      float *dxf = malloc(4 * nx);
      for (int i = 0; i < nx; i++) dxf[i] = (float)dx[i];
      /* torch computes in float: agree to float rounding (atol 1: errors are absolute, ~1e-7 of O(1) data) */
      CHECK_MSG(spx_nt_err(yf, yt, ny, 1.0) < 1e-6, "case %d ac=%d forward vs torch %.3g", cs, ac,
                spx_nt_err(yf, yt, ny, 1.0));
      CHECK_MSG(spx_nt_err(dxf, dxt, nx, 1.0) < 1e-6, "case %d ac=%d backward vs torch %.3g", cs, ac,
                spx_nt_err(dxf, dxt, nx, 1.0));
      free(y), free(dx), free(yf), free(dxf), free(yt), free(dxt);
    }
    free(shape), free(x), free(g);
  }
}

static void device_case(spx_ctx *ctx, int n, int c, int h, int w, int ac) {
  size_t nin = (size_t)n * c * h * w, nout = 4 * nin;
  float *x = malloc(4 * nin), *g = malloc(4 * nout), *pre = malloc(4 * nin), *got = malloc(4 * nout), *got2 = malloc(4 * nin);
  double *xd = malloc(8 * nin), *gd = malloc(8 * nout), *ref = malloc(8 * nout);
  unsigned long long s = 41 + h;
  spx_nt_rand(x, nin, -1, 1, &s), spx_nt_rand(g, nout, -1, 1, &s), spx_nt_rand(pre, nin, -1, 1, &s);
  spx_nt_to_double(x, xd, nin), spx_nt_to_double(g, gd, nout);
  spx_tensor tx, ty, tg, tdx;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, 2 * h, 2 * w, &ty));
  CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, 2 * h, 2 * w, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
  CHECK_OK(ctx, spx_upsample2x_forward(ctx, &tx, ac, &ty));
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got));
  spx_ref_upsample2x_forward(xd, n, c, h, w, ac, ref);
  CHECK_MSG(spx_nt_err(got, ref, nout, 1.0) < 1e-6, "%dx%d ac=%d forward %.3g", h, w, ac, spx_nt_err(got, ref, nout, 1.0));
  CHECK_OK(ctx, spx_upsample2x_backward(ctx, &tg, ac, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got));
  spx_nt_to_double(pre, ref, nin);
  spx_ref_upsample2x_backward(gd, n, c, h, w, ac, ref);
  CHECK_MSG(spx_nt_err(got, ref, nin, 1.0) < 1e-6, "%dx%d ac=%d backward %.3g", h, w, ac, spx_nt_err(got, ref, nin, 1.0));
  CHECK_OK(ctx, spx_cl_write(ctx, tdx.mem, tdx.off * 4, 4 * nin, pre));
  CHECK_OK(ctx, spx_upsample2x_backward(ctx, &tg, ac, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got2));
  CHECK(memcmp(got, got2, 4 * nin) == 0);
  CHECK(spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &tdx));
  CHECK(spx_upsample2x_forward(ctx, &tx, ac, &tx) == SPX_E_ARG);
  spx_nt_free(&tx), spx_nt_free(&ty), spx_nt_free(&tg), spx_nt_free(&tdx);
  free(x), free(g), free(pre), free(got), free(got2), free(xd), free(gd), free(ref);
}

static void test_device(void) {
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
  if (!ctx) return;
  for (int ac = 0; ac < 2; ac++) {
    device_case(ctx, 2, 3, 37, 53, ac);
    device_case(ctx, 1, 2, 19, 25, ac);
    device_case(ctx, 1, 1, 1, 7, ac);
    device_case(ctx, 1, 1, 6, 1, ac);
    device_case(ctx, 1, 1, 154, 205, ac); /* large: every gather window fully inside */
  }
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_reference_fd);
  SPX_RUN(test_golden);
  SPX_RUN(test_device);
  return spx_test_summary();
}
