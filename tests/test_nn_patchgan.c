/* One stage-2 training step (lib/nn/gan_step.c: UNet generator + pix2pixHD multi-scale PatchGAN,
 * LSGAN + feature matching + L1) against PyTorch (tests/data/patchgan/make_patchgan_golden.py):
 *  - G.safetensors (a PyTorch UNet state_dict) and D.safetensors (a PyTorch
 *    MultiscaleDiscriminator(getIntermFeat=True) state_dict) load here by their own names;
 *  - the loss terms before the step, and every parameter of G and of D after the step (Adam on
 *    both), within max(1e-4, 10 x PyTorch's own float32-vs-float64 spread of that tensor), for
 *    the generator loss L1 + GAN + 0.1 FM and for the paper's L_VGG + GAN + 0.1 FM (a small random
 *    VGG19, tests/data/vgg);
 *  - the discriminator checkpoint round trip (weights, Adam moments, step) and its errors (a
 *    missing and a misshapen tensor named in one line); PyTorch loads our D file strictly (run
 *    when /usr/bin/python3 has torch). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nn/gan_step.h"
#include "nn/vgg.h"
#include "nn_testutil.h"
#include "smplpix/safetensors.h"
#include "st_compare.h"

#define DIR SPX_TEST_DATA "/patchgan/"
#define TOL 1e-4
#define SPREAD_FACTOR 10.0
enum { SAMPLE = 2048 };

static spx_st_file G;
static double g_worst_loss, g_worst_g, g_worst_d;

/* ours (n floats) vs after.<tag><name> (complete or sampled + checksums); returns the error
 * relative to the tolerance (<= 1 passes). */
static double compare(const char *tag, const char *name, const float *ours, size_t n) {
  char key[256];
  snprintf(key, sizeof key, "spread.%s%s", tag, name);
  float *sp = spx_t_st_floats(&G, key, NULL);
  double tol = fmax(TOL, SPREAD_FACTOR * (sp ? sp[0] : 1.0));
  free(sp);
  snprintf(key, sizeof key, "after.%s%s", tag, name);
  size_t cnt = 0;
  float *g = spx_t_st_floats(&G, key, &cnt);
  if (!g) return INFINITY;
  size_t stride = n <= SAMPLE ? 1 : (n + SAMPLE - 1) / SAMPLE, m = (n + stride - 1) / stride;
  double e = INFINITY;
  if (cnt == m) {
    double num = 0, den = 1e-30;
    for (size_t i = 0; i < m; i++) num = fmax(num, fabs((double)ours[i * stride] - g[i])), den = fmax(den, fabs(g[i]));
    e = num / den;
  }
  free(g);
  if (n > SAMPLE) {
    snprintf(key, sizeof key, "aftersum.%s%s", tag, name);
    float *sums = spx_t_st_floats(&G, key, &cnt);
    if (!sums || cnt != 2) e = INFINITY;
    else {
      double dot = 0, l1 = 0;
      for (size_t i = 0; i < n; i++) {
        uint32_t h = (uint32_t)((uint64_t)i * 2654435761u);
        dot += (h & 0x80000000u) ? -(double)ours[i] : (double)ours[i];
        l1 += fabs((double)ours[i]);
      }
      e = fmax(e, fmax(fabs(dot - sums[0]), fabs(l1 - sums[1])) / fmax((double)sums[1], 1e-30));
    }
    free(sums);
  }
  CHECK_MSG(e <= tol, "%s%s after the step: relative error %.3g > %.3g", tag, name, e, tol);
  return e;
}

/* with_vgg: the paper's stage 2 (L_VGG instead of L1, step_vgg.safetensors); checkpoint checks
 * run once (without). */
