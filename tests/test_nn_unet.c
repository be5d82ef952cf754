/* The SMPLpix UNet against PyTorch (tests/data/unet/make_unet_golden.py wrote the golden file:
 * milesial UNet, bilinear, width 8, input 1x4x37x53, see the script for its exact contents).
 *
 *  - the golden file is itself a PyTorch-written checkpoint (state_dict names, F16 conv weights,
 *    I64 num_batches_tracked): spx_unet_load reads it, so loading PyTorch weights is checked;
 *  - train-mode output and L1 loss, every parameter gradient, the three losses and the weights
 *    and running statistics after 3 Adam steps (lr 1e-3), and the eval-mode output (batch norm
 *    folded into the convolutions);
 *  - checkpoint round trip (weights, running stats, optimizer state, step), resume gives the
 *    same next step as continuing, and errors name the missing / mis-shaped tensor;
 *  - the other direction: our checkpoint + our eval output are written for the script's --check
 *    mode, which is run when /usr/bin/python3 has torch (else the command is printed).
 *
 * Tolerance: 1e-4, as max |ours - torch| / max |torch| over each tensor. Both sides are float32
 * but sum in different orders (our conv tiles / deterministic two-stage reductions vs oneDNN's
 * blocked GEMM and PyTorch's batch-norm reductions); through ~20 layers, each with batch norm
 * over as few as 6 values per channel at the bottleneck, those rounding differences grow to
 * ~1e-6..1e-5 of the tensor's scale. 1e-4 keeps a 10x margin; a wrong op or wiring is O(1).
 *
 * With Winograd in training (tunable CONV_WINO_TRAIN, and a layer of this width-8 network wide
 * enough for CONV_WINO_MINC: its widest 3x3 convolutions are 64 -> 64 channels), both tolerances
 * (TOL and SPREAD_FACTOR) are multiplied by SPX_WINO_RMS_GAIN = 32 (lib/nn/conv2d.h): the factor
 * by which F(4x4,3x3)'s rounding error exceeds the direct convolution's in the worst output of a
 * tile, derived from the transform matrices alone in tests/test_nn_conv2d_winograd.c (second
 * moments: rounding errors of the Cin-term GEMM sums are amplified by the output transform and
 * grow with the transformed operands' magnitudes; 31.4 for the points 0, +-1, +-2, inf). Every
 * golden difference here is accumulated conv rounding, so it scales by at most that factor: the
 * bound becomes 3.2e-3 (observed with every layer on Winograd, SPX_TUNE_CONV_WINO_MINC=1: see the
 * printed worst errors), still far below the O(1) error of a wrong op. The Winograd weight gradient
 * (CONV_WINO_DW; its typical error gain is 24.2 <= 32, derived in tests/test_nn_conv2d_winograd_dw.c)
 * widens them the same way when a layer here takes it; the ctest variant test_nn_unet_wino_all runs
 * every 3x3 layer's forward, data and weight gradient on Winograd (gradients 2.2e-4 and weights after
 * Adam 3.2e-3, the same as without the Winograd weight gradient: the forward's rounding dominates;
 * with only the weight gradient on Winograd, SPX_TUNE_CONV_WINO_MINC=0, 4.9e-5 and 1.7e-4, as direct). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nn/conv2d.h"
#include "nn/unet.h"
#include "nn_testutil.h"
#include "smplpix/safetensors.h"
#include "st_compare.h"
#include "smplpix/smplpix.h"
#include "smplpix/unet.h"

#define GOLDEN SPX_TEST_DATA "/unet/unet_w8_golden.safetensors"
#define TOL 1e-4
#define SPREAD_FACTOR 10.0 /* see spread_tol */
#define ADAM_EPS 1e-3 /* as in the script: see there why not 1e-8 */
enum { GN = 1, GH = 37, GW = 53, SAMPLE = 2048 };

static spx_st_file G;
static double g_worst[8]; /* max errors by check kind, printed at the end */
static const char *g_kind[8] = {"output", "loss", "gradients", "losses(3 steps)", "weights after Adam",
                                "running stats", "eval output", "grad/weight checksums"};

/* max |a - b| / max |b| */
static double rel_err(const float *a, const float *b, size_t n) {
  double num = 0, den = 1e-30;
  for (size_t i = 0; i < n; i++) {
    double d = fabs((double)a[i] - (double)b[i]);
    if (!(d <= num)) num = d;
    den = fmax(den, fabs((double)b[i]));
  }
  return num / den;
}

