/* spx_unet_device_bytes (the device-memory figure of benchmarks/bench_unet): on a width-8 UNet,
 *  - right after creation it is exactly the parameter slab (4 bytes per parameter) + the state
 *    slab (running mean / variance and the folded batch-norm scale / shift: 16 bytes per channel
 *    of every batch norm, i.e. 2x the running statistics); the gradient and Adam m / v slabs
 *    (12 bytes per parameter) appear with the first training use, never for inference;
 *  - the arena (activations, gradients and every conv's workspace) is exactly the largest plan
 *    so far (spx_tape_plan_bytes; an eval plan may be the larger one: inference forwards take
 *    Winograd, whose weight transforms dominate at this size); a training step adds the gradient
 *    and Adam slabs; a larger batch's plan is larger;
 *  - repeating a pass of an already planned shape adds nothing (grow-only, steady state);
 *  - the host backend holds no device memory (0).
 * and the context's device-memory counter (spx_device_live_bytes / spx_device_peak_bytes):
 *  - creating the UNet adds exactly its slabs to the live bytes, destroying it takes them off;
 *  - after a pass the live bytes are the network's buffers (per-call scratch is gone), the peak is
 *    at least that, and a reset brings the peak down to the live bytes;
 *  - a training step allocates nothing but the slabs and the planned arena (every op's scratch
 *    lies in it): over a fresh network's first step the peak is exactly the live bytes after it. */
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "nn/conv2d.h"
#include "nn/unet.h"
#include "nn_testutil.h"
#include "smplpix/smplpix.h"
#include "smplpix/unet.h"

enum { WD = 8, H = 32, W = 48 };

/* OpenCL may delete a released buffer only once the queued commands using it are done (PoCL does
 * it on its own thread), so the live count settles shortly after a finish: wait up to 5 s. */
static size_t settled_live(spx_ctx *ctx, size_t want) {
  spx_device_finish(ctx);
  for (int i = 0; i < 500 && spx_device_live_bytes(ctx) != want; i++) {
    struct timespec ts = {0, 10000000};
    nanosleep(&ts, NULL);
  }
  return spx_device_live_bytes(ctx);
}

/* Floats of the UNet's parameters and of its running statistics. */
static void count_tensors(spx_unet *u, size_t *params, size_t *stats) {
  *params = *stats = 0;
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    int nd;
    int64_t sh[4];
    const char *name = spx_unet_tensor_name(u, i, &nd, sh);
    if (strncmp(name, "optimizer.", 10) == 0) continue;
    size_t n = 1;
    for (int d = 0; d < nd; d++) n *= (size_t)sh[d];
    size_t len = strlen(name);
    if ((len > 13 && !strcmp(name + len - 13, ".running_mean")) || (len > 12 && !strcmp(name + len - 12, ".running_var")))
      *stats += n;
    else
      *params += n;
  }
}

static void test_device_bytes(void) {
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
  if (!ctx) return;
  spx_unet *u = NULL, *hu = NULL;
  size_t nin = (size_t)2 * 4 * H * W, nout = (size_t)2 * 3 * H * W;
  float *in = malloc(nin * sizeof(float)), *tg = malloc(nout * sizeof(float)), *out = malloc(nout * sizeof(float));
  CHECK(in && tg && out);
  if (!in || !tg || !out) goto done;
  unsigned long long s = 7;
  spx_nt_rand(in, nin, 0.0f, 1.0f, &s);
  spx_nt_rand(tg, nout, 0.0f, 1.0f, &s);
  /* the op scratch inside the arena (the CPU default; the GPU-class variant of this test too) */
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "TAPE_WS_ARENA", 1));
  size_t live0 = spx_device_live_bytes(ctx);
  CHECK_OK(ctx, spx_unet_create(ctx, WD, 0, 1, &u));
  if (!u) goto done;
  CHECK_MSG(spx_device_live_bytes(ctx) == live0 + spx_unet_device_bytes(u), "live %zu after create, %zu + %zu",
            spx_device_live_bytes(ctx), live0, spx_unet_device_bytes(u));
  size_t params = 0, stats = 0;
  count_tensors(u, &params, &stats);
  CHECK(params > 0 && stats > 0);
  size_t b0 = spx_unet_device_bytes(u);
  CHECK_MSG(b0 == 4 * params + 8 * stats, "after create: %zu bytes, expected %zu", b0, 4 * params + 8 * stats);

  spx_tape *t = spx_unet_tape(u);
  CHECK_OK(ctx, spx_unet_forward(u, in, 1, H, W, 0, out));
  /* an eval pass keeps its convolutions' prepared weights (CONV_WPREP, on in both classes) */
  size_t b1 = spx_unet_device_bytes(u), pe = spx_tape_plan_bytes(t, NULL), wp = spx_tape_wprep_bytes(t);
  CHECK_MSG(pe >= (size_t)(4 + 3) * H * W * sizeof(float) && wp > 0 && b1 == b0 + pe + wp,
            "eval: %zu -> %zu bytes, plan %zu, prepared weights %zu", b0, b1, pe, wp);
  CHECK_OK(ctx, spx_unet_forward(u, in, 1, H, W, 0, out));
  CHECK(spx_unet_device_bytes(u) == b1 && spx_tape_wprep_bytes(t) == wp);

  float loss;
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, 1, H, W, NULL, &loss));
  CHECK_OK(ctx, spx_unet_backward(u));
  size_t b2 = spx_unet_device_bytes(u), pt1 = spx_tape_plan_bytes(t, NULL);
  size_t arena = pt1 > pe ? pt1 : pe;
  CHECK_MSG(b2 == b0 + 12 * params + arena + wp, "train b1: %zu -> %zu bytes, plan %zu", b1, b2, pt1);
  CHECK_OK(ctx, spx_unet_adam_step(u, 1e-3)); /* new weights: the prepared ones are released */
  CHECK(spx_tape_wprep_bytes(t) == 0);
  b2 -= wp;
  CHECK_OK(ctx, spx_unet_zero_grad(u));
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, 1, H, W, NULL, &loss));
  CHECK_OK(ctx, spx_unet_backward(u));
  CHECK(spx_unet_device_bytes(u) == b2);

  settled_live(ctx, live0 + b2); /* nothing of the finished passes pending: live = peak after the reset */
  spx_device_reset_peak(ctx);
  CHECK(spx_device_peak_bytes(ctx) == spx_device_live_bytes(ctx));
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, 2, H, W, NULL, &loss));
  CHECK_OK(ctx, spx_unet_backward(u));
  size_t b3 = spx_unet_device_bytes(u), pt2 = spx_tape_plan_bytes(t, NULL);
  arena = pt2 > arena ? pt2 : arena;
  CHECK_MSG(pt2 > pt1 && b3 == b0 + 12 * params + arena, "train b2: %zu -> %zu bytes, plan %zu", b2, b3, pt2);
  size_t live = settled_live(ctx, live0 + b3), peak = spx_device_peak_bytes(ctx);
  CHECK_MSG(live == live0 + b3, "live %zu after a step, network %zu + %zu before", live, b3, live0);
  CHECK_MSG(peak >= live && peak >= live0 + b2, "peak %zu, live %zu", peak, live);
  spx_device_reset_peak(ctx);
  CHECK(spx_device_peak_bytes(ctx) == live);

  CHECK_OK(ctx, spx_unet_create_ex(ctx, WD, 0, 1, SPX_TAPE_HOST, &hu));
  CHECK(hu && spx_unet_device_bytes(hu) == 0);
  CHECK(spx_unet_device_bytes(NULL) == 0);
  spx_unet_destroy(u);
  u = NULL;
  size_t after = settled_live(ctx, live0);
  CHECK_MSG(after == live0, "live %zu after destroy, %zu before", after, live0);