static void run_step(int with_vgg) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  spx_unet *g = NULL;
  spx_patchgan *d = NULL;
  spx_vgg *vgg = NULL;
  g_worst_loss = g_worst_g = g_worst_d = 0;
  CHECK_OK(ctx, spx_st_load(ctx, with_vgg ? DIR "step_vgg.safetensors" : DIR "step.safetensors", &G));
  if (with_vgg) CHECK_OK(ctx, spx_vgg_open(ctx, SPX_TEST_DATA "/vgg/vgg_w4.safetensors", &vgg));
  CHECK_OK(ctx, spx_unet_load(ctx, DIR "G.safetensors", &g));
  CHECK_OK(ctx, spx_patchgan_load(ctx, DIR "D.safetensors", 7, SPX_TAPE_DEVICE, &d));
  size_t nin = 0, ntg = 0;
  float *in = spx_t_st_floats(&G, "input", &nin), *tg = spx_t_st_floats(&G, "target", &ntg);
  if (!g || !d || !in || !tg) goto done;
  CHECK(spx_patchgan_num_d(d) == 3 && spx_patchgan_ndf(d) == 4 && spx_patchgan_step(d) == 0);
  spx_gan_opts o = {1e-3, 1e-3, 0.9, 0.999, 1e-3, 0.1f, 1.0f};
  spx_gan_losses tm;
  CHECK_OK(ctx, spx_gan_step(ctx, g, d, vgg, in, tg, 1, 37, 53, &o, &tm));
  const char *ln[6] = {"loss.rec", "loss.gan", "loss.fm", "loss.d_fake", "loss.d_real", "loss.vgg"};
  float ours[6] = {tm.rec, tm.gan, tm.fm, tm.d_fake, tm.d_real, tm.vgg};
  for (int i = 0; i < (with_vgg ? 6 : 5); i++) {
    float *v = spx_t_st_floats(&G, ln[i], NULL);
    if (!v) continue;
    double e = fabs(ours[i] - v[0]) / fabs(v[0]);
    g_worst_loss = fmax(g_worst_loss, e);
    CHECK_MSG(e <= TOL, "%s: ours %.7g torch %.7g", ln[i], ours[i], v[0]);
    free(v);
  }
  CHECK(fabsf(tm.d_total - 0.5f * (tm.d_fake + tm.d_real)) <= 1e-6f * tm.d_total);
  CHECK(fabsf(tm.g_total - ((with_vgg ? tm.vgg : tm.rec) + tm.gan + 0.1f * tm.fm)) <= 1e-5f * tm.g_total);
  for (int i = 0; i < spx_unet_tensor_count(g); i++) {
    int ndim;
    int64_t sh[4];
    const char *name = spx_unet_tensor_name(g, i, &ndim, sh);
    if (strstr(name, "running_")) continue;
    size_t n = 1;
    for (int k = 0; k < ndim; k++) n *= (size_t)sh[k];
    float *buf = malloc(n * 4);
    CHECK_OK(ctx, spx_unet_read(g, name, SPX_UNET_VALUE, buf, n));
    g_worst_g = fmax(g_worst_g, compare("G.", name, buf, n));
    free(buf);
  }
  spx_tape *dt = spx_patchgan_tape(d);
  for (int i = 0; i < spx_patchgan_tensor_count(d); i++) {
    const char *name = spx_patchgan_tensor_name(d, i, NULL, NULL);
    int id = spx_patchgan_value_id(d, name);
    size_t n = spx_tape_numel(dt, id);
    float *buf = malloc(n * 4);
    CHECK_OK(ctx, spx_tape_read(dt, id, buf));
    g_worst_d = fmax(g_worst_d, compare("D.", name, buf, n));
    free(buf);
  }
  printf("  %s vs PyTorch: loss terms %.3g, G after the step %.3g, D after the step %.3g (relative)\n",
         with_vgg ? "L_VGG + GAN + 0.1 FM" : "L1 + GAN + 0.1 FM", g_worst_loss, g_worst_g, g_worst_d);
  CHECK(spx_patchgan_step(d) == 1 && spx_unet_step(g) == 1);
  if (with_vgg) goto done;

  /* checkpoint round trip and errors */
  char path[512], bad[512];
  snprintf(path, sizeof path, "%s/d_ckpt.safetensors", spx_t_tmpdir());
  snprintf(bad, sizeof bad, "%s/d_bad.safetensors", spx_t_tmpdir());
  CHECK_OK(ctx, spx_patchgan_save(d, path, 1));
  spx_patchgan *d2 = NULL;
  CHECK_OK(ctx, spx_patchgan_load(ctx, path, 7, SPX_TAPE_DEVICE, &d2));
  if (d2) {
    int same = spx_patchgan_step(d2) == 1;
    for (int i = 0; i < spx_patchgan_tensor_count(d) && same; i++) {
      const char *name = spx_patchgan_tensor_name(d, i, NULL, NULL);
      int a = spx_patchgan_value_id(d, name), b = spx_patchgan_value_id(d2, name);
      size_t n = spx_tape_numel(dt, a);
      float *x1 = malloc(n * 4), *x2 = malloc(n * 4), *m1 = malloc(n * 4), *m2 = malloc(n * 4), *v1 = malloc(n * 4),
            *v2 = malloc(n * 4);
      spx_tape_read(dt, a, x1), spx_tape_read(spx_patchgan_tape(d2), b, x2);
      spx_tape_read_moments(dt, a, m1, v1), spx_tape_read_moments(spx_patchgan_tape(d2), b, m2, v2);
      same = !memcmp(x1, x2, n * 4) && !memcmp(m1, m2, n * 4) && !memcmp(v1, v2, n * 4);
      free(x1), free(x2), free(m1), free(m2), free(v1), free(v2);
    }
    CHECK_MSG(same, "discriminator checkpoint round trip differs");
    spx_patchgan_destroy(d2);
  }
  /* a file without one tensor, and one with a misshapen tensor */
  spx_st_file f;
  CHECK_OK(ctx, spx_st_load(ctx, path, &f));
  for (int pass = 0; pass < 2; pass++) {
    /* [32,16,4,4] as [16,32,4,4] */
    CHECK_OK(ctx, spx_t_st_save_altered(ctx, &f, bad, pass == 0 ? "scale1_layer2.0.bias" : NULL,
                                        pass == 1 ? "scale2_layer3.0.weight" : NULL));
    spx_patchgan *d3 = NULL;
    CHECK(spx_patchgan_load(ctx, bad, 7, SPX_TAPE_DEVICE, &d3) != SPX_OK && d3 == NULL);
    const char *msg = spx_ctx_message(ctx);
    printf("  bad file: %s\n", msg);
    CHECK(strstr(msg, bad) && strstr(msg, pass == 0 ? "missing tensor scale1_layer2.0.bias" : "scale2_layer3.0.weight"));
    CHECK(!strchr(msg, '\n'));
  }
  spx_st_free(&f);
  CHECK(spx_patchgan_load(ctx, DIR "G.safetensors", 7, SPX_TAPE_DEVICE, &d2) != SPX_OK);
  char cmd[1024];
  snprintf(cmd, sizeof cmd, "/usr/bin/python3 %s/patchgan/make_patchgan_golden.py --check %s", SPX_TEST_DATA, path);
  if (spx_t_system("/usr/bin/python3 -c 'import torch' >/dev/null 2>&1") == 0)
    CHECK_MSG(spx_t_system(cmd) == 0, "PyTorch rejected our discriminator checkpoint: %s", cmd);
  else
    printf("  (no PyTorch here: check the checkpoint with %s)\n", cmd);