static double g_tol = TOL, g_spread_factor = SPREAD_FACTOR; /* times SPX_WINO_RMS_GAIN with Winograd */

static void note_tol(int kind, const char *what, double e, double tol) {
  if (!(e <= g_worst[kind])) g_worst[kind] = e;
  CHECK_MSG(e <= tol, "%s: relative error %.3g > %.3g", what, e, tol);
}
static void note(int kind, const char *what, double e) { note_tol(kind, what, e, g_tol); }

/* Tensors after the 3 Adam steps: tolerance max(TOL, SPREAD_FACTOR * spread), spread being how far
 * PyTorch float32 itself is from the same run in float64 (golden.spread.<name>, see the script).
 * Training amplifies rounding: after 1 and 2 steps ours and PyTorch agree to ~1e-6 (as PyTorch
 * float32 and float64 do), the 3rd step jumps to ~1e-4 in a few layers for both. Our float32 sums
 * are measured ~2x less accurate than oneDNN's blocked ones before that jump, and the jump
 * multiplies any difference, so the factor is 10; a real error (wrong moment, bias correction,
 * running-stat update) is orders of magnitude larger.
 * The weights after 3 steps also get a floor of ADAM3_FLOOR: the 3rd step's jump moves with the
 * summation order itself, not only with the precision. Our own legitimate orders (the GPU column's
 * batch-norm tree, SPX_TUNE_BN_WG=4 on the CPU column) land a tensor whose PyTorch spread is
 * ~2e-6 at 2.2e-4 (ratio 100 instead of ~6), while a wrong Adam moves weights by O(lr) = 1e-3 per
 * step, 3e-3..3e-2 of these tensors' scale (a missing bias correction: 2.7 lr at step 1). */
#define ADAM3_FLOOR 1e-3
static double g_spread_ratio; /* max err / spread seen */
static double spread_tol(int kind, const char *name, double err) {
  char k[256];
  snprintf(k, sizeof k, "golden.spread.%s", name);
  float *sp = spx_t_st_floats(&G, k, NULL);
  double spread = sp ? sp[0] : 0;
  free(sp);
  CHECK_MSG(spread > 0, "no %s", k);
  if (spread > 0 && err / spread > g_spread_ratio) g_spread_ratio = err / spread;
  return fmax(fmax(g_tol, g_spread_factor * spread), kind == 4 ? ADAM3_FLOOR : 0.0);
}

/* Compare a tensor of ours with a golden record that is complete (<= SAMPLE elements) or a strided
 * sample + [sum g*r, sum |g|] checksums over all elements. */
static void compare_sampled(int kind, const char *prefix, const char *sumprefix, const char *name, const float *ours,
                            size_t n) {
  char key[256];
  snprintf(key, sizeof key, "%s%s", prefix, name);
  size_t cnt = 0;
  float *g = spx_t_st_floats(&G, key, &cnt);
  CHECK_MSG(g != NULL, "golden has no %s", key);
  if (!g) return;
  size_t stride = n <= SAMPLE ? 1 : (n + SAMPLE - 1) / SAMPLE, m = (n + stride - 1) / stride;
  CHECK(cnt == m);
  float *s = malloc(m * sizeof(float));
  for (size_t i = 0; i < m; i++) s[i] = ours[i * stride];
  if (cnt == m) {
    double e = rel_err(s, g, m);
    note_tol(kind, key, e, kind >= 4 ? spread_tol(kind, name, e) : g_tol);
  }
  free(s);
  if (n > SAMPLE) {
    snprintf(key, sizeof key, "%s%s", sumprefix, name);
    float *sums = spx_t_st_floats(&G, key, &cnt);
    CHECK(sums && cnt == 2);
    if (sums && cnt == 2) {
      double dot = 0, l1 = 0;
      for (size_t i = 0; i < n; i++) {
        uint32_t hsh = (uint32_t)((uint64_t)i * 2654435761u);
        dot += (hsh & 0x80000000u) ? -(double)ours[i] : (double)ours[i];
        l1 += fabs((double)ours[i]);
      }
      /* both sums relative to sum |g| (the dot product can cancel) */
      double e = fmax(fabs(dot - sums[0]), fabs(l1 - sums[1])) / fmax((double)sums[1], 1e-30);
      if (!(e <= g_worst[7])) g_worst[7] = e;
      double tol = kind >= 4 ? spread_tol(kind, name, e) : g_tol;
      CHECK_MSG(e <= tol, "%s: checksum error %.3g > %.3g", key, e, tol);
    }
    free(sums);
  }
  free(g);
}

