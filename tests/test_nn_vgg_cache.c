/* The frozen VGG's target-feature cache (spx_vgg_set_target_cache, lib/nn/vgg_cache.c): training
 * with it changes no bit. Two equal small UNets take the same perceptual steps (spx_unet_vgg_step)
 * on a fixed set of four targets, one VGG with the cache and one without, on both backends and
 * both losses (VGG19 eq. 5 and VGG16, 1/16 width): every step's losses are equal bit for bit, and
 * so are the networks' outputs afterwards. The batches come back in other orders and pairings
 * (the cached features are restored at other batch positions); the cache holds each target once
 * (spx_vgg_target_bytes each) and its passes restore features (one more plan than without: the
 * restoring pass); a batch of another size computes its own features; a budget of one target
 * keeps one; budget 0 drops all, and the cached run still equals the uncached one. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nn/tape.h"
#include "nn/unet.h"
#include "nn/vgg.h"
#include "nn_testutil.h"

#define DIR SPX_TEST_DATA "/vgg/"
enum { H = 37, W = 29, NT = 4 };

static const char *const wfile[2] = {DIR "vgg_w4.safetensors", DIR "vgg16_w4.safetensors"};

/* batches of the targets (index lists, -1 ends a batch of one) */
static const int order[][2] = {{0, 1}, {2, 3}, {1, 0}, {3, 2}, {0, 2}, {3, -1}, {1, 3}, {2, 0}};

static void gather(const float *src, size_t per, const int *idx, int n, float *dst) {
  for (int i = 0; i < n; i++) memcpy(dst + (size_t)i * per, src + (size_t)idx[i] * per, per * sizeof(float));
}

static int same(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

static void run(spx_ctx *ctx, spx_vgg_kind kind, spx_tape_backend be) {
  size_t hw = (size_t)H * W, pin = 4 * hw, pout = 3 * hw;
  float *in = malloc(NT * pin * sizeof(float)), *tg = malloc(NT * pout * sizeof(float));
  float *bin = malloc(2 * pin * sizeof(float)), *btg = malloc(2 * pout * sizeof(float));
  float *o0 = malloc(pout * sizeof(float)), *o1 = malloc(pout * sizeof(float));
  spx_unet *g[2] = {NULL, NULL};
  spx_vgg *v[2] = {NULL, NULL};
  unsigned long long s = 5 + (unsigned long long)kind;
  for (size_t i = 0; i < NT * pin; i++) in[i] = (float)spx_t_uniform(&s);
  for (size_t i = 0; i < NT * pout; i++) tg[i] = (float)spx_t_uniform(&s);
  for (int k = 0; k < 2; k++) {
    CHECK_OK(ctx, spx_unet_create_ex(ctx, 4, 0, 3, be, &g[k]));
    CHECK_OK(ctx, spx_vgg_open_ex(ctx, wfile[kind], kind, be, &v[k]));
  }
  if (!g[0] || !g[1] || !v[0] || !v[1]) goto done;
  size_t one = spx_vgg_target_bytes(v[1], H, W);
  CHECK_OK(ctx, spx_vgg_set_target_cache(v[1], 64 * one));
  int equal = 1, nsteps = (int)(sizeof order / sizeof order[0]);
  for (int step = 0; step < nsteps; step++) {
    int n = order[step][1] < 0 ? 1 : 2;
    gather(in, pin, order[step], n, bin), gather(tg, pout, order[step], n, btg);
    spx_gan_losses l[2];
    for (int k = 0; k < 2; k++) CHECK_OK(ctx, spx_unet_vgg_step(g[k], v[k], bin, btg, n, H, W, 1e-3, &l[k]));
    equal &= same(l[0].vgg, l[1].vgg) && same(l[0].rec, l[1].rec);
    if (step == 1) CHECK(spx_vgg_target_cache_bytes(v[1]) == NT * one);
  }
  CHECK_MSG(equal, "a step's loss differs with the cache");
  /* the four targets at batch size 2, target 3 at batch size 1 */
  CHECK(spx_vgg_target_cache_bytes(v[1]) == (NT + 1) * one);
  int p0 = spx_tape_plan_count(spx_vgg_tape(v[0])), p1 = spx_tape_plan_count(spx_vgg_tape(v[1]));
  CHECK_MSG(p1 == p0 + 1, "plans %d with the cache, %d without: no restoring pass ran", p1, p0);
  CHECK_OK(ctx, spx_unet_forward(g[0], in, 1, H, W, 0, o0));
  CHECK_OK(ctx, spx_unet_forward(g[1], in, 1, H, W, 0, o1));
  CHECK_MSG(!memcmp(o0, o1, pout * sizeof(float)), "the networks differ after training with and without the cache");
  /* a smaller budget drops every entry and then keeps what fits: one target */
  CHECK_OK(ctx, spx_vgg_set_target_cache(v[1], one + one / 2));
  CHECK(spx_vgg_target_cache_bytes(v[1]) == 0);
  for (int step = 0; step < 2; step++) {
    gather(in, pin, order[step], 2, bin), gather(tg, pout, order[step], 2, btg);
    spx_gan_losses l[2];
    for (int k = 0; k < 2; k++) CHECK_OK(ctx, spx_unet_vgg_step(g[k], v[k], bin, btg, 2, H, W, 1e-3, &l[k]));
    CHECK(same(l[0].vgg, l[1].vgg));
  }
  CHECK(spx_vgg_target_cache_bytes(v[1]) == one);
  CHECK_OK(ctx, spx_vgg_set_target_cache(v[1], 0));
  CHECK(spx_vgg_target_cache_bytes(v[1]) == 0);
  printf("  %s, %s backend: %d steps equal bit for bit; %zu bytes a target\n", kind ? "VGG16" : "VGG19",
         be == SPX_TAPE_HOST ? "host" : "device", nsteps, one);
done:
  for (int k = 0; k < 2; k++) spx_unet_destroy(g[k]), spx_vgg_destroy(v[k]);
  free(in), free(tg), free(bin), free(btg), free(o0), free(o1);
}

static void test_cache_exact(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  for (int kind = 0; kind < 2; kind++) {
    run(ctx, (spx_vgg_kind)kind, SPX_TAPE_DEVICE);
    run(ctx, (spx_vgg_kind)kind, SPX_TAPE_HOST);
  }
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_cache_exact);
  return spx_test_summary();
}
