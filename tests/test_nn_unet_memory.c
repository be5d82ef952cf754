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
 *    lies in it): over a fresh network's first step the peak is exactly the live bytes after it;
 *  - an arena split into chunks (TAPE_CHUNK_MB: buffers of at most that size, what a device whose
 *    largest allocation is below the plan gets) gives the same bits as one buffer, and a storage
 *    larger than a chunk is a one-line error. */
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

/* A batch-2 input and target of uniform values in [0, 1) from seed (malloc'd; 0 when either
 * allocation failed, the other freed). */
static int make_batch(unsigned long long seed, float **in, float **tg) {
  size_t nin = (size_t)2 * 4 * H * W, nout = (size_t)2 * 3 * H * W;
  *in = malloc(nin * sizeof(float)), *tg = malloc(nout * sizeof(float));
  CHECK(*in && *tg);
  if (!*in || !*tg) {
    free(*in), free(*tg);
    *in = *tg = NULL;
    return 0;
  }
  spx_nt_rand(*in, nin, 0.0f, 1.0f, &seed);
  spx_nt_rand(*tg, nout, 0.0f, 1.0f, &seed);
  return 1;
}

static void test_device_bytes(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  spx_unet *u = NULL, *hu = NULL;
  size_t nout = (size_t)2 * 3 * H * W;
  float *in = NULL, *tg = NULL, *out = malloc(nout * sizeof(float));
  CHECK(out != NULL);
  if (!make_batch(7, &in, &tg) || !out) goto done;
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
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  spx_unet *u = NULL;
  float *in = NULL, *tg = NULL;
  if (!make_batch(5, &in, &tg)) goto done;
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "TAPE_WS_ARENA", in_arena));
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WINO_TRAIN", 1));
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WINO_MINC", WD));
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WINO_CHUNK", 0));
  CHECK(spx_conv2d_winograd_applies(ctx, 3, 1, 1, WD, WD, 1 << 30, 0));
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

/* Eval output, loss and every parameter gradient of a batch-2 training step, one buffer of the
 * arena (chunk_mb 0) or chunks of chunk_mb MiB; *plan: the plan's bytes. Returns the floats
 * written to res (NULL on failure). */
static float *chunked_run(int chunk_mb, const float *in, const float *tg, size_t *nres, size_t *plan) {
  spx_ctx *ctx = spx_nt_open();
  spx_unet *u = NULL;
  float *res = NULL;
  size_t n = 0, cap = 0;
  CHECK(ctx != NULL);
  if (!ctx) return NULL;
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "TAPE_WS_ARENA", 1));
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "TAPE_CHUNK_MB", chunk_mb));
  CHECK_OK(ctx, spx_unet_create(ctx, WD, 0, 3, &u));
  if (!u) goto done;
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    int nd;
    int64_t sh[4];
    spx_unet_tensor_name(u, i, &nd, sh);
    size_t m = 1;
    for (int d = 0; d < nd; d++) m *= (size_t)sh[d];
    cap += m;
  }
  cap += (size_t)2 * 3 * H * W + 1;
  res = calloc(cap, sizeof(float));
  CHECK(res != NULL);
  if (!res) goto done;
  CHECK_OK(ctx, spx_unet_forward(u, in, 2, H, W, 0, res));
  n += (size_t)2 * 3 * H * W;
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, 2, H, W, NULL, &res[n++]));
  CHECK_OK(ctx, spx_unet_backward(u));
  *plan = spx_tape_plan_bytes(spx_unet_tape(u), NULL);
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    int nd;
    int64_t sh[4];
    const char *name = spx_unet_tensor_name(u, i, &nd, sh);
    size_t m = 1;
    for (int d = 0; d < nd; d++) m *= (size_t)sh[d];
    if (strncmp(name, "optimizer.", 10) == 0 || strstr(name, "running_")) continue;
    CHECK_OK(ctx, spx_unet_read(u, name, SPX_UNET_GRAD, res + n, m));
    n += m;
  }
done:
  *nres = n;
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
  return res;
}

/* Nonzero when a batch-2 training pass cannot run with chunks of mb MiB. */
static int chunk_fails(int mb, const float *in, const float *tg) {
  spx_ctx *ctx = spx_nt_open();
  spx_unet *u = NULL;
  float loss;
  int bad = !ctx || spx_device_set_tunable(ctx, "TAPE_WS_ARENA", 1) || spx_device_set_tunable(ctx, "TAPE_CHUNK_MB", mb) ||
            spx_unet_create(ctx, WD, 0, 3, &u) || spx_unet_forward_loss(u, in, tg, 2, H, W, NULL, &loss) ||
            spx_unet_backward(u);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
  return bad;
}

static void test_arena_chunks(void) {
  size_t nout = (size_t)2 * 3 * H * W, n1 = 0, n2 = 0, plan1 = 0, plan2 = 0;
  float *in = NULL, *tg = NULL;
  if (!make_batch(11, &in, &tg)) goto done;
  float *one = chunked_run(0, in, tg, &n1, &plan1), *split = NULL;
  /* the largest chunk below the plan that holds its largest storage (a conv's scratch: 3.7 of
   * 4.8 MiB in the CPU class), so that the plan needs at least two */
  int mb = (int)((plan1 - 1) >> 20);
  while (mb > 1 && chunk_fails(mb, in, tg)) mb--;
  CHECK_MSG(mb >= 1 && ((size_t)mb << 20) < plan1, "no chunk size splits a %zu-byte plan", plan1);
  split = chunked_run(mb, in, tg, &n2, &plan2);
  CHECK_MSG(plan2 >= plan1, "plans: %zu bytes in one buffer, %zu in %d MiB chunks", plan1, plan2, mb);
  CHECK(one && split && n1 == n2 && n1 > nout);
  if (one && split && n1 == n2) {
    size_t bad = 0;
    for (size_t i = 0; i < n1; i++) bad += memcmp(&one[i], &split[i], sizeof(float)) != 0;
    CHECK_MSG(bad == 0, "%zu of %zu floats differ between one arena buffer and %d MiB chunks", bad, n1, mb);
  }
  free(one), free(split);
  /* a 1 MiB chunk is smaller than a conv's scratch of this pass (Winograd's transformed weights of
   * the 128-channel layers, 2.4 MB, in either class): a clear error, no pass */
  spx_ctx *ctx = spx_nt_open();
  spx_unet *u = NULL;
  CHECK(ctx != NULL);
  if (ctx) {
    CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_WINO_MINC", 64));
    CHECK_OK(ctx, spx_device_set_tunable(ctx, "TAPE_WS_ARENA", 1));
    CHECK_OK(ctx, spx_device_set_tunable(ctx, "TAPE_CHUNK_MB", 1));
    CHECK_OK(ctx, spx_unet_create(ctx, WD, 0, 3, &u));
    float *out = malloc(nout * sizeof(float));
    spx_status st = u && out ? spx_unet_forward(u, in, 2, H, W, 0, out) : SPX_E_NOMEM;
    const char *msg = spx_ctx_message(ctx);
    CHECK_MSG(st == SPX_E_DEVMEM && strstr(msg, "more than an arena buffer may hold"), "status %d: %s", (int)st, msg);
    free(out);
    spx_unet_destroy(u);
    spx_ctx_destroy(ctx);
  }
done:
  free(in), free(tg);
}

int main(void) {
  SPX_RUN(test_device_bytes);
  SPX_RUN(test_arena_chunks);
  SPX_RUN(test_peak_is_plan);
  return spx_test_summary();
}
