/* Batch norm 2d (kernels/batchnorm.cl): FD check of the reference backward (dx, dweight,
 * dbias); reference vs torch.nn.BatchNorm2d golden (train output, running stats over two steps,
 * backward, eval; tests/data/batchnorm); device train/eval forward and backward vs reference on
 * odd shapes with accumulate semantics; accuracy at 126k values per channel with |mean| >> std;
 * bit-identical reruns; the one-value-per-channel error. Batch norm + ReLU fused: FD check of its
 * reference backward; on the device, the same bits as batch norm then the ReLU (forward) and as
 * the ReLU backward into a zeroed gradient then the batch norm backward, and close to the
 * reference. */
#include "nn/activations.h"
#include "nn/batchnorm.h"
#include "nn_testutil.h"

#define GOLDEN SPX_TEST_DATA "/batchnorm/batchnorm_golden.txt"

struct bn_args {
  int n, c, hw;
};
static void bn_f(void *u, const double *in, double *out) {
  struct bn_args *a = u;
  int nx = a->n * a->c * a->hw;
  double sm[8], si[8];
  spx_ref_bn_train_forward(in, a->n, a->c, a->hw, in + nx, in + nx + a->c, NULL, NULL, 0.1, 1e-5, sm, si, out);
}
static void bn_b(void *u, const double *in, const double *dout, double *din) {
  struct bn_args *a = u;
  int nx = a->n * a->c * a->hw;
  double sm[8], si[8], *y = malloc(sizeof(double) * nx);
  spx_ref_bn_train_forward(in, a->n, a->c, a->hw, in + nx, in + nx + a->c, NULL, NULL, 0.1, 1e-5, sm, si, y);
  spx_ref_bn_train_backward(in, a->n, a->c, a->hw, in + nx, sm, si, dout, din, din + nx, din + nx + a->c);
  free(y);
}

static void bn_relu_f(void *u, const double *in, double *out) {
  struct bn_args *a = u;
  int nx = a->n * a->c * a->hw;
  bn_f(u, in, out);
  for (int i = 0; i < nx; i++) out[i] = out[i] > 0 ? out[i] : 0;
}
static void bn_relu_b(void *u, const double *in, const double *dout, double *din) {
  struct bn_args *a = u;
  int nx = a->n * a->c * a->hw;
  double sm[8], si[8], *y = malloc(sizeof(double) * nx);
  spx_ref_bn_train_forward(in, a->n, a->c, a->hw, in + nx, in + nx + a->c, NULL, NULL, 0.1, 1e-5, sm, si, y);
  CHECK(spx_ref_bn_relu_train_backward(in, a->n, a->c, a->hw, in + nx, in + nx + a->c, sm, si, dout, din, din + nx,
                                       din + nx + a->c) == 0);
  free(y);
}

static void test_reference_fd(void) {
  struct bn_args a = {2, 3, 7};
  int nx = 42, nin = nx + 6;
  double in[48];
  unsigned long long s = 8;
  for (int i = 0; i < nin; i++) in[i] = 2 * spx_t_uniform(&s) - 1;
  double e = spx_fd_check(bn_f, bn_b, &a, in, nin, nx, 1e-5, 3);
  CHECK_MSG(e < 1e-7, "fd error %.3g", e);
  /* with the ReLU (bias 0.2: about half the pre-activations positive; none within the FD step of
   * the kink for this seed) */
  for (int i = nx + 3; i < nin; i++) in[i] = 0.2;
  e = spx_fd_check(bn_relu_f, bn_relu_b, &a, in, nin, nx, 1e-5, 3);
  CHECK_MSG(e < 1e-7, "fused ReLU fd error %.3g", e);
}

static double *G(const char *name, int want) {
  int n = 0;
  double *v = spx_golden_get(GOLDEN, name, &n);
  CHECK_MSG(v && n == want, "golden %s: %d values, expected %d", name, n, want);
  return v && n == want ? v : NULL;
}