done:
  free(in), free(tg);
  spx_unet_destroy(g);
  spx_patchgan_destroy(d);
  spx_vgg_destroy(vgg);
  spx_st_free(&G);
  spx_ctx_destroy(ctx);
}

static void test_step(void) { run_step(0); }
static void test_step_vgg(void) { run_step(1); }

/* A perceptual step after the image L1 weight changed runs the new loss, not the graph planned for
 * the old one: two equal generators take a step at weight 0, then one more, one at 0.5 and one at
 * 0; the second steps' losses differ by 0.5 x the L1 both report (their forwards see equal weights). */
static void test_vgg_image_l1_change(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  spx_unet *g[2] = {NULL, NULL};
  spx_vgg *v[2] = {NULL, NULL};
  spx_gan_losses l[2][2];
  CHECK_OK(ctx, spx_st_load(ctx, DIR "step_vgg.safetensors", &G));
  float *in = spx_t_st_floats(&G, "input", NULL), *tg = spx_t_st_floats(&G, "target", NULL);
  for (int k = 0; k < 2 && in && tg; k++) {
    CHECK_OK(ctx, spx_unet_load(ctx, DIR "G.safetensors", &g[k]));
    CHECK_OK(ctx, spx_vgg_open(ctx, SPX_TEST_DATA "/vgg/vgg_w4.safetensors", &v[k]));
    if (!g[k] || !v[k]) break;
    CHECK_OK(ctx, spx_unet_vgg_step(g[k], v[k], in, tg, 1, 37, 53, 1e-3, &l[k][0]));
    CHECK_OK(ctx, spx_vgg_set_image_l1(v[k], k ? 0.0 : 0.5));
    CHECK_OK(ctx, spx_unet_vgg_step(g[k], v[k], in, tg, 1, 37, 53, 1e-3, &l[k][1]));
  }
  if (g[1] && v[1]) {
    double extra = l[0][1].vgg - l[1][1].vgg, want = 0.5 * l[1][1].rec;
    printf("  second step: loss %.7g at weight 0.5, %.7g at 0 (difference %.4g, 0.5 x L1 %.4g)\n", l[0][1].vgg,
           l[1][1].vgg, extra, want);
    CHECK(l[0][0].vgg == l[1][0].vgg && l[0][1].rec == l[1][1].rec);
    CHECK_MSG(fabs(extra - want) <= 1e-4 * l[1][1].vgg + 1e-6, "difference %.7g, want %.7g", extra, want);
  }
  for (int k = 0; k < 2; k++) spx_unet_destroy(g[k]), spx_vgg_destroy(v[k]);
  free(in), free(tg);
  spx_st_free(&G);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_step);
  SPX_RUN(test_step_vgg);
  SPX_RUN(test_vgg_image_l1_change);
  return spx_test_summary();
}