done:
  spx_unet_destroy(hu);
  spx_unet_destroy(u);
  free(in), free(tg), free(out);
  spx_ctx_destroy(ctx);
}

/* One training step (zero grad, forward + L1, backward, Adam) at batch n, finished. */
static void train_step(spx_ctx *ctx, spx_unet *u, const float *in, const float *tg, int n) {
  float loss;
  CHECK_OK(ctx, spx_unet_zero_grad(u));
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, n, H, W, NULL, &loss));
  CHECK_OK(ctx, spx_unet_backward(u));
  CHECK_OK(ctx, spx_unet_adam_step(u, 1e-3));
  CHECK_OK(ctx, spx_device_finish(ctx));
}

/* A fresh width-8 UNet's first training step at batch 2 with Winograd in training (every 3x3
 * layer of 8+ channels, one sample per pass: CONV_WINO_CHUNK 0), then a second step: the peak
 * over each equals the live bytes after it, which are the network's slabs + the plan's arena
 * (no scratch allocated or grown during a pass, no buffer replaced while its old copy lives).
 * in_arena 1: the op scratch lies inside the arena (TAPE_WS_ARENA 1, CPU default); 0: it is one
 * separate buffer sized by the plan (the GPU default), so the bytes are larger than slabs +
 * arena but still reached before the pass, never grown during it. */
static void peak_is_plan(int in_arena) {
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
  if (!ctx) return;
  spx_unet *u = NULL;
  size_t nin = (size_t)2 * 4 * H * W, nout = (size_t)2 * 3 * H * W;
  float *in = malloc(nin * sizeof(float)), *tg = malloc(nout * sizeof(float));
  CHECK(in && tg);
  if (!in || !tg) goto done;
  unsigned long long s = 5;
  spx_nt_rand(in, nin, 0.0f, 1.0f, &s);
  spx_nt_rand(tg, nout, 0.0f, 1.0f, &s);
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "TAPE_WS_ARENA", in_arena));
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WINO_TRAIN", 1));
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WINO_MINC", WD));
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WINO_CHUNK", 0));
  CHECK(spx_conv2d_winograd_applies(ctx, 3, 1, 1, WD, WD, 0));
  size_t live0 = settled_live(ctx, spx_device_live_bytes(ctx));
  CHECK_OK(ctx, spx_unet_create(ctx, WD, 0, 1, &u));
  if (!u) goto done;
  size_t params, stats;
  count_tensors(u, &params, &stats);
  spx_device_reset_peak(ctx);
  for (int step = 0; step < 2; step++) {
    train_step(ctx, u, in, tg, 2);
    size_t bytes = spx_unet_device_bytes(u), live = settled_live(ctx, live0 + bytes);
    size_t peak = spx_device_peak_bytes(ctx), plan = spx_tape_plan_bytes(spx_unet_tape(u), NULL);
    CHECK_MSG(live == live0 + bytes && peak == live, "step %d: peak %zu, live %zu (network %zu + %zu before)", step,
              peak, live, bytes, live0);
    size_t slabs = 16 * params + 8 * stats;
    CHECK_MSG(plan > 0 && (in_arena ? bytes == slabs + plan : bytes > slabs + plan), "arena %d step %d: %zu bytes, plan %zu",
              in_arena, step, bytes, plan);
    spx_device_reset_peak(ctx);
  }
done:
  spx_unet_destroy(u);
  free(in), free(tg);
  spx_ctx_destroy(ctx);
}

static void test_peak_is_plan(void) {
  peak_is_plan(1);
  peak_is_plan(0);
}

int main(void) {
  SPX_RUN(test_device_bytes);
  SPX_RUN(test_peak_is_plan);
  return spx_test_summary();
}
