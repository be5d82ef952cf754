/* LPIPS (lib/metrics/lpips.c) and its 3x3/2 max pooling (kernels/metrics.cl):
 *  - the device pooling against the double reference (odd sizes, ties, NaN, -inf), bit-reproducible;
 *  - LPIPS against the lpips PyPI package (tools/make_lpips_golden.py: a random AlexNet whose weights
 *    this test regenerates bit for bit, written here to a safetensors file), relative 1e-5;
 *  - weight files with a missing, misshapen or non-float tensor: one message naming file and tensor. */
#include "metrics/metrics_internal.h"
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
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
  if (!ctx) return;
  pool_case(ctx, 2, 3, 37, 53, 0);
  pool_case(ctx, 2, 3, 15, 16, 1);
  pool_case(ctx, 1, 2, 3, 3, 0);
  spx_ctx_destroy(ctx);
}

/* ---- the LPIPS golden ---- */

/* splitmix64(seed * 2^32 + i) >> 11, times 2^-53 (tools/make_lpips_golden.py: splitmix_uniform) */
static double uniform(uint64_t seed, uint64_t i) {
  uint64_t z = (seed << 32) + i + 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  z ^= z >> 31;
  return (double)(z >> 11) * 0x1p-53;
}

static const char *const conv_names[5] = {"net.slice1.0", "net.slice2.3", "net.slice3.6", "net.slice4.8",
                                          "net.slice5.10"};
static const int conv_shape[5][4] = {{64, 3, 11, 11}, {192, 64, 5, 5}, {384, 192, 3, 3}, {256, 384, 3, 3}, {256, 256, 3, 3}};

/* Write the golden's weights to path. skip: a tensor to leave out; bad: a tensor to give a wrong shape. */
static int write_weights(spx_ctx *ctx, const char *path, const char *skip, const char *bad) {
  spx_st_entry e[17];
  char names[17][48];
  float *bufs[17] = {0};
  int n = 0;
  uint64_t seed = 1;
  static const float shift[3] = {-.030f, -.088f, -.188f}, scale[3] = {.458f, .448f, .450f};
  for (int l = 0; l < 5; l++)
    for (int part = 0; part < 2; part++, seed++) {
      size_t cnt = part ? (size_t)conv_shape[l][0]
                        : (size_t)conv_shape[l][0] * conv_shape[l][1] * conv_shape[l][2] * conv_shape[l][3];
      double a = part ? 0.1 : sqrt(6.0 / (conv_shape[l][1] * conv_shape[l][2] * conv_shape[l][3]));
      bufs[n] = malloc(4 * cnt);
      for (size_t i = 0; i < cnt; i++) bufs[n][i] = (float)((2 * uniform(seed, i) - 1) * a);
      snprintf(names[n], sizeof names[n], "%s.%s", conv_names[l], part ? "bias" : "weight");
      e[n] = (spx_st_entry){names[n], SPX_F32, part ? 1 : 4, {0}, bufs[n]};
      for (int d = 0; d < (part ? 1 : 4); d++) e[n].shape[d] = conv_shape[l][d];
      n++;
    }
  for (int l = 0; l < 5; l++, seed++) {
    size_t cnt = (size_t)conv_shape[l][0];
    bufs[n] = malloc(4 * cnt);
    for (size_t i = 0; i < cnt; i++) bufs[n][i] = (float)(0.2 * uniform(seed, i));
    snprintf(names[n], sizeof names[n], "lin%d.model.1.weight", l);
    e[n] = (spx_st_entry){names[n], SPX_F32, 4, {1, conv_shape[l][0], 1, 1}, bufs[n]};
    n++;
  }
  e[n++] = (spx_st_entry){"scaling_layer.shift", SPX_F32, 4, {1, 3, 1, 1}, shift};
  e[n++] = (spx_st_entry){"scaling_layer.scale", SPX_F32, 4, {1, 3, 1, 1}, scale};
  int m = 0;
  for (int i = 0; i < n; i++) {
    if (skip && !strcmp(e[i].name, skip)) continue;
    e[m] = e[i];
    if (bad && !strcmp(e[i].name, bad)) e[m].shape[0] = 1, e[m].shape[1] = 1, e[m].ndim = 2;
    m++;
  }
  spx_status st = spx_st_save(ctx, path, e, m, NULL, NULL, 0);
  for (int i = 0; i < 17; i++) free(bufs[i]);
  return st == SPX_OK;
}

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

static void test_golden(void) {
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
  if (!ctx) return;
  char w[700], line[256], p[1024];
  spx_t_path(w, sizeof w, "lpips_golden.safetensors");
  CHECK(write_weights(ctx, w, NULL, NULL));
  spx_lpips *lp = NULL;
  CHECK_OK(ctx, spx_lpips_load(ctx, w, &lp));
  snprintf(p, sizeof p, "%s/metrics/lpips_expected.txt", SPX_TEST_DATA);
  FILE *f = fopen(p, "r");
  CHECK(f && lp);
  int cases = 0;
  while (f && lp && fgets(line, sizeof line, f)) {
    char name[64], pn[96], tn[96];
    double want, want32;
    if (line[0] == '#' || sscanf(line, "%63s %lf %lf", name, &want, &want32) != 3) continue;
    snprintf(pn, sizeof pn, "%s_pred", name);
    snprintf(tn, sizeof tn, "%s_target", name);
    spx_image a = {0}, b = {0};
    CHECK(load_npy(ctx, pn, &a) && load_npy(ctx, tn, &b));
    double got = -1, again = -2;
    CHECK_OK(ctx, spx_lpips_distance(lp, &a, &b, &got));
    CHECK_OK(ctx, spx_lpips_distance(lp, &a, &b, &again));
    fprintf(stderr, "  %-10s LPIPS %.10g (lpips float64 %.10g, float32 %.10g): rel %.2g\n", name, got, want, want32,
            want ? fabs(got - want) / want : fabs(got));
    CHECK_NEAR(got, want, 1e-9, 1e-5);
    CHECK(got == again); /* deterministic */
    spx_image_free(&a), spx_image_free(&b);
    cases++;
  }
  if (f) fclose(f);
  CHECK(cases == 3);
  /* too small for AlexNet */
  spx_image s = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, 30, 40, 3, &s));
  double v;
  if (lp) CHECK(spx_lpips_distance(lp, &s, &s, &v) == SPX_E_ARG && strstr(spx_ctx_message(ctx), "31x31"));
  spx_image_free(&s);
  spx_lpips_free(lp);
  spx_ctx_destroy(ctx);
}

static void bad_file(spx_ctx *ctx, const char *skip, const char *bad, const char *needle) {
  char w[700];
  spx_t_path(w, sizeof w, "lpips_bad.safetensors");
  CHECK(write_weights(ctx, w, skip, bad));
  spx_lpips *lp = (spx_lpips *)1;
  CHECK(spx_lpips_load(ctx, w, &lp) == SPX_E_FORMAT && lp == NULL);
  const char *m = spx_ctx_message(ctx);
  CHECK_MSG(strstr(m, "lpips_bad.safetensors") && strstr(m, needle), "%s", m);
}

static void test_bad_weights(void) {
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
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
  SPX_RUN(test_bad_weights);
  return spx_test_summary();
}