static void test_golden(void) {
  int cnt = 0;
  double *shape = spx_golden_get(GOLDEN, "shape", &cnt);
  CHECK(shape && cnt == 4);
  if (!shape) return;
  int n = (int)shape[0], c = (int)shape[1], hw = (int)shape[2] * (int)shape[3], nx = n * c * hw;
  free(shape);
  double *w = G("weight", c), *b = G("bias", c), *rm = G("rm0", c), *rv = G("rv0", c), *x1 = G("x1", nx);
  double *x2 = G("x2", nx), *g1 = G("g1", nx), *y1 = G("y1", nx), *rm1 = G("rm1", c), *rv1 = G("rv1", c);
  double *dx1 = G("dx1", nx), *dw1 = G("dweight1", c), *db1 = G("dbias1", c), *y2 = G("y2", nx), *rm2 = G("rm2", c);
  double *rv2 = G("rv2", c), *ye = G("yeval", nx);
  if (w && b && rm && rv && x1 && x2 && g1 && y1 && rm1 && rv1 && dx1 && dw1 && db1 && y2 && rm2 && rv2 && ye) {
    double *y = malloc(8 * nx), *dx = calloc(nx, 8), dw[16] = {0}, db[16] = {0}, sm[16], si[16];
    float *f = malloc(4 * nx);
#define CMP(ref_, golden_, count_)                                                                  \
  do {                                                                                              \
    for (int i_ = 0; i_ < (count_); i_++) f[i_] = (float)(ref_)[i_];                               \
    double e_ = spx_nt_err(f, golden_, count_, 1.0);                                                \
    CHECK_MSG(e_ < 2e-6, "%s vs torch: %.3g", #golden_, e_);                                        \
  } while (0)
    spx_ref_bn_train_forward(x1, n, c, hw, w, b, rm, rv, 0.1, 1e-5, sm, si, y);
    CMP(y, y1, nx);
    CMP(rm, rm1, c);
    CMP(rv, rv1, c);
    spx_ref_bn_train_backward(x1, n, c, hw, w, sm, si, g1, dx, dw, db);
    CMP(dx, dx1, nx);
    CMP(dw, dw1, c);
    CMP(db, db1, c);
    spx_ref_bn_train_forward(x2, n, c, hw, w, b, rm, rv, 0.1, 1e-5, sm, si, y);
    CMP(y, y2, nx);
    CMP(rm, rm2, c);
    CMP(rv, rv2, c);
    spx_ref_bn_eval_forward(x1, n, c, hw, w, b, rm, rv, 1e-5, y);
    CMP(y, ye, nx);
    free(y), free(dx), free(f);
  }
  free(w), free(b), free(rm), free(rv), free(x1), free(x2), free(g1), free(y1), free(rm1), free(rv1), free(dx1);
  free(dw1), free(db1), free(y2), free(rm2), free(rv2), free(ye);
}

/* device vs reference; offset/scale shape the data (|mean| >> std for the accuracy case) */
static void device_case(spx_ctx *ctx, int n, int c, int h, int w, float offset, float spread, double tol) {
  int hw = h * w;
  size_t nx = (size_t)n * c * hw;
  float *x = malloc(4 * nx), *g = malloc(4 * nx), *pre = malloc(4 * nx), *got = malloc(4 * nx), *got2 = malloc(4 * nx);
  float par[6 * 64], outp[6 * 64];
  double *xd = malloc(8 * nx), *gd = malloc(8 * nx), *ref = malloc(8 * nx), *dref = malloc(8 * nx);
  unsigned long long s = 77 + c;
  spx_nt_rand(x, nx, offset - spread, offset + spread, &s), spx_nt_rand(g, nx, -1, 1, &s), spx_nt_rand(pre, nx, -1, 1, &s);
  /* par: weight, bias, rm, rv, dweight-pre, dbias-pre */
  spx_nt_rand(par, 6 * (size_t)c, 0.5f, 1.5f, &s);
  spx_nt_to_double(x, xd, nx), spx_nt_to_double(g, gd, nx);
  double pd[6 * 64], sm[64], si[64];
  spx_nt_to_double(par, pd, 6 * (size_t)c);
  spx_tensor tx, tw, tb, trm, trv, tsave, ty, tg, tdx, tdw, tdb;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, par, c, 1, 1, 1, &tw));
  CHECK_OK(ctx, spx_nt_upload(ctx, par + c, c, 1, 1, 1, &tb));
  CHECK_OK(ctx, spx_nt_upload(ctx, par + 2 * c, c, 1, 1, 1, &trm));
  CHECK_OK(ctx, spx_nt_upload(ctx, par + 3 * c, c, 1, 1, 1, &trv));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 2 * c, 1, 1, 1, &tsave));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, h, w, &ty));
  CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, h, w, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
  CHECK_OK(ctx, spx_nt_upload(ctx, par + 4 * c, c, 1, 1, 1, &tdw));
  CHECK_OK(ctx, spx_nt_upload(ctx, par + 5 * c, c, 1, 1, 1, &tdb));

  CHECK_OK(ctx, spx_bn_train_forward(ctx, &tx, &tw, &tb, &trm, &trv, 0.1f, 1e-5f, 1, &tsave, &ty));
  spx_ref_bn_train_forward(xd, n, c, hw, pd, pd + c, pd + 2 * c, pd + 3 * c, 0.1, 1e-5, sm, si, ref);
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got));
  /* y error is dominated by the float rounding of the mean (|mean| * eps / std) */
  double ytol = tol * (1 + fabs(offset) / spread);
  CHECK_MSG(spx_nt_err(got, ref, nx, 1.0) < ytol, "%dx%dx%dx%d y: %.3g", n, c, h, w, spx_nt_err(got, ref, nx, 1.0));
  CHECK_OK(ctx, spx_nt_download(ctx, &tsave, outp));
  CHECK_MSG(spx_nt_err(outp, sm, c, 0) < tol, "mean: %.3g", spx_nt_err(outp, sm, c, 0));
  CHECK_MSG(spx_nt_err(outp + c, si, c, 0) < tol, "invstd: %.3g", spx_nt_err(outp + c, si, c, 0));
  CHECK_OK(ctx, spx_nt_download(ctx, &trm, outp));
  CHECK_MSG(spx_nt_err(outp, pd + 2 * c, c, 0) < tol, "running_mean: %.3g", spx_nt_err(outp, pd + 2 * c, c, 0));
  CHECK_OK(ctx, spx_nt_download(ctx, &trv, outp));
  CHECK_MSG(spx_nt_err(outp, pd + 3 * c, c, 0) < tol, "running_var: %.3g", spx_nt_err(outp, pd + 3 * c, c, 0));
  /* rerun without the running-stat update: the same bits, running stats untouched */
  CHECK_OK(ctx, spx_bn_train_forward(ctx, &tx, &tw, &tb, NULL, NULL, 0.1f, 1e-5f, 0, &tsave, &ty));
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got2));
  CHECK(memcmp(got, got2, 4 * nx) == 0);
  float rv_again[64];
  CHECK_OK(ctx, spx_nt_download(ctx, &trv, rv_again));
  CHECK(memcmp(rv_again, outp, 4 * (size_t)c) == 0);

  /* backward from the device's own saved stats (as training does) */
  CHECK_OK(ctx, spx_nt_download(ctx, &tsave, outp));
  double smd[64], sid[64], dw[64], db[64];
  for (int i = 0; i < c; i++) smd[i] = outp[i], sid[i] = outp[c + i], dw[i] = par[4 * c + i], db[i] = par[5 * c + i];
  spx_nt_to_double(pre, dref, nx);
  spx_ref_bn_train_backward(xd, n, c, hw, pd, smd, sid, gd, dref, dw, db);
  CHECK_OK(ctx, spx_bn_train_backward(ctx, &tx, &tw, &tsave, &tg, &tdx, &tdw, &tdb));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got));
  CHECK_MSG(spx_nt_err(got, dref, nx, 1.0) < ytol, "dx: %.3g", spx_nt_err(got, dref, nx, 1.0));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdw, outp));
  CHECK_MSG(spx_nt_err(outp, dw, c, 1.0) < tol, "dweight: %.3g", spx_nt_err(outp, dw, c, 1.0));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdb, outp));
  CHECK_MSG(spx_nt_err(outp, db, c, 1.0) < tol, "dbias: %.3g", spx_nt_err(outp, db, c, 1.0));
  /* rerun: bit-identical; only dbias wanted: dx untouched */
  CHECK_OK(ctx, spx_cl_write(ctx, tdx.mem, tdx.off * 4, 4 * nx, pre));
  CHECK_OK(ctx, spx_bn_train_backward(ctx, &tx, &tw, &tsave, &tg, &tdx, NULL, NULL));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got2));
  CHECK(memcmp(got, got2, 4 * nx) == 0);
  CHECK_OK(ctx, spx_bn_train_backward(ctx, &tx, &tw, &tsave, &tg, NULL, NULL, &tdb));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got2));
  CHECK(memcmp(got, got2, 4 * nx) == 0);
  CHECK(spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &tdx) && spx_nt_guards_ok(ctx, &tsave) &&
        spx_nt_guards_ok(ctx, &tdw) && spx_nt_guards_ok(ctx, &trv));

  /* eval with the updated running stats */
  CHECK_OK(ctx, spx_bn_eval_forward(ctx, &tx, &tw, &tb, &trm, &trv, 1e-5f, &ty));
  CHECK_OK(ctx, spx_nt_download(ctx, &trm, outp));
  CHECK_OK(ctx, spx_nt_download(ctx, &trv, outp + c));
  double rmd[64], rvd[64];
  for (int i = 0; i < c; i++) rmd[i] = outp[i], rvd[i] = outp[c + i];
  spx_ref_bn_eval_forward(xd, n, c, hw, pd, pd + c, rmd, rvd, 1e-5, ref);
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got));
  CHECK_MSG(spx_nt_err(got, ref, nx, 1.0) < ytol, "eval y: %.3g", spx_nt_err(got, ref, nx, 1.0));
  CHECK(spx_nt_guards_ok(ctx, &ty));

  spx_nt_free(&tx), spx_nt_free(&tw), spx_nt_free(&tb), spx_nt_free(&trm), spx_nt_free(&trv), spx_nt_free(&tsave);
  spx_nt_free(&ty), spx_nt_free(&tg), spx_nt_free(&tdx), spx_nt_free(&tdw), spx_nt_free(&tdb);
  free(x), free(g), free(pre), free(got), free(got2), free(xd), free(gd), free(ref), free(dref);
}

