/* The pretrained perceptual networks of `make weights` (found as `smplpix` finds them:
 * spx_weights_path, ${SPX_CACHE_DIR:-~/.cache/smplpix}/weights/) against outside code
 * (tools/make_weights_golden.py, tests/data/weights/):
 *  - LPIPS with the cached lpips_alex.safetensors on 24 image pairs of 6 sizes (31x31 .. 64x48)
 *    = the lpips package's LPIPS(net='alex') with that AlexNet, float64, within 1e-5 relative;
 *  - the VGG16 loss (lib/nn/vgg.c) with the cached vgg16.safetensors and its gradient w.r.t. the
 *    prediction = the official SMPLpix code's Vgg16Features + L1Loss on torchvision's
 *    vgg16().features with those weights: HOST backend (double) vs PyTorch float64 within 1e-6,
 *    DEVICE backend (float32) vs PyTorch float32 within 10 x PyTorch's own float32-vs-float64
 *    spread (at least 1e-5).
 * Skipped (77, saying which file is absent) without the weights; ctest runs it with the caller's
 * SPX_CACHE_DIR / HOME (tests/extra.cmake). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lpips_weights.h"
#include "nn/vgg.h"
#include "nn_testutil.h"
#include "smplpix/metrics.h"
#include "smplpix/safetensors.h"
#include "vgg_pass.h"

#define DIR SPX_TEST_DATA "/weights/"

static const double alphas[4] = {1.0 / 16, 1.0 / 4, 1.0 / 2, 1.0};

/* Pair j of tools/make_weights_golden.py (pair_images): pred = a, target = (1 - alpha) a + alpha b. */
static void pair_images(int j, int h, int w, double alpha, spx_image *p, spx_image *t) {
  size_t n = (size_t)h * w * 3;
  float *a = malloc(n * sizeof(float)), *b = malloc(n * sizeof(float));
  for (size_t i = 0; i < n && a && b; i++) {
    double u = spx_t_lpips_uniform(1000 + (uint64_t)j, i), v = spx_t_lpips_uniform(2000 + (uint64_t)j, i);
    a[i] = (float)u;
    b[i] = (float)((1.0 - alpha) * u + alpha * v);
  }
  *p = (spx_image){w, h, 3, a};
  *t = (spx_image){w, h, 3, b};
}

static int test_lpips(spx_ctx *ctx) {
  char w[4096];
  if (spx_weights_path(SPX_WEIGHTS_LPIPS_ALEX, w, sizeof w) != 1) {
    printf("  skipped LPIPS: %s is absent (make weights downloads it)\n", w[0] ? w : "the cache (no HOME)");
    return 0;
  }
  spx_lpips *lp = NULL;
  CHECK_OK(ctx, spx_lpips_load(ctx, w, &lp));
  FILE *f = fopen(DIR "lpips_alex_expected.txt", "r");
  CHECK(f && lp);
  char line[512];
  int cases = 0, sizes = 0, last_h = 0;
  double worst = 0;
  while (f && lp && fgets(line, sizeof line, f)) {
    int j, h, wd;
    double alpha, want, want32;
    if (line[0] == '#' || sscanf(line, "%d %d %d %lf %lf %lf", &j, &h, &wd, &alpha, &want, &want32) != 6) continue;
    CHECK(alpha == alphas[j % 4]);
    spx_image p, t;
    pair_images(j, h, wd, alpha, &p, &t);
    double got = -1;
    CHECK_OK(ctx, spx_lpips_distance(lp, &p, &t, &got));
    double rel = fabs(got - want) / fabs(want);
    if (rel > worst) worst = rel;
    CHECK_MSG(rel <= 1e-5, "pair %d (%dx%d, alpha %g): LPIPS %.10g, lpips package %.10g (rel %.3g)", j, wd, h, alpha,
              got, want, rel);
    sizes += h != last_h;
    last_h = h;
    spx_image_free(&p), spx_image_free(&t);
    cases++;
  }
  if (f) fclose(f);
  CHECK(cases == 24 && sizes >= 6);
  printf("  LPIPS (%s) vs the lpips package (float64): %d pairs, largest relative difference %.3g\n", w, cases, worst);
  spx_lpips_free(lp);
  return 1;
}

static double at(const spx_st_tensor *t, size_t i) {
  if (t->dtype == SPX_F64) {
    double d;
    memcpy(&d, (const char *)t->data + 8 * i, 8);
    return d;
  }
  float x;
  memcpy(&x, (const char *)t->data + 4 * i, 4);
  return x;
}