static float *read_all(spx_ctx *ctx, spx_unet *u, const char *name, spx_unet_field f, size_t *n) {
  int64_t shape[4];
  int ndim = 0;
  *n = 0;
  for (int i = 0; i < spx_unet_tensor_count(u); i++)
    if (!strcmp(spx_unet_tensor_name(u, i, &ndim, shape), name)) {
      size_t c = 1;
      for (int d = 0; d < ndim; d++) c *= (size_t)shape[d];
      float *buf = malloc(c * sizeof(float));
      if (spx_unet_read(u, name, f, buf, c)) {
        fprintf(stderr, "  read %s: %s\n", name, spx_ctx_message(ctx));
        free(buf);
        return NULL;
      }
      *n = c;
      return buf;
    }
  return NULL;
}

/* u saved to path (with_optimizer: its Adam state too) and loaded back; NULL when either fails. */
static spx_unet *save_and_load(spx_ctx *ctx, spx_unet *u, const char *path, int with_optimizer) {
  spx_unet *r = NULL;
  CHECK_OK(ctx, spx_unet_save(u, path, with_optimizer));
  CHECK_OK(ctx, spx_unet_load(ctx, path, &r));
  return r;
}

static void test_golden(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  int wdw = 0; /* a weight gradient on Winograd: the levels have 8 << i channels at (GH x GW) >> i */
  for (int i = 0; i < 4; i++) wdw |= spx_conv2d_winograd_dw_applies(ctx, 3, 1, 1, 8 << i, 8 << i, GH >> i, GW >> i);
  if (spx_conv2d_winograd_applies(ctx, 3, 1, 1, 64, 64, 1 << 30, 0) || wdw) { /* see the top of the file */
    g_tol = TOL * SPX_WINO_RMS_GAIN;
    g_spread_factor = SPREAD_FACTOR * SPX_WINO_RMS_GAIN;
    printf("Winograd in training: tolerances x %d\n", SPX_WINO_RMS_GAIN);
  }
  CHECK_OK(ctx, spx_st_load(ctx, GOLDEN, &G));
  spx_unet *u = NULL;
  CHECK_OK(ctx, spx_unet_load(ctx, GOLDEN, &u)); /* the PyTorch-written checkpoint */
  float *in = spx_t_st_floats(&G, "golden.input", NULL), *tg = spx_t_st_floats(&G, "golden.target", NULL);
  float *gout = spx_t_st_floats(&G, "golden.output", NULL), *gloss = spx_t_st_floats(&G, "golden.loss", NULL);
  float *glosses = spx_t_st_floats(&G, "golden.losses", NULL), *geval = spx_t_st_floats(&G, "golden.eval_output", NULL);
  size_t nout = (size_t)GN * 3 * GH * GW;
  float *out = malloc(nout * sizeof(float));
  if (!u || !in || !tg || !gout || !gloss || !glosses || !geval) goto done;
  CHECK(spx_unet_width(u) == 8);
  CHECK(spx_unet_step(u) == 0);

  float loss = 0;
  CHECK_OK(ctx, spx_unet_zero_grad(u));
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, GN, GH, GW, out, &loss));
  note(0, "train output", rel_err(out, gout, nout));
  note(1, "loss", fabs(loss - gloss[0]) / gloss[0]);
  note(3, "loss 1", fabs(loss - glosses[0]) / glosses[0]);
  CHECK_OK(ctx, spx_unet_backward(u));
  int nparams = 0;
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    const char *name = spx_unet_tensor_name(u, i, NULL, NULL);
    if (strstr(name, "running_")) continue;
    size_t n;
    float *g = read_all(ctx, u, name, SPX_UNET_GRAD, &n);
    CHECK(g != NULL);
    if (g) compare_sampled(2, "golden.grad.", "golden.gradsum.", name, g, n);
    free(g);
    nparams++;
  }
  CHECK(nparams == 9 * 2 * 3 + 2); /* conv, gamma, beta per bn + outc weight, bias */
  /* three Adam steps, each on a fresh forward/backward (like the script) */
  CHECK_OK(ctx, spx_unet_adam_step_ex(u, 1e-3, 0.9, 0.999, ADAM_EPS));
  for (int s = 1; s < 3; s++) {
    CHECK_OK(ctx, spx_unet_zero_grad(u));
    CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, GN, GH, GW, NULL, &loss));
    note(3, "loss of step", fabs(loss - glosses[s]) / glosses[s]);
    CHECK_OK(ctx, spx_unet_backward(u));
    CHECK_OK(ctx, spx_unet_adam_step_ex(u, 1e-3, 0.9, 0.999, ADAM_EPS));
  }
  CHECK(spx_unet_step(u) == 3);
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    const char *name = spx_unet_tensor_name(u, i, NULL, NULL);
    size_t n;
    float *v = read_all(ctx, u, name, SPX_UNET_VALUE, &n);
    CHECK(v != NULL);
    if (v) compare_sampled(strstr(name, "running_") ? 5 : 4, "golden.after.", "golden.aftersum.", name, v, n);
    free(v);
  }
  CHECK_OK(ctx, spx_unet_forward(u, in, GN, GH, GW, 0, out));
  double ee = rel_err(out, geval, nout);
  note_tol(6, "eval output", ee, spread_tol(6, "eval_output", ee));

  /* checkpoint round trip, then the PyTorch --check files */
  char ck[512], io[512], cmd[2048];
  spx_t_path(ck, sizeof ck, "ours_ckpt.safetensors");
  spx_t_path(io, sizeof io, "ours_io.safetensors");
  spx_unet *r = save_and_load(ctx, u, ck, 1);
  if (r) {
    CHECK(spx_unet_step(r) == 3 && spx_unet_width(r) == 8);
    int same = 1;
    for (int i = 0; i < spx_unet_tensor_count(u); i++) {
      const char *name = spx_unet_tensor_name(u, i, NULL, NULL);
      for (int f = 0; f < 4; f++) {
        if (f && strstr(name, "running_")) continue;
        if (f == SPX_UNET_GRAD) continue;
        size_t na, nb;
        float *a = read_all(ctx, u, name, (spx_unet_field)f, &na), *b = read_all(ctx, r, name, (spx_unet_field)f, &nb);
        same &= a && b && na == nb && !memcmp(a, b, na * sizeof(float));
        free(a), free(b);
      }
    }
    CHECK_MSG(same, "checkpoint round trip changed a tensor");
    float *out2 = malloc(nout * sizeof(float));
    CHECK_OK(ctx, spx_unet_forward(r, in, GN, GH, GW, 0, out2));
    CHECK(!memcmp(out, out2, nout * sizeof(float)));
    /* resume: one more step on both gives identical weights */
    float l1 = 0, l2 = 0;
    CHECK_OK(ctx, spx_unet_zero_grad(u));
    CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, GN, GH, GW, NULL, &l1));
    CHECK_OK(ctx, spx_unet_backward(u));
    CHECK_OK(ctx, spx_unet_adam_step_ex(u, 1e-3, 0.9, 0.999, ADAM_EPS));
    CHECK_OK(ctx, spx_unet_zero_grad(r));
    CHECK_OK(ctx, spx_unet_forward_loss(r, in, tg, GN, GH, GW, NULL, &l2));
    CHECK_OK(ctx, spx_unet_backward(r));
    CHECK_OK(ctx, spx_unet_adam_step_ex(r, 1e-3, 0.9, 0.999, ADAM_EPS));
    CHECK(l1 == l2);
    size_t na, nb;
    float *a = read_all(ctx, u, "up3.conv.double_conv.0.weight", SPX_UNET_VALUE, &na);
    float *b = read_all(ctx, r, "up3.conv.double_conv.0.weight", SPX_UNET_VALUE, &nb);
    CHECK(a && b && na == nb && !memcmp(a, b, na * sizeof(float)));
    free(a), free(b), free(out2);
    spx_unet_destroy(r);
  }
  /* PyTorch check files: our checkpoint now (after 4 steps) + our eval output of it */
  CHECK_OK(ctx, spx_unet_save(u, ck, 1));
  CHECK_OK(ctx, spx_unet_forward(u, in, GN, GH, GW, 0, out));
  spx_st_entry es[2] = {{"input", SPX_F32, 4, {GN, 4, GH, GW}, in}, {"eval_output", SPX_F32, 4, {GN, 3, GH, GW}, out}};
  CHECK_OK(ctx, spx_st_save(ctx, io, es, 2, NULL, NULL, 0));
  snprintf(cmd, sizeof cmd, "/usr/bin/python3 %s/unet/make_unet_golden.py --check %s %s", SPX_TEST_DATA, ck, io);
  if (spx_t_system("/usr/bin/python3 -c 'import torch' >/dev/null 2>&1") == 0) {
    CHECK_MSG(spx_t_system(cmd) == 0, "PyTorch rejected our checkpoint: %s", cmd);
  } else {
    fprintf(stderr, "  (no PyTorch here: run `%s` to check the checkpoint loads in PyTorch)\n", cmd);
  }
