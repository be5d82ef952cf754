/* LPIPS (lib/metrics/lpips.c) and its 3x3/2 max pooling (kernels/metrics.cl):
 *  - the device pooling against the double reference (odd sizes, ties, NaN, -inf), bit-reproducible;
 *  - LPIPS against the lpips PyPI package (tools/make_lpips_golden.py: a random AlexNet whose weights
 *    this test regenerates bit for bit, written here to a safetensors file), relative 1e-5;
 *  - weight files with a missing, misshapen or non-float tensor: one message naming file and tensor. */
#include "metrics/metrics_internal.h"
#include "lpips_weights.h"
#include "nn_testutil.h"
#include "smplpix/metrics.h"

static void pool_case(spx_ctx *ctx, int n, int c, int h, int w, int ties) {
  int oh = spx_maxpool3s2_out(h), ow = spx_maxpool3s2_out(w);
  size_t nin = (size_t)n * c * h * w, nout = (size_t)n * c * oh * ow;
  float *x = malloc(4 * nin), *got = malloc(4 * nout), *got2 = malloc(4 * nout);
  double *xd = malloc(8 * nin), *ref = malloc(8 * nout);
  unsigned long long s = 77 + (unsigned long long)ties;
  spx_nt_rand(x, nin, -1, 1, &s);
  if (ties)
    for (size_t i = 0; i < nin; i++) x[i] = floorf((x[i] + 1) * 2);
  x[0] = x[1] = x[2] = x[w] = x[w + 1] = x[w + 2] = x[2 * w] = x[2 * w + 1] = x[2 * w + 2] = -INFINITY;
  if (nin > 100) x[nin - 1] = NAN; /* the last window's corner: NaN wins */
  spx_nt_to_double(x, xd, nin);
  spx_tensor tx, ty;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, oh, ow, &ty));
  CHECK_OK(ctx, spx_maxpool3s2_forward(ctx, &tx, &ty));
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got));
  spx_ref_maxpool3s2_forward(xd, n * c, h, w, ref);
  int ok = 1;
  for (size_t i = 0; i < nout; i++) ok &= (isnan(ref[i]) && isnan(got[i])) || (double)got[i] == ref[i];
  CHECK_MSG(ok, "pooling differs from the reference (%dx%dx%dx%d)", n, c, h, w);
  CHECK(isinf(got[0]) && got[0] < 0);
  if (nin > 100 && h % 2 && w % 2) CHECK(isnan(got[nout - 1]));
  CHECK_OK(ctx, spx_maxpool3s2_forward(ctx, &tx, &ty));
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got2));
  CHECK(memcmp(got, got2, 4 * nout) == 0);
  CHECK(spx_nt_guards_ok(ctx, &ty));
  CHECK(spx_maxpool3s2_forward(ctx, &tx, &tx) == SPX_E_ARG);
  spx_nt_free(&tx), spx_nt_free(&ty);
  free(x), free(got), free(got2), free(xd), free(ref);
}

static void test_pool(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  pool_case(ctx, 2, 3, 37, 53, 0);
  pool_case(ctx, 2, 3, 15, 16, 1);
  pool_case(ctx, 1, 2, 3, 3, 0);
  spx_ctx_destroy(ctx);
}

/* ---- the LPIPS golden ---- */

static int load_npy(spx_ctx *ctx, const char *name, spx_image *img) {
  char p[1024];
  snprintf(p, sizeof p, "%s/metrics/%s.npy", SPX_TEST_DATA, name);
  spx_array a;
  if (spx_npy_load(ctx, p, &a)) return 0;
  float *f = NULL;
  int ok = a.ndim == 3 && spx_array_to_f32(ctx, &a, &f) == SPX_OK;
  if (ok) *img = (spx_image){(int32_t)a.shape[1], (int32_t)a.shape[0], (int32_t)a.shape[2], f};
  spx_array_free(&a);
  return ok;
}

/* The golden's random AlexNet written to `wname` and loaded, and the expected-values file
 * tests/data/metrics/<table> opened; NULLs (checked) on failure. */
static spx_lpips *golden_open(spx_ctx *ctx, const char *wname, const char *table, FILE **f) {
  char w[700], p[1024];
  spx_t_path(w, sizeof w, wname);
  CHECK(spx_t_lpips_weights(ctx, w, NULL, NULL));
  spx_lpips *lp = NULL;
  CHECK_OK(ctx, spx_lpips_load(ctx, w, &lp));
  snprintf(p, sizeof p, "%s/metrics/%s", SPX_TEST_DATA, table);
  *f = fopen(p, "r");
  CHECK(*f && lp);
  return lp;
}

/* The next case of a golden table ("name float64 float32" lines, '#' comments): its values and
 * its image pair tests/data/metrics/<name>_{pred,target}.npy. 0 at the end of the table. */
static int next_case(spx_ctx *ctx, FILE *f, char name[64], double *want, double *want32, spx_image *a, spx_image *b) {
  char line[256], pn[96], tn[96];
  while (fgets(line, sizeof line, f)) {
    if (line[0] == '#' || sscanf(line, "%63s %lf %lf", name, want, want32) != 3) continue;
    snprintf(pn, sizeof pn, "%s_pred", name);
    snprintf(tn, sizeof tn, "%s_target", name);
    CHECK(load_npy(ctx, pn, a) && load_npy(ctx, tn, b));
    return 1;
  }
  return 0;
}

/* Every case of a golden file pair through check (the weights opened, the case's images a and b
 * freed after it), then after (may be NULL) with the weights; three cases expected. */
typedef void (*golden_check)(spx_ctx *ctx, spx_lpips *lp, const char *name, double want, double want32,
                             const spx_image *a, const spx_image *b);