static void vgg16_run(spx_ctx *ctx, const char *path, const spx_st_file *g, spx_tape_backend be) {
  spx_vgg *v = NULL;
  CHECK_OK(ctx, spx_vgg_open_ex(ctx, path, SPX_VGG16_SMPLPIX, be, &v));
  const spx_st_tensor *tp = spx_st_find(g, "pred"), *tt = spx_st_find(g, "gt");
  const spx_st_tensor *tl = spx_st_find(g, be == SPX_TAPE_HOST ? "loss64" : "loss");
  const spx_st_tensor *tg = spx_st_find(g, be == SPX_TAPE_HOST ? "grad64" : "grad");
  const spx_st_tensor *sl = spx_st_find(g, "spread.loss"), *sg = spx_st_find(g, "spread.grad");
  CHECK(v && tp && tt && tl && tg && sl && sg && tp->ndim == 4 && tp->dtype == SPX_F32);
  if (!v || !tp || !tt || !tl || !tg || !sl || !sg || tp->ndim != 4) {
    spx_vgg_destroy(v);
    return;
  }
  CHECK(spx_vgg_width(v) == 64);
  int n = (int)tp->shape[0], h = (int)tp->shape[2], w = (int)tp->shape[3];
  size_t np = (size_t)n * 3 * h * w;
  float *x = malloc(2 * np * sizeof(float)), *grad = malloc(np * sizeof(float));
  for (size_t i = 0; i < np; i++) x[i] = (float)at(tp, i), x[np + i] = (float)at(tt, i);
  spx_tape *t = spx_vgg_tape(v);
  spx_t_vgg_pass p = {v, x, x + np, n, h, w, -1, -1};
  float lv = 0;
  CHECK_OK(ctx, spx_t_vgg_loss_grad(t, &p, &lv, grad));
  const int xi = p.xi, loss = p.loss;
  double l_ours = be == SPX_TAPE_HOST ? spx_tape_host(t, loss)[0] : lv, num = 0, den = 1e-30;
  for (size_t i = 0; i < np; i++) {
    double r = at(tg, i), o = be == SPX_TAPE_HOST ? spx_tape_host_grad(t, xi)[i] : grad[i];
    num = fmax(num, fabs(o - r)), den = fmax(den, fabs(r));
  }
  double el = fabs(l_ours - at(tl, 0)) / fabs(at(tl, 0)), eg = num / den;
  double tol_l = be == SPX_TAPE_HOST ? 1e-6 : fmax(1e-5, 10 * at(sl, 0));
  double tol_g = be == SPX_TAPE_HOST ? 1e-6 : fmax(1e-5, 10 * at(sg, 0));
  printf("  VGG16 loss (%s), %s vs PyTorch %s: loss %.8g, relative difference %.3g; gradient %.3g (tolerances %.3g, "
         "%.3g)\n", path, be == SPX_TAPE_HOST ? "host (double)" : "device (float32)",
         be == SPX_TAPE_HOST ? "float64" : "float32", l_ours, el, eg, tol_l, tol_g);
  CHECK_MSG(el <= tol_l && eg <= tol_g, "loss %.3g gradient %.3g", el, eg);
  free(x), free(grad);
  spx_vgg_destroy(v);
}

static int test_vgg16(spx_ctx *ctx) {
  char w[4096];
  if (spx_weights_path(SPX_WEIGHTS_VGG16, w, sizeof w) != 1) {
    printf("  skipped VGG16: %s is absent (make weights downloads it)\n", w[0] ? w : "the cache (no HOME)");
    return 0;
  }
  spx_st_file g;
  memset(&g, 0, sizeof g);
  CHECK_OK(ctx, spx_st_load(ctx, DIR "vgg16_golden.safetensors", &g));
  vgg16_run(ctx, w, &g, SPX_TAPE_HOST);
  vgg16_run(ctx, w, &g, SPX_TAPE_DEVICE);
  spx_st_free(&g);
  return 1;
}

int main(void) {
  spx_ctx *ctx = spx_nt_open();
  if (!ctx) return 1;
  int ran = test_lpips(ctx);
  ran += test_vgg16(ctx);
  spx_ctx_destroy(ctx);
  int rc = spx_test_summary();
  if (rc) return rc;
  if (ran < 2) {
    printf("skipped: the pretrained weights of `make weights` are missing (see above)\n");
    return 77;
  }
  return 0;
}
