/* The VGG perceptual losses (lib/nn/vgg.c) against PyTorch: VGG19, eq. 5 of the paper
 * (tests/data/vgg/make_vgg_golden.py), and VGG16 as the official SMPLpix code computes it
 * (make_vgg16_golden.py: its Vgg16Features + L1Loss, batch 2), both with torchvision's layer order
 * and names at 1/16 width and random weights: the loss value and its gradient w.r.t. the
 * prediction, on the HOST backend (double references: vs PyTorch's float64 run) and the DEVICE
 * backend (vs PyTorch float32, within max(1e-4, 10 x its float32-vs-float64 spread)), also with an
 * image L1 weight w (spx_vgg_set_image_l1: reference + w mean |pred - gt|, gradient + w sign / n;
 * a weight outside [0, 1000] or NaN is refused); the frozen
 * weights have no gradient or optimizer slabs; a file without a tensor or with a misshapen one
 * fails with one line naming both, and so does the other network's file. (The real VGG16 of
 * `make weights`: tests/test_weights_golden.c.) */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nn/vgg.h"
#include "nn_testutil.h"
#include "smplpix/safetensors.h"
#include "st_compare.h"
#include "vgg_pass.h"

#define DIR SPX_TEST_DATA "/vgg/"

static spx_st_file G;
static const char *const wfile[2] = {DIR "vgg_w4.safetensors", DIR "vgg16_w4.safetensors"};
static const char *const gfile[2] = {DIR "vgg_golden.safetensors", DIR "vgg16_golden.safetensors"};

static const void *gdata(const char *name, size_t *n) {
  const spx_st_tensor *t = spx_st_find(&G, name);
  if (!t) return NULL;
  *n = t->nbytes / (t->dtype == SPX_F64 ? 8 : 4);
  return t->data;
}

/* element i of a F64 / F32 golden tensor (safetensors data need not be 8-byte aligned) */
static double at(const void *p, size_t i, int f64) {
  if (f64) {
    double d;
    memcpy(&d, (const char *)p + 8 * i, 8);
    return d;
  }
  float f;
  memcpy(&f, (const char *)p + 4 * i, 4);
  return f;
}

static void run(spx_ctx *ctx, spx_vgg_kind kind, spx_tape_backend be, double w) {
  spx_vgg *v = NULL;
  CHECK_OK(ctx, spx_vgg_open_ex(ctx, wfile[kind], kind, be, &v));
  if (!v) return;
  CHECK_OK(ctx, spx_vgg_set_image_l1(v, w));
  CHECK(spx_vgg_get_kind(v) == kind);
  const spx_st_tensor *pt = spx_st_find(&G, "pred");
  CHECK(pt && pt->ndim == 4 && pt->shape[1] == 3);
  if (!pt || pt->ndim != 4) goto done;
  int N = (int)pt->shape[0], H = (int)pt->shape[2], W = (int)pt->shape[3];
  spx_tape *t = spx_vgg_tape(v);
  CHECK(spx_vgg_width(v) == 4 && spx_tape_param_count(t) == 0); /* frozen: no trainable slab */
  size_t np = 0, ng = 0, nl = 0, ngr = 0;
  const float *pred = gdata("pred", &np), *gt = gdata("gt", &ng);
  const float *gl = gdata(be == SPX_TAPE_HOST ? "loss64" : "loss", &nl);
  const void *gg = gdata(be == SPX_TAPE_HOST ? "grad64" : "grad", &ngr);
  CHECK(pred && gt && gl && gg && np == (size_t)N * 3 * H * W && ngr == np);
  if (!pred || !gt || !gl || !gg) goto done;
  float *x = malloc(2 * np * 4), *grad = malloc(2 * np * 4);
  memcpy(x, pred, np * 4), memcpy(x + np, gt, np * 4);
  spx_t_vgg_pass p = {v, x, x + np, N, H, W, -1, -1};
  float lv = 0;
  CHECK_OK(ctx, spx_t_vgg_loss_grad(t, &p, &lv, grad));
  const int xi = p.xi, loss = p.loss;
  double ref_l = at(gl, 0, be == SPX_TAPE_HOST);
  for (size_t i = 0; i < np; i++) ref_l += w * fabs((double)pred[i] - gt[i]) / (double)np;
  double l_ours = be == SPX_TAPE_HOST ? spx_tape_host(t, loss)[0] : lv;
  double num = 0, den = 1e-30;
  for (size_t i = 0; i < np; i++) {
    double r = at(gg, i, be == SPX_TAPE_HOST) + w * (pred[i] > gt[i] ? 1.0 : -1.0) / (double)np;
    double o = be == SPX_TAPE_HOST ? spx_tape_host_grad(t, xi)[i] : grad[i];
    num = fmax(num, fabs(o - r)), den = fmax(den, fabs(r));
  }
  double el = fabs(l_ours - ref_l) / fabs(ref_l), eg = num / den;
  size_t one = 0;
  const float *sl = gdata("spread.loss", &one), *sg = gdata("spread.grad", &one);
  /* host: double arithmetic, but the normalisation constants 1/std and -mean/std are stored as
   * float32 in the tape (as on the device): ~1e-8 from PyTorch's float64 */
  double tl = be == SPX_TAPE_HOST ? 1e-6 : fmax(1e-4, 10.0 * sl[0]);
  double tg = be == SPX_TAPE_HOST ? 1e-6 : fmax(1e-4, 10.0 * sg[0]);
  printf("  %s%s %s vs PyTorch %s: loss %.3g, gradient w.r.t. the prediction %.3g (tolerances %.3g, %.3g)\n",
         kind ? "VGG16" : "VGG19", w > 0 ? " + image L1" : "", be == SPX_TAPE_HOST ? "host (double)" : "device (float32)",
         be == SPX_TAPE_HOST ? "float64" : "float32", el, eg, tl, tg);
  CHECK_MSG(el <= tl && eg <= tg, "loss %.3g gradient %.3g", el, eg);
  free(x), free(grad);
done:
  spx_vgg_destroy(v);
}