done:
  free(in), free(tg), free(gout), free(gloss), free(glosses), free(geval), free(out);
  spx_unet_destroy(u);
  spx_st_free(&G);
  spx_ctx_destroy(ctx);
}

/* Errors name the tensor and the expected shape; an interrupted save keeps the old file. */
static void test_checkpoint_errors(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  spx_unet *u = NULL;
  CHECK_OK(ctx, spx_unet_create(ctx, 16, 1, 42, &u));
  CHECK(spx_unet_create(ctx, 12, 0, 1, &(spx_unet *){NULL}) == SPX_E_ARG);
  if (!u) {
    spx_ctx_destroy(ctx);
    return;
  }
  char ck[512], bad[512];
  spx_t_path(ck, sizeof ck, "w16.safetensors");
  spx_t_path(bad, sizeof bad, "bad.safetensors");
  spx_unet *r = save_and_load(ctx, u, ck, 0);
  if (r) {
    CHECK(spx_unet_width(r) == 16 && spx_unet_sigmoid(r) == 1 && spx_unet_step(r) == 0);
    spx_unet_destroy(r);
    r = NULL;
  }
  /* rewrite the file without one tensor, and with one tensor of the wrong shape */
  spx_st_file f;
  CHECK_OK(ctx, spx_st_load(ctx, ck, &f));
  spx_st_entry *es = calloc((size_t)f.count, sizeof *es);
  for (int pass = 0; pass < 2; pass++) {
    int ne = 0;
    for (int i = 0; i < f.count; i++) {
      const spx_st_tensor *t = &f.tensors[i];
      int victim = !strcmp(t->name, "up2.conv.double_conv.3.weight");
      if (victim && pass == 0) continue;
      es[ne].name = t->name;
      es[ne].dtype = t->dtype;
      es[ne].ndim = t->ndim;
      memcpy(es[ne].shape, t->shape, sizeof t->shape);
      es[ne].data = t->data;
      if (victim) { /* [32, 64, 3, 3] -> [64, 32, 3, 3], same bytes */
        es[ne].shape[0] = 64;
        es[ne].shape[1] = 32;
      }
      ne++;
    }
    CHECK_OK(ctx, spx_st_save(ctx, bad, es, ne, NULL, NULL, 0));
    CHECK(spx_unet_load(ctx, bad, &r) == SPX_E_FORMAT && r == NULL);
    const char *msg = spx_ctx_message(ctx);
    CHECK_MSG(strstr(msg, "up2.conv.double_conv.3.weight") && strstr(msg, "[32, 64, 3, 3]") && strstr(msg, bad),
              "message: %s", msg);
    if (pass == 0) CHECK(strstr(msg, "missing") != NULL);
    else CHECK(strstr(msg, "[64, 32, 3, 3]") != NULL);
  }
  free(es);
  spx_st_free(&f);
  /* a tiny file claiming width 1024 is refused before anything that size is allocated */
  {
    static float w0[1024 * 4 * 9];
    spx_st_entry one = {"inc.double_conv.0.weight", SPX_F32, 4, {1024, 4, 3, 3}, w0};
    CHECK_OK(ctx, spx_st_save(ctx, bad, &one, 1, NULL, NULL, 0));
    CHECK(spx_unet_load(ctx, bad, &r) == SPX_E_FORMAT && r == NULL);
    CHECK_MSG(strstr(spx_ctx_message(ctx), "up1.conv.double_conv.0.weight (expected shape [8192, 16384, 3, 3])"),
              "message: %s", spx_ctx_message(ctx));
  }
  /* a save to a directory that does not exist fails and leaves nothing behind; the old file stays */
  CHECK(spx_unet_save(u, "/nonexistent-dir/x.safetensors", 1) != SPX_OK);
  CHECK_OK(ctx, spx_unet_load(ctx, ck, &r));
  spx_unet_destroy(r);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_golden);
  SPX_RUN(test_checkpoint_errors);
  fprintf(stderr, "max relative errors vs PyTorch:\n");
  for (int k = 0; k < 8; k++) fprintf(stderr, "  %-24s %.3g\n", g_kind[k], g_worst[k]);
  fprintf(stderr, "  after Adam: max (our error / PyTorch float32-vs-float64 spread) = %.3g\n", g_spread_ratio);
  return spx_test_summary();
}
