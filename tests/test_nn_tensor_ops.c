/* Tensor helpers (kernels/tensor_ops.cl): pad/crop and concat — FD check of the references,
 * device forward/backward vs reference at odd sizes and offsets, accumulate semantics,
 * guard floats untouched; axpy/scale/add/copy/fill against plain C. */
#include "nn/tensor_ops.h"
#include "nn_testutil.h"

static spx_ctx *ctx;

struct pad_args {
  int n, c, h, w, l, r, t, b;
};
static void pad_f(void *u, const double *in, double *out) {
  struct pad_args *a = u;
  spx_ref_pad_forward(in, a->n, a->c, a->h, a->w, a->l, a->r, a->t, a->b, out);
}
static void pad_b(void *u, const double *in, const double *dout, double *din) {
  struct pad_args *a = u;
  (void)in;
  spx_ref_pad_backward(dout, a->n, a->c, a->h, a->w, a->l, a->r, a->t, a->b, din);
}

static void test_pad_reference_fd(void) {
  struct pad_args cases[] = {{1, 2, 5, 4, 1, 2, 0, 3}, {2, 1, 6, 7, -1, 2, -2, 1}, {1, 1, 3, 3, -1, -1, -1, -1}};
  for (int t = 0; t < 3; t++) {
    struct pad_args *a = &cases[t];
    int nin = a->n * a->c * a->h * a->w, nout = a->n * a->c * (a->h + a->t + a->b) * (a->w + a->l + a->r);
    double *x = malloc(sizeof(double) * nin);
    unsigned long long s = 11 + t;
    for (int i = 0; i < nin; i++) x[i] = 2 * spx_t_uniform(&s) - 1;
    double e = spx_fd_check(pad_f, pad_b, a, x, nin, nout, 1e-3, 5);
    CHECK_MSG(e < 1e-8, "pad case %d: fd error %.3g", t, e);
    free(x);
  }
  /* the reference itself: a known value */
  double x[4] = {1, 2, 3, 4}, o[9];
  spx_ref_pad_forward(x, 1, 1, 2, 2, 1, 0, 0, 1, o); /* 3x3: [[0,1,2],[0,3,4],[0,0,0]] */
  CHECK(o[0] == 0 && o[1] == 1 && o[2] == 2 && o[4] == 3 && o[5] == 4 && o[8] == 0);
}

static void pad_device_case(int n, int c, int h, int w, int l, int r, int t, int b) {
  int oh = h + t + b, ow = w + l + r;
  size_t nin = (size_t)n * c * h * w, nout = (size_t)n * c * oh * ow;
  float *x = malloc(sizeof(float) * nin), *g = malloc(sizeof(float) * nout), *pre = malloc(sizeof(float) * nin);
  float *got = malloc(sizeof(float) * (nin > nout ? nin : nout));
  double *xd = malloc(sizeof(double) * nin), *gd = malloc(sizeof(double) * nout);
  double *ref = malloc(sizeof(double) * (nin > nout ? nin : nout));
  unsigned long long s = 99;
  spx_nt_rand(x, nin, -1, 1, &s);
  spx_nt_rand(g, nout, -1, 1, &s);
  spx_nt_rand(pre, nin, -1, 1, &s);
  spx_nt_to_double(x, xd, nin);
  spx_nt_to_double(g, gd, nout);
  spx_tensor tx, to, tg, tdx;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, oh, ow, &to));
  CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, oh, ow, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
  CHECK_OK(ctx, spx_pad_forward(ctx, &tx, l, r, t, b, &to));
  CHECK_OK(ctx, spx_nt_download(ctx, &to, got));
  spx_ref_pad_forward(xd, n, c, h, w, l, r, t, b, ref);
  CHECK_CLOSE_ARR(got, ref, nout, 0, 0); /* a copy: exact */
  CHECK_OK(ctx, spx_pad_backward(ctx, &tg, l, r, t, b, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got));
  for (size_t i = 0; i < nin; i++) ref[i] = pre[i];
  spx_ref_pad_backward(gd, n, c, h, w, l, r, t, b, ref);
  CHECK_CLOSE_ARR(got, ref, nin, 1e-7, 1e-6);
  CHECK(spx_nt_guards_ok(ctx, &to) && spx_nt_guards_ok(ctx, &tdx));
  /* wrong output shape is an argument error naming the op */
  spx_tensor bad = to;
  bad.w += 1;
  CHECK(spx_pad_forward(ctx, &tx, l, r, t, b, &bad) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "pad_forward") != NULL);
  spx_nt_free(&tx), spx_nt_free(&to), spx_nt_free(&tg), spx_nt_free(&tdx);
  free(x), free(g), free(pre), free(got), free(xd), free(gd), free(ref);
}

