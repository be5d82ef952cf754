/* Liveness planning of the tape's arena (lib/nn/tape_plan.c), on both backends:
 *  - exact arena sizes of two hand-planned tiny graphs (an eval chain and a training graph);
 *  - a UNet training step plans far less than the sum of its activations and gradients;
 *  - reuse changes no float: a UNet training step (loss, output, every parameter gradient) and an
 *    eval forward are bit-identical with reuse + NaN poisoning of every dead storage and without
 *    reuse (a premature free would put NaNs or another value's data into the results);
 *  - a batch-1 device eval forward puts each up block's skip inside its concatenation (no copy)
 *    and gives the same bits as without reuse;
 *  - reading a value after its last use, or a second backward without retain, is refused. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nn/loss.h"
#include "nn/tape.h"
#include "nn/tape_internal.h"
#include "nn/unet.h"
#include "nn_testutil.h"
#include "smplpix/smplpix.h"
#include "smplpix/unet.h"

static size_t elem(spx_tape_backend be) { return be == SPX_TAPE_HOST ? sizeof(double) : sizeof(float); }

/* The device's op scratch is planned inside the arena in every class (TAPE_WS_ARENA 1: the
 * layouts checked here count it there; the separate-buffer mode is in test_nn_unet_memory.c). */
static spx_ctx *open_ctx(spx_tape_backend be) {
  if (be == SPX_TAPE_DEVICE) {
    spx_ctx *dctx = spx_nt_open();
    if (dctx && spx_device_set_tunable(dctx, "TAPE_WS_ARENA", 1) != SPX_OK) {
      spx_ctx_destroy(dctx);
      return NULL;
    }
    return dctx;
  }
  spx_ctx *ctx = NULL;
  return spx_ctx_create(&ctx) == SPX_OK ? ctx : NULL;
}

/* A context and a tape without parameters (NULL, *ctx NULL and a failed check when either cannot
 * be made). */
static spx_tape *bare_tape(spx_tape_backend be, spx_ctx **ctx) {
  spx_tape *t = NULL;
  *ctx = open_ctx(be);
  CHECK(*ctx != NULL);
  if (!*ctx) return NULL;
  CHECK_OK(*ctx, spx_tape_create(*ctx, be, &t));
  if (t) CHECK_OK(*ctx, spx_tape_alloc_params(t));
  else spx_ctx_destroy(*ctx), *ctx = NULL;
  return t;
}

/* x -> relu -> relu -> relu (1x1x3x5 = 15 floats each, offsets 16-aligned), eval. x dies at node 0
 * (time 1), a at 3, b at 5, c is the output. Largest-first / first-fit: x at 0, a at 16 (meets x),
 * b at 0 (x is dead), c at 16: 16 + 15 = 31 floats, against 60 without reuse. */
typedef struct chain {
  const float *x;
  int in, out, loss;
} chain;

static spx_status eval_chain(spx_tape *t, void *user) {
  chain *c = user;
  c->in = spx_tape_input(t, 1, 1, 3, 5, c->x);
  c->out = spx_tape_act(t, SPX_ACT_RELU, 0, spx_tape_act(t, SPX_ACT_RELU, 0, spx_tape_act(t, SPX_ACT_RELU, 0, c->in)));
  return SPX_OK;
}

static void test_exact_eval(spx_tape_backend be) {
  spx_ctx *ctx = NULL;
  spx_tape *t = bare_tape(be, &ctx);
  if (!t) return;
  float x[15];
  for (int i = 0; i < 15; i++) x[i] = (float)i - 7.0f;
  chain ch = {x, -1, -1, -1};
  CHECK_OK(ctx, spx_tape_pass(t, 0, 1, eval_chain, &ch));
  const int c = ch.out, in = ch.in;
  size_t sum = 0, size = spx_tape_plan_bytes(t, &sum);
  CHECK_MSG(size == 31 * elem(be) && sum == 60 * elem(be), "eval chain: arena %zu, sum %zu bytes", size, sum);
  float y[15];
  CHECK_OK(ctx, spx_tape_read(t, c, y));
  for (int i = 0; i < 15; i++) CHECK(y[i] == (x[i] > 0 ? x[i] : 0));
  /* the input died at the first node: refused, not stale */
  CHECK(spx_tape_read(t, in, y) == SPX_E_STATE);
  spx_tape_destroy(t);
  spx_ctx_destroy(ctx);
}