static void test_golden(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  for (int kind = 0; kind < 2; kind++) {
    CHECK_OK(ctx, spx_st_load(ctx, gfile[kind], &G));
    for (int k = 0; k < 2; k++) {
      run(ctx, (spx_vgg_kind)kind, SPX_TAPE_HOST, 0.5 * k);
      run(ctx, (spx_vgg_kind)kind, SPX_TAPE_DEVICE, 0.5 * k);
    }
    spx_st_free(&G);
  }
  spx_ctx_destroy(ctx);
}

static void test_bad_files(void) {
  spx_ctx *ctx = spx_nt_open();
  if (!ctx) return;
  spx_st_file f;
  CHECK_OK(ctx, spx_st_load(ctx, DIR "vgg_w4.safetensors", &f));
  char path[600];
  snprintf(path, sizeof path, "%s/bad_vgg.safetensors", spx_t_tmpdir());
  for (int pass = 0; pass < 2; pass++) {
    /* [16, 8, 3, 3] as [8, 16, 3, 3] */
    CHECK_OK(ctx, spx_t_st_save_altered(ctx, &f, path, pass == 0 ? "features.19.bias" : NULL,
                                        pass == 1 ? "features.10.weight" : NULL));
    spx_vgg *v = NULL;
    CHECK(spx_vgg_open(ctx, path, &v) != SPX_OK && !v);
    const char *m = spx_ctx_message(ctx);
    printf("  %s\n", m);
    CHECK(strstr(m, path) && strstr(m, pass ? "features.10.weight" : "missing tensor features.19.bias") && !strchr(m, '\n'));
  }
  spx_st_free(&f);
  spx_vgg *v = NULL;
  CHECK(spx_vgg_open(ctx, SPX_TEST_DATA "/patchgan/D.safetensors", &v) != SPX_OK);
  CHECK(strstr(spx_ctx_message(ctx), "features.0.weight") != NULL);
  CHECK(spx_vgg16_open(ctx, SPX_TEST_DATA "/patchgan/D.safetensors", &v) != SPX_OK && !v);
  CHECK(strstr(spx_ctx_message(ctx), "features.0.weight") && strstr(spx_ctx_message(ctx), "VGG16"));
  /* each network's file given to the other */
  CHECK(spx_vgg16_open(ctx, DIR "vgg_w4.safetensors", &v) != SPX_OK && !v);
  printf("  %s\n", spx_ctx_message(ctx));
  CHECK(strstr(spx_ctx_message(ctx), "vgg_w4.safetensors: holds a VGG19") != NULL);
  CHECK(spx_vgg_open(ctx, DIR "vgg16_w4.safetensors", &v) != SPX_OK && !v);
  printf("  %s\n", spx_ctx_message(ctx));
  CHECK(strstr(spx_ctx_message(ctx), "vgg16_w4.safetensors: holds a VGG16") != NULL);
  /* VGG16: a missing and a misshapen tensor */
  CHECK_OK(ctx, spx_st_load(ctx, DIR "vgg16_w4.safetensors", &f));
  for (int pass = 0; pass < 2; pass++) {
    CHECK_OK(ctx, spx_t_st_save_altered(ctx, &f, path, pass == 0 ? "features.21.bias" : NULL,
                                        pass == 1 ? "features.17.weight" : NULL));
    CHECK(spx_vgg16_open(ctx, path, &v) != SPX_OK && !v);
    const char *m = spx_ctx_message(ctx);
    printf("  %s\n", m);
    CHECK(strstr(m, path) && strstr(m, pass ? "features.17.weight" : "missing tensor features.21.bias") && !strchr(m, '\n'));
  }
  spx_st_free(&f);
  /* an image L1 weight outside [0, 1000] */
  CHECK_OK(ctx, spx_vgg16_open(ctx, DIR "vgg16_w4.safetensors", &v));
  const double bad[3] = {-0.1, 1001, NAN};
  for (int i = 0; i < 3 && v; i++) {
    CHECK(spx_vgg_set_image_l1(v, bad[i]) == SPX_E_ARG);
    CHECK(strstr(spx_ctx_message(ctx), "image L1 weight") != NULL);
  }
  spx_vgg_destroy(v);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_golden);
  SPX_RUN(test_bad_files);
  return spx_test_summary();
}