static void test_pad_device(void) {
  pad_device_case(2, 3, 37, 53, 1, 2, 0, 3);
  pad_device_case(2, 3, 37, 53, -1, -2, 3, -4);
  pad_device_case(1, 2, 19, 25, 0, 1, 1, 0); /* the UNet case: 38x51 -> pad to the skip's size */
  pad_device_case(1, 1, 1, 1, 0, 0, 0, 0);
}

struct cat_args {
  int n, ca, cb, hw;
};
static void cat_f(void *u, const double *in, double *out) {
  struct cat_args *a = u;
  spx_ref_concat_forward(in, in + a->n * a->ca * a->hw, a->n, a->ca, a->cb, a->hw, out);
}
static void cat_b(void *u, const double *in, const double *dout, double *din) {
  struct cat_args *a = u;
  (void)in;
  spx_ref_concat_backward(dout, a->n, a->ca, a->cb, a->hw, din, din + a->n * a->ca * a->hw);
}

static void test_concat(void) {
  struct cat_args a = {2, 2, 3, 6};
  int nin = a.n * (a.ca + a.cb) * a.hw;
  double xd0[60];
  unsigned long long s = 3;
  for (int i = 0; i < nin; i++) xd0[i] = spx_t_uniform(&s);
  double e = spx_fd_check(cat_f, cat_b, &a, xd0, nin, nin, 1e-3, 8);
  CHECK_MSG(e < 1e-8, "concat fd error %.3g", e);

  int n = 2, ca = 3, cb = 5, h = 37, w = 53, hw = h * w;
  size_t na = (size_t)n * ca * hw, nb = (size_t)n * cb * hw, no = na + nb;
  float *fa = malloc(4 * na), *fb = malloc(4 * nb), *fg = malloc(4 * no), *pa = malloc(4 * na), *pb = malloc(4 * nb);
  float *got = malloc(4 * no);
  double *da = malloc(8 * na), *db = malloc(8 * nb), *dg = malloc(8 * no), *ref = malloc(8 * no);
  spx_nt_rand(fa, na, -1, 1, &s), spx_nt_rand(fb, nb, -1, 1, &s), spx_nt_rand(fg, no, -1, 1, &s);
  spx_nt_rand(pa, na, -1, 1, &s), spx_nt_rand(pb, nb, -1, 1, &s);
  spx_nt_to_double(fa, da, na), spx_nt_to_double(fb, db, nb), spx_nt_to_double(fg, dg, no);
  spx_tensor ta, tb, to, tg, tda, tdb;
  CHECK_OK(ctx, spx_nt_upload(ctx, fa, n, ca, h, w, &ta));
  CHECK_OK(ctx, spx_nt_upload(ctx, fb, n, cb, h, w, &tb));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, ca + cb, h, w, &to));
  CHECK_OK(ctx, spx_nt_upload(ctx, fg, n, ca + cb, h, w, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pa, n, ca, h, w, &tda));
  CHECK_OK(ctx, spx_nt_upload(ctx, pb, n, cb, h, w, &tdb));
  spx_ref_concat_forward(da, db, n, ca, cb, hw, ref);
  /* both placements: the element-wise kernel and one buffer copy per sample (SPX_PLACE_COPY) */
  const int pc = spx_nt_tunable(ctx, "PLACE_COPY");
  CHECK(pc >= 0);
  for (int v = 0; v < 2; v++) {
    CHECK_OK(ctx, spx_device_set_tunable(ctx, "PLACE_COPY", v));
    CHECK_OK(ctx, spx_fill(ctx, &to, -3.0f));
    CHECK_OK(ctx, spx_concat_forward(ctx, &ta, &tb, &to));
    CHECK_OK(ctx, spx_nt_download(ctx, &to, got));
    CHECK_CLOSE_ARR(got, ref, no, 0, 0);
  }
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "PLACE_COPY", pc));
  /* only db wanted: da stays untouched */
  CHECK_OK(ctx, spx_concat_backward(ctx, &tg, NULL, &tdb));
  CHECK_OK(ctx, spx_concat_backward(ctx, &tg, &tda, NULL));
  double *ra = malloc(8 * na), *rb = malloc(8 * nb);
  spx_nt_to_double(pa, ra, na), spx_nt_to_double(pb, rb, nb);
  spx_ref_concat_backward(dg, n, ca, cb, hw, ra, rb);
  CHECK_OK(ctx, spx_nt_download(ctx, &tda, got));
  CHECK_CLOSE_ARR(got, ra, na, 1e-7, 1e-6);
  CHECK_OK(ctx, spx_nt_download(ctx, &tdb, got));
  CHECK_CLOSE_ARR(got, rb, nb, 1e-7, 1e-6);
  CHECK(spx_nt_guards_ok(ctx, &to) && spx_nt_guards_ok(ctx, &tda) && spx_nt_guards_ok(ctx, &tdb));
  CHECK(spx_concat_forward(ctx, &ta, &ta, &to) == SPX_E_ARG);
  spx_nt_free(&ta), spx_nt_free(&tb), spx_nt_free(&to), spx_nt_free(&tg), spx_nt_free(&tda), spx_nt_free(&tdb);
  free(fa), free(fb), free(fg), free(pa), free(pb), free(got), free(da), free(db), free(dg), free(ref), free(ra),
      free(rb);
}