/* Fused batch norm + ReLU against the two ops (memcmp) and the reference, on an n x c x h x w
 * input with the accumulate semantics (dx, dweight, dbias pre-filled). */
static void relu_case(spx_ctx *ctx, int n, int c, int h, int w) {
  const int hw = h * w;
  const size_t nx = (size_t)n * c * hw;
  float *buf = malloc(4 * nx * 8), par[6 * 64];
  double *xd = malloc(8 * nx * 3);
  CHECK(buf && xd && c <= 64);
  if (!buf || !xd) goto done;
  float *x = buf, *g = buf + nx, *pre = buf + 2 * nx, *zero = buf + 3 * nx, *y1 = buf + 4 * nx, *y2 = buf + 5 * nx,
        *d1 = buf + 6 * nx, *d2 = buf + 7 * nx;
  unsigned long long s = 91 + (unsigned long long)c;
  spx_nt_rand(x, nx, -1.5f, 2.5f, &s), spx_nt_rand(g, nx, -1, 1, &s), spx_nt_rand(pre, nx, -1, 1, &s);
  memset(zero, 0, 4 * nx);
  spx_nt_rand(par, 6 * (size_t)c, -0.5f, 1.5f, &s); /* weight, bias (some negative), rm, rv, dw-pre, db-pre */
  spx_tensor tx, tw, tb, tsave, ty, tyb, tg, tdx, tdw, tdb, tgz;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, par, c, 1, 1, 1, &tw));
  CHECK_OK(ctx, spx_nt_upload(ctx, par + c, c, 1, 1, 1, &tb));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 2 * c, 1, 1, 1, &tsave));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, h, w, &ty));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, h, w, &tyb));
  CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, h, w, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
  CHECK_OK(ctx, spx_nt_upload(ctx, par + 4 * c, c, 1, 1, 1, &tdw));
  CHECK_OK(ctx, spx_nt_upload(ctx, par + 5 * c, c, 1, 1, 1, &tdb));
  CHECK_OK(ctx, spx_nt_upload(ctx, zero, n, c, h, w, &tgz));
  /* forward: fused vs batch norm then ReLU */
  CHECK_OK(ctx, spx_bn_relu_train_forward(ctx, &tx, &tw, &tb, NULL, NULL, 0.1f, 1e-5f, 0, &tsave, 1, &ty));
  CHECK_OK(ctx, spx_bn_train_forward(ctx, &tx, &tw, &tb, NULL, NULL, 0.1f, 1e-5f, 0, &tsave, &tyb));
  CHECK_OK(ctx, spx_act_forward(ctx, SPX_ACT_RELU, 0.0f, &tyb, &tyb));
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, y1));
  CHECK_OK(ctx, spx_nt_download(ctx, &tyb, y2));
  size_t pos = 0;
  for (size_t i = 0; i < nx; i++) pos += y1[i] > 0;
  CHECK_MSG(pos > nx / 10 && pos < nx - nx / 10, "%zu of %zu outputs positive: the mask is not exercised", pos, nx);
  CHECK_MSG(!memcmp(y1, y2, 4 * nx), "%dx%dx%dx%d: fused forward differs from batch norm + ReLU", n, c, h, w);
  /* backward: fused vs ReLU backward into a zeroed gradient, then the batch norm backward */
  float dw1[64], db1[64], dw2[64], db2[64];
  CHECK_OK(ctx, spx_bn_relu_train_backward(ctx, &tx, &tw, &tb, &tsave, &tg, &tdx, &tdw, &tdb));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, d1));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdw, dw1));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdb, db1));
  CHECK_OK(ctx, spx_cl_write(ctx, tdx.mem, tdx.off * 4, 4 * nx, pre));
  CHECK_OK(ctx, spx_cl_write(ctx, tdw.mem, tdw.off * 4, 4 * (size_t)c, par + 4 * c));
  CHECK_OK(ctx, spx_cl_write(ctx, tdb.mem, tdb.off * 4, 4 * (size_t)c, par + 5 * c));
  CHECK_OK(ctx, spx_act_backward(ctx, SPX_ACT_RELU, 0.0f, &ty, &tg, &tgz));
  CHECK_OK(ctx, spx_bn_train_backward(ctx, &tx, &tw, &tsave, &tgz, &tdx, &tdw, &tdb));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, d2));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdw, dw2));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdb, db2));
  CHECK_MSG(!memcmp(d1, d2, 4 * nx) && !memcmp(dw1, dw2, 4 * (size_t)c) && !memcmp(db1, db2, 4 * (size_t)c),
            "%dx%dx%dx%d: fused backward differs from ReLU + batch norm backward", n, c, h, w);
  /* and close to the reference (the device's saved statistics, as training uses them) */
  float sv[128];
  double pd[6 * 64], smd[64], sid[64], dwd[64], dbd[64], *gd = xd + nx, *dref = xd + 2 * nx;
  CHECK_OK(ctx, spx_nt_download(ctx, &tsave, sv));
  spx_nt_to_double(par, pd, 6 * (size_t)c), spx_nt_to_double(x, xd, nx), spx_nt_to_double(g, gd, nx);
  spx_nt_to_double(pre, dref, nx);
  for (int i = 0; i < c; i++) smd[i] = sv[i], sid[i] = sv[c + i], dwd[i] = pd[4 * c + i], dbd[i] = pd[5 * c + i];
  CHECK(spx_ref_bn_relu_train_backward(xd, n, c, hw, pd, pd + c, smd, sid, gd, dref, dwd, dbd) == 0);
  CHECK_MSG(spx_nt_err(d1, dref, nx, 1.0) < 1e-5, "fused dx: %.3g", spx_nt_err(d1, dref, nx, 1.0));
  CHECK_MSG(spx_nt_err(dw1, dwd, c, 1.0) < 1e-5, "fused dweight: %.3g", spx_nt_err(dw1, dwd, c, 1.0));
  CHECK_MSG(spx_nt_err(db1, dbd, c, 1.0) < 1e-5, "fused dbias: %.3g", spx_nt_err(db1, dbd, c, 1.0));
  CHECK(spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &tdx) && spx_nt_guards_ok(ctx, &tdw));
  spx_nt_free(&tx), spx_nt_free(&tw), spx_nt_free(&tb), spx_nt_free(&tsave), spx_nt_free(&ty), spx_nt_free(&tyb);
  spx_nt_free(&tg), spx_nt_free(&tdx), spx_nt_free(&tdw), spx_nt_free(&tdb), spx_nt_free(&tgz);