/* Training: x (requires_grad) -> y = relu(x) -> z = relu(y) -> l = mean((z - 0.5)^2) (c: the
 * constant). Nodes at times 1, 3, 5; backward_begin 7, backward of node 2, 1, 0 at 9, 11, 13.
 * Data: x [0,1] (ReLU's backward reads its output), y [1,13], z [3,11], c [5,9], l [5,inf).
 * Gradients: l [7,9] (seeded), z [9,11], y [11,13], x [13,inf) (requires_grad).
 * By size (15, then 1), ties by id, data before gradient: x.d 0, x.g 0, y.d 16, y.g 32, z.d 0,
 * z.g 48, c 32, l.d 64, l.g 80 (below it: z.d, y.d, c, z.g, l.d) -> 81 floats; 7 x 15 + 2 = 107
 * without reuse. On the device the loss's reduction scratch (node 2's forward workspace, live at
 * 5 only) also lies in the arena (it still fits in 81 floats) and "without reuse" counts it. */
static spx_status train_chain(spx_tape *t, void *user) {
  chain *c = user;
  c->in = spx_tape_input(t, 1, 1, 3, 5, c->x);
  spx_status st = spx_tape_requires_grad(t, c->in);
  c->out = spx_tape_act(t, SPX_ACT_RELU, 0, c->in);
  c->loss = spx_tape_mse_const(t, spx_tape_act(t, SPX_ACT_RELU, 0, c->out), 0.5f);
  return st;
}

static void test_exact_train(spx_tape_backend be) {
  spx_ctx *ctx = NULL;
  spx_tape *t = bare_tape(be, &ctx);
  if (!t) return;
  float x[15], g[15];
  for (int i = 0; i < 15; i++) x[i] = 0.1f * (float)i - 0.6f;
  chain ch = {x, -1, -1, -1};
  CHECK_OK(ctx, spx_tape_pass(t, 1, 2, train_chain, &ch));
  const int xi = ch.in, y = ch.out, l = ch.loss;
  size_t sum = 0, size = spx_tape_plan_bytes(t, &sum);
  spx_ws_need red = {{0}};
  size_t arena_floats = 81;
  if (be == SPX_TAPE_DEVICE) {
    spx_loss_forward_need(ctx, 15, &red);
    /* the scratch (live at time 5 only) starts at a multiple m of the device's sub-buffer
     * alignment a at or past 48 (below that z.d, y.d and c are live at 5), l.d and l.g fit
     * beside it below 81 while m + scratch <= 81 (PoCL's a = 32: m = 64); NVIDIA's a = 128
     * puts it at 128 */
    size_t a = t->pl.nplans ? t->pl.plans[0].wsalign : 16;
    size_t m = (48 + a - 1) / a * a, end = m + (red.slot[0] + sizeof(float) - 1) / sizeof(float);
    if (end > arena_floats) arena_floats = end;
  }
  CHECK_MSG(size == arena_floats * elem(be) && sum == 107 * elem(be) + red.slot[0],
            "training graph: arena %zu, sum %zu bytes (want %zu)", size, sum, arena_floats * elem(be));
  CHECK_OK(ctx, spx_tape_backward(t, l));
  CHECK_OK(ctx, spx_tape_read_grad(t, xi, g));
  for (int i = 0; i < 15; i++) {
    double want = x[i] > 0 ? 2.0 * ((double)x[i] - 0.5) / 15.0 : 0.0;
    CHECK_NEAR(g[i], want, 0, 1e-6);
  }
  /* y's gradient died at node 0's backward; a second backward needs retain */
  CHECK(spx_tape_read_grad(t, y, g) == SPX_E_STATE);
  CHECK(spx_tape_backward(t, l) == SPX_E_STATE);
  spx_tape_destroy(t);
  spx_ctx_destroy(ctx);
}

enum { WD = 8, N = 2, H = 32, W = 48 };