static void test_elementwise(void) {
  int n = 1001;
  float x[1001], y[1001], got[1001];
  unsigned long long s = 17;
  spx_nt_rand(x, n, -2, 2, &s), spx_nt_rand(y, n, -2, 2, &s);
  spx_tensor tx, ty, to;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, 1, 1, 1, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, y, n, 1, 1, 1, &ty));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, 1, 1, 1, &to));
  CHECK_OK(ctx, spx_add(ctx, &tx, &ty, &to));
  CHECK_OK(ctx, spx_nt_download(ctx, &to, got));
  int ok = 1;
  for (int i = 0; i < n; i++) ok &= got[i] == x[i] + y[i];
  CHECK(ok);
  CHECK_OK(ctx, spx_axpy(ctx, -0.75f, &tx, &ty)); /* y += -0.75 x */
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got));
  ok = 1;
  for (int i = 0; i < n; i++) ok &= got[i] == y[i] + -0.75f * x[i];
  CHECK(ok);
  CHECK_OK(ctx, spx_scale(ctx, 3.0f, &tx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tx, got));
  ok = 1;
  for (int i = 0; i < n; i++) ok &= got[i] == x[i] * 3.0f;
  CHECK(ok);
  CHECK_OK(ctx, spx_copy(ctx, &tx, &to));
  CHECK_OK(ctx, spx_nt_download(ctx, &to, y));
  CHECK(memcmp(got, y, sizeof got) == 0);
  CHECK_OK(ctx, spx_fill(ctx, &to, 2.5f));
  CHECK_OK(ctx, spx_nt_download(ctx, &to, got));
  ok = 1;
  for (int i = 0; i < n; i++) ok &= got[i] == 2.5f;
  CHECK(ok);
  CHECK(spx_nt_guards_ok(ctx, &tx) && spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &to));
  spx_tensor shorter = tx;
  shorter.n--;
  CHECK(spx_add(ctx, &shorter, &ty, &to) == SPX_E_ARG);
  spx_nt_free(&tx), spx_nt_free(&ty), spx_nt_free(&to);
}

int main(void) {
  static const spx_t_test host[] = {SPX_TEST(test_pad_reference_fd)};
  static const spx_t_test dev[] = {SPX_TEST(test_pad_device), SPX_TEST(test_concat), SPX_TEST(test_elementwise)};
  return spx_nt_main(&ctx, host, 1, dev, 3);
}
