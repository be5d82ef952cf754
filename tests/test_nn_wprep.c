/* Prepared weights kept between inference passes (CONV_WPREP; lib/nn/tape.c, spx_conv2d_wprep in
 * lib/nn/conv2d.h): an eval pass that reuses them gives the same bits as one that prepares its
 * weights again (CONV_WPREP = 0), and every way the weights change (Adam step, spx_unet_write,
 * a checkpoint-style write of all tensors) is seen by the next pass, on the direct path and with
 * every 3x3 layer on Winograd; so is a change of the register tile the panels were packed for. */
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"
#include "nn/tape.h"
#include "nn/unet.h"
#include "nn_testutil.h"
#include "smplpix/smplpix.h"
#include "smplpix/unet.h"

enum { WD = 8, H = 34, W = 46 };

static int tunable(spx_ctx *ctx, const char *name) {
  for (int i = 0; i < SPX_NTUNABLES; i++) {
    spx_tunable_info t;
    if (spx_device_tunable(ctx, i, &t) == SPX_OK && !strcmp(t.name, name)) return t.value;
  }
  CHECK_MSG(0, "no tunable %s", name);
  return -1;
}

/* One eval forward with CONV_WPREP = on; 'out' gets the output. */
static void eval(spx_ctx *ctx, spx_unet *u, const float *in, int on, float *out) {
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WPREP", on));
  CHECK_OK(ctx, spx_unet_forward(u, in, 1, H, W, 0, out));
}

/* The cached pass (a) against a fresh preparation (b) of the same weights: same bits. */
static void same(spx_ctx *ctx, spx_unet *u, const float *in, float *a, float *b, size_t n, const char *what) {
  eval(ctx, u, in, 1, a);
  eval(ctx, u, in, 0, b);
  CHECK_MSG(!memcmp(a, b, n * sizeof(float)), "%s: the pass with kept weights differs from a fresh one", what);
}

static void run(spx_ctx *ctx, int wino) {
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WINO_MINC", wino ? 1 : 0));
  size_t nin = (size_t)4 * H * W, nout = (size_t)3 * H * W;
  float *in = malloc(nin * sizeof(float)), *tg = malloc(nout * sizeof(float));
  float *a = malloc(nout * sizeof(float)), *b = malloc(nout * sizeof(float)), *first = malloc(nout * sizeof(float));
  spx_unet *u = NULL;
  CHECK(in && tg && a && b && first);
  if (!in || !tg || !a || !b || !first) goto done;
  unsigned long long s = 11;
  spx_nt_rand(in, nin, 0.0f, 1.0f, &s);
  spx_nt_rand(tg, nout, 0.0f, 1.0f, &s);
  CHECK_OK(ctx, spx_unet_create(ctx, WD, 0, 3, &u));
  if (!u) goto done;
  spx_tape *t = spx_unet_tape(u);
  /* the GPU class's fused Winograd transforms its weights inside: nothing is kept then */
  const int keeps = !(wino && tunable(ctx, "CONV_WINO_LDS"));
  eval(ctx, u, in, 1, first); /* prepares and keeps */
  CHECK(keeps == (spx_tape_wprep_bytes(t) > 0));
  same(ctx, u, in, a, b, nout, "second pass");
  CHECK(!memcmp(a, first, nout * sizeof(float)));

  /* an Adam step changes every weight */
  float loss;
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, 1, H, W, NULL, &loss));
  CHECK_OK(ctx, spx_unet_backward(u));
  CHECK_OK(ctx, spx_unet_adam_step(u, 1e-2));
  CHECK(spx_tape_wprep_bytes(t) == 0);
  same(ctx, u, in, a, b, nout, "after an Adam step");
  CHECK_MSG(memcmp(a, first, nout * sizeof(float)), "the Adam step did not change the output");

  /* one convolution's weights rewritten through the public API */
  memcpy(first, a, nout * sizeof(float));
  eval(ctx, u, in, 1, a); /* kept again */
  CHECK(keeps == (spx_tape_wprep_bytes(t) > 0));
  int changed = 0;
  for (int i = 0; i < spx_unet_tensor_count(u) && !changed; i++) {
    int nd;
    int64_t sh[4];
    const char *name = spx_unet_tensor_name(u, i, &nd, sh);
    if (!name || nd != 4 || sh[2] != 3) continue;
    size_t n = (size_t)(sh[0] * sh[1] * sh[2] * sh[3]);
    float *wv = malloc(n * sizeof(float));
    if (!wv) break;
    CHECK_OK(ctx, spx_unet_read(u, name, SPX_UNET_VALUE, wv, n));
    for (size_t j = 0; j < n; j++) wv[j] = -1.5f * wv[j];
    CHECK_OK(ctx, spx_unet_write(u, name, wv, n));
    free(wv);
    changed = 1;
  }
  CHECK(changed && spx_tape_wprep_bytes(t) == 0);
  same(ctx, u, in, a, b, nout, "after spx_unet_write");
  CHECK_MSG(memcmp(a, first, nout * sizeof(float)), "rewriting a convolution's weights did not change the output");

  /* a register tile changed between passes (as `smplpix tune` does on a live network): the panels
   * kept for the old tile are not reused. Same bits as a fresh preparation under the new tile,
   * and (same summation order) as before the change. */
  if (!wino) {
    const int tm = tunable(ctx, "CONV_TM"), ntm = tunable(ctx, "CONV_NARROW_TM");
    memcpy(first, a, nout * sizeof(float));
    eval(ctx, u, in, 1, a); /* kept under the opened tiles */
    CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_TM", tm == 8 ? 4 : 8));
    CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_NARROW_TM", ntm == 8 ? 4 : 8));
    same(ctx, u, in, a, b, nout, "after a register-tile change");
    CHECK_MSG(!memcmp(a, first, nout * sizeof(float)), "a register-tile change changed the output");
    CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_TM", tm));
    CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_NARROW_TM", ntm));
  }
done:
  spx_unet_destroy(u);
  free(in), free(tg), free(a), free(b), free(first);
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WPREP", 1));
}

static spx_ctx *g_ctx;
static void test_direct(void) { run(g_ctx, 0); }
static void test_winograd(void) { run(g_ctx, 1); }

int main(void) {
  static const spx_t_test dev[] = {SPX_TEST(test_direct), SPX_TEST(test_winograd)};
  return spx_nt_main(&g_ctx, NULL, 0, dev, 2);
}