typedef struct step_out {
  float loss, *out, *grads, *out1; /* out1: a batch-1 eval forward */
  size_t nout, ngrad, arena, sum;
  int in_place; /* device batch-1 eval: upcats whose skip lies at their output's start */
} step_out;

/* The upcats of the tape's last pass whose skip lies where their output starts (the planned
 * concatenation in place, lib/nn/tape_plan.c). */
static int upcats_in_place(const spx_tape *t) {
  int n = 0;
  for (int k = 0; k < t->nnodes; k++) {
    const tnode *nd = &t->nodes[k];
    n += nd->kind == OP_UPCAT && t->vals[nd->in[0]].off == t->vals[nd->out].off;
  }
  return n;
}

/* One training step and one eval forward of a width-8 UNet with fixed weights and data. */
static void unet_step(spx_tape_backend be, int reuse, int poison, step_out *r) {
  memset(r, 0, sizeof *r);
  spx_ctx *ctx = open_ctx(be);
  CHECK(ctx != NULL);
  if (!ctx) return;
  spx_unet *u = NULL;
  CHECK_OK(ctx, spx_unet_create_ex(ctx, WD, 0, 5, be, &u));
  size_t nin = (size_t)N * 4 * H * W;
  r->nout = (size_t)2 * N * 3 * H * W;
  float *in = malloc(nin * sizeof(float)), *tg = malloc(r->nout / 2 * sizeof(float));
  r->out = malloc(r->nout * sizeof(float));
  if (!u || !in || !tg || !r->out) goto done;
  unsigned long long s = 11;
  spx_nt_rand(in, nin, 0.0f, 1.0f, &s);
  spx_nt_rand(tg, r->nout / 2, 0.0f, 1.0f, &s);
  spx_tape *t = spx_unet_tape(u);
  spx_tape_set_reuse(t, reuse);
  spx_tape_set_poison(t, poison);
  CHECK_OK(ctx, spx_unet_zero_grad(u));
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, N, H, W, r->out, &r->loss));
  r->arena = spx_tape_plan_bytes(t, &r->sum);
  CHECK_OK(ctx, spx_unet_backward(u));
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    const char *name = spx_unet_tensor_name(u, i, NULL, NULL);
    int id = spx_unet_value_id(u, name);
    if (strstr(name, "running_") || strncmp(name, "optimizer.", 10) == 0 || id < 0) continue;
    size_t n = spx_tape_numel(t, id);
    float *ng = realloc(r->grads, (r->ngrad + n) * sizeof(float));
    if (!ng) break;
    r->grads = ng;
    CHECK_OK(ctx, spx_unet_read(u, name, SPX_UNET_GRAD, r->grads + r->ngrad, n));
    r->ngrad += n;
  }
  CHECK_OK(ctx, spx_unet_forward(u, in, N, H, W, 0, r->out + r->nout / 2));
  r->out1 = malloc((size_t)3 * H * W * sizeof(float));
  if (r->out1) {
    CHECK_OK(ctx, spx_unet_forward(u, in, 1, H, W, 0, r->out1));
    r->in_place = upcats_in_place(t);
  }
done:
  free(in), free(tg);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
}

static void test_unet_bit_exact(spx_tape_backend be) {
  step_out a, b;
  unet_step(be, 0, 0, &a);
  unet_step(be, 1, 1, &b);
  CHECK(a.ngrad > 0 && a.ngrad == b.ngrad && a.out && b.out);
  if (a.ngrad > 0 && a.ngrad == b.ngrad && a.out && b.out) {
    CHECK_MSG(memcmp(&a.loss, &b.loss, sizeof a.loss) == 0, "loss %.9g vs %.9g", a.loss, b.loss);
    CHECK(memcmp(a.out, b.out, a.nout * sizeof(float)) == 0);
    CHECK(memcmp(a.grads, b.grads, a.ngrad * sizeof(float)) == 0);
    CHECK(a.out1 && b.out1 && memcmp(a.out1, b.out1, (size_t)3 * H * W * sizeof(float)) == 0);
    /* the four up blocks' skips are planned in place on the device with reuse, never without */
    CHECK_MSG(a.in_place == 0 && b.in_place == (be == SPX_TAPE_DEVICE ? 4 : 0), "skips in place: %d without reuse, %d with",
              a.in_place, b.in_place);
    /* the whole step's values and gradients (+ the largest op workspace, device), against what
     * the plan needs at once: at least a quarter less (on the device the arena also holds every
     * conv's workspace at its step; at 32x48 the deepest Winograd layers' transforms, padded to
     * whole tile vectors, are most of that) */
    CHECK_MSG(b.arena * 4 < b.sum * 3 && a.arena >= a.sum, "arena %zu of %zu (without reuse: %zu of %zu)", b.arena,
              b.sum, a.arena, a.sum);
    printf("  %s: UNet w%d %dx4x%dx%d training arena %zu bytes with reuse, %zu without (%.2fx)\n",
           be == SPX_TAPE_HOST ? "host" : "device", WD, N, H, W, b.arena, a.arena, (double)a.arena / (double)b.arena);
  }
  free(a.out), free(a.grads), free(b.out), free(b.grads), free(a.out1), free(b.out1);
}