done:
  free(buf), free(xd);
}

static void test_device_relu(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  relu_case(ctx, 2, 3, 37, 53); /* vector body and scalar tail per plane */
  relu_case(ctx, 3, 5, 1, 3);   /* tail only */
  relu_case(ctx, 1, 4, 64, 80); /* whole vectors */
  spx_ctx_destroy(ctx);
}

static void test_device(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  device_case(ctx, 2, 3, 37, 53, 0.3f, 2.0f, 2e-6);
  device_case(ctx, 3, 5, 1, 1, 0.0f, 1.0f, 2e-6); /* 3 values per channel */
  device_case(ctx, 1, 2, 308, 410, 100.0f, 1.0f, 2e-6); /* 126k per channel, |mean| >> std */
  /* one value per channel in train mode is an error, like PyTorch */
  spx_tensor t, v, sv;
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 1, 2, 1, 1, &t));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 2, 1, 1, 1, &v));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 4, 1, 1, 1, &sv));
  CHECK(spx_bn_train_forward(ctx, &t, &v, &v, &v, &v, 0.1f, 1e-5f, 1, &sv, &t) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "more than 1 value") != NULL);
  CHECK(spx_bn_train_forward(ctx, &t, &v, &v, &v, &v, 0.1f, 1e-5f, 1, &v, &t) == SPX_E_ARG); /* save too small */
  spx_nt_free(&t), spx_nt_free(&v), spx_nt_free(&sv);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_reference_fd);
  SPX_RUN(test_golden);
  SPX_RUN(test_device);
  SPX_RUN(test_device_relu);
  return spx_test_summary();
}