static void golden_cases(const char *weights, const char *expected, golden_check check,
                         void (*after)(spx_ctx *, spx_lpips *)) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  FILE *f = NULL;
  spx_lpips *lp = golden_open(ctx, weights, expected, &f);
  int cases = 0;
  char name[64];
  double want, want32;
  spx_image a = {0}, b = {0};
  while (f && lp && next_case(ctx, f, name, &want, &want32, &a, &b)) {
    check(ctx, lp, name, want, want32, &a, &b);
    spx_image_free(&a), spx_image_free(&b);
    cases++;
  }
  if (f) fclose(f);
  CHECK(cases == 3);
  if (lp && after) after(ctx, lp);
  spx_lpips_free(lp);
  spx_ctx_destroy(ctx);
}

static void check_plain(spx_ctx *ctx, spx_lpips *lp, const char *name, double want, double want32,
                        const spx_image *a, const spx_image *b) {
  double got = -1, again = -2;
  CHECK_OK(ctx, spx_lpips_distance(lp, a, b, &got));
  CHECK_OK(ctx, spx_lpips_distance(lp, a, b, &again));
  fprintf(stderr, "  %-10s LPIPS %.10g (lpips float64 %.10g, float32 %.10g): rel %.2g\n", name, got, want, want32,
          want ? fabs(got - want) / want : fabs(got));
  CHECK_NEAR(got, want, 1e-9, 1e-5);
  CHECK(got == again); /* deterministic */
}

/* too small for AlexNet */
static void check_too_small(spx_ctx *ctx, spx_lpips *lp) {
  spx_image s = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, 30, 40, 3, &s));
  double v;
  CHECK(spx_lpips_distance(lp, &s, &s, &v) == SPX_E_ARG && strstr(spx_ctx_message(ctx), "31x31"));
  spx_image_free(&s);
}

static void test_golden(void) {
  golden_cases("lpips_golden.safetensors", "lpips_expected.txt", check_plain, check_too_small);
}

/* The masked LPIPS against the lpips package's spatial map (tools/make_lpips_golden.py --masked):
 * the mean over the rectangle x in [W/4, 3W/4), y in [H/5, 4H/5). */
static void check_masked(spx_ctx *ctx, spx_lpips *lp, const char *name, double want, double want32,
                         const spx_image *a, const spx_image *b) {
  spx_image m = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, a->width, a->height, 1, &m));
  for (int y = 0; y < a->height; y++)
    for (int x = 0; x < a->width; x++)
      m.data[(size_t)y * a->width + x] =
          x >= a->width / 4 && x < 3 * a->width / 4 && y >= a->height / 5 && y < 4 * a->height / 5;
  double full = -1, got = -1, plain = -2, none = 0;
  CHECK_OK(ctx, spx_lpips_distance_masked(lp, a, b, &m, &full, &got));
  CHECK_OK(ctx, spx_lpips_distance(lp, a, b, &plain));
  CHECK(full == plain); /* the mask changes nothing of the full-image value */
  CHECK_OK(ctx, spx_lpips_distance_masked(lp, a, b, NULL, &full, &none));
  CHECK(isnan(none));
  fprintf(stderr, "  %-10s masked LPIPS %.10g (lpips float64 %.10g, float32 %.10g): rel %.2g\n", name, got, want,
          want32, want ? fabs(got - want) / want : fabs(got));
  CHECK_NEAR(got, want, 1e-9, 1e-5);
  /* a mask of another size, a mask without foreground: errors naming the problem */
  spx_image small = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, a->width - 1, a->height, 1, &small));
  CHECK(spx_lpips_distance_masked(lp, a, b, &small, &full, &got) == SPX_E_ARG && strstr(spx_ctx_message(ctx), "mask"));
  memset(m.data, 0, sizeof(float) * (size_t)a->width * a->height);
  CHECK(spx_lpips_distance_masked(lp, a, b, &m, &full, &got) == SPX_E_ARG &&
        strstr(spx_ctx_message(ctx), "no foreground"));
  spx_image_free(&m), spx_image_free(&small);
}

static void test_masked_golden(void) {
  golden_cases("lpips_golden_m.safetensors", "lpips_masked_expected.txt", check_masked, NULL);
}

static void bad_file(spx_ctx *ctx, const char *skip, const char *bad, const char *needle) {
  char w[700];
  spx_t_path(w, sizeof w, "lpips_bad.safetensors");
  CHECK(spx_t_lpips_weights(ctx, w, skip, bad));
  spx_lpips *lp = (spx_lpips *)1;
  CHECK(spx_lpips_load(ctx, w, &lp) == SPX_E_FORMAT && lp == NULL);
  const char *m = spx_ctx_message(ctx);
  CHECK_MSG(strstr(m, "lpips_bad.safetensors") && strstr(m, needle), "%s", m);
}

static void test_bad_weights(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  bad_file(ctx, "net.slice3.6.weight", NULL, "net.slice3.6.weight is missing");
  bad_file(ctx, "lin4.model.1.weight", NULL, "lin4.model.1.weight is missing");
  bad_file(ctx, "scaling_layer.shift", NULL, "scaling_layer.shift is missing");
  bad_file(ctx, NULL, "net.slice2.3.bias", "net.slice2.3.bias has shape [1x1], expected [192]");
  bad_file(ctx, NULL, "lin0.model.1.weight", "lin0.model.1.weight has shape [1x1], expected [1x64x1x1]");
  spx_lpips *lp = NULL;
  CHECK(spx_lpips_load(ctx, "/nonexistent/w.safetensors", &lp) != SPX_OK && lp == NULL);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_pool);
  SPX_RUN(test_golden);
  SPX_RUN(test_masked_golden);
  SPX_RUN(test_bad_weights);
  return spx_test_summary();
}