/* A build handing its own input to another tape: refused while its pass measures (no data yet),
 * done on the planned run. */
typedef struct handoff {
  spx_tape *dst;
  int did;
  const float *x;
  int runs, refused;
} handoff;

static spx_status handoff_build(spx_tape *t, void *user) {
  handoff *h = user;
  int in = spx_tape_input(t, 1, 1, 3, 5, h->x);
  spx_status st = spx_tape_transfer(h->dst, h->did, 0, 0, t, in, 0, 0, 15, 0);
  h->runs++;
  if (st == SPX_E_STATE) h->refused++;
  return h->runs == 1 ? SPX_OK : st; /* the measuring run goes on to be planned */
}

/* Inputs outside a pass and transfers out of a measuring pass are refused; a transfer into a
 * measuring pass copies nothing (the two-tape graphs of test_nn_tape_multi use it). */
static void test_pass_rules(spx_tape_backend be) {
  spx_ctx *ctx = NULL;
  spx_tape *t = bare_tape(be, &ctx), *t2 = NULL;
  CHECK(t == NULL || spx_tape_create(ctx, be, &t2) == SPX_OK);
  if (!t || !t2 || spx_tape_alloc_params(t2)) {
    spx_tape_destroy(t), spx_tape_destroy(t2);
    spx_ctx_destroy(ctx);
    return;
  }
  float x[15], y[15];
  for (int i = 0; i < 15; i++) x[i] = (float)i;
  CHECK(spx_tape_input(t, 1, 1, 3, 5, x) < 0);
  CHECK(strstr(spx_ctx_message(ctx), "outside spx_tape_pass") != NULL);
  chain ch = {x, -1, -1, -1};
  CHECK_OK(ctx, spx_tape_pass(t2, 0, 1, eval_chain, &ch)); /* t2's output: the destination */
  chain c0 = {x, -1, -1, -1};
  CHECK_OK(ctx, spx_tape_pass(t, 0, 1, eval_chain, &c0)); /* t's arena exists: a read would "work" */
  handoff h = {t2, ch.out, x, 0, 0};
  CHECK_OK(ctx, spx_tape_pass(t, 0, 3, handoff_build, &h));
  CHECK_MSG(h.runs == 2 && h.refused == 1, "%d runs, %d refused", h.runs, h.refused);
  CHECK_OK(ctx, spx_tape_read(t2, ch.out, y));
  CHECK(memcmp(x, y, sizeof x) == 0);
  spx_tape_destroy(t), spx_tape_destroy(t2);
  spx_ctx_destroy(ctx);
}

static void test_host(void) {
  test_pass_rules(SPX_TAPE_HOST);
  test_exact_eval(SPX_TAPE_HOST);
  test_exact_train(SPX_TAPE_HOST);
  test_unet_bit_exact(SPX_TAPE_HOST);
}
static void test_device(void) {
  test_pass_rules(SPX_TAPE_DEVICE);
  test_exact_eval(SPX_TAPE_DEVICE);
  test_exact_train(SPX_TAPE_DEVICE);
  test_unet_bit_exact(SPX_TAPE_DEVICE);
}

int main(void) {
  SPX_RUN(test_host);
  SPX_RUN(test_device);
  return spx_test_summary();
}
