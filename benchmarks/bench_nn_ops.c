/* Times the non-convolution network ops at the UNet's largest shapes (width 64, 308x410,
 * batch 1) on the default device: median of 5 runs after a warm-up, with the memory traffic
 * each op needs at minimum, as effective GB/s, and the process's CPU time (all threads: steadier
 * than the wall time on a loaded machine). Usage: bench_nn_ops [width [name-substring]] */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "nn/activations.h"
#include "nn/batchnorm.h"
#include "nn/loss.h"
#include "nn/optim.h"
#include "nn/pool.h"
#include "nn/tensor_ops.h"
#include "nn/upsample.h"
#include "smplpix/smplpix.h"

static spx_ctx *ctx;
static cl_mem big[4];
static spx_tensor T(int i, int n, int c, int h, int w) { return spx_tensor_view(big[i], 0, n, c, h, w); }

static int cmpd(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

typedef spx_status (*op_fn)(void);
static const char *only; /* argv[2]: run only the ops whose name contains it */
static void bench(const char *name, op_fn f, double bytes) {
  double t[5], c[5];
  if (only && !strstr(name, only)) return;
  if (f() || spx_device_finish(ctx)) {
    printf("%-28s failed: %s\n", name, spx_ctx_message(ctx));
    return;
  }
  for (int r = 0; r < 5; r++) {
    double t0 = spx_now();
    clock_t c0 = clock();
    f();
    spx_device_finish(ctx);
    t[r] = spx_now() - t0;
    c[r] = (double)(clock() - c0) / CLOCKS_PER_SEC;
  }
  qsort(t, 5, sizeof t[0], cmpd);
  qsort(c, 5, sizeof c[0], cmpd);
  printf("%-28s %9.3f ms  %7.2f GB/s  (process CPU %.3f ms)\n", name, t[2] * 1e3, bytes / t[2] * 1e-9, c[2] * 1e3);
}

static int W = 64, H = 308, X = 410;
static spx_status relu_f(void) {
  spx_tensor a = T(0, 1, W, H, X), b = T(1, 1, W, H, X);
  return spx_act_forward(ctx, SPX_ACT_RELU, 0, &a, &b);
}
static spx_status relu_b(void) {
  spx_tensor a = T(0, 1, W, H, X), g = T(1, 1, W, H, X), d = T(2, 1, W, H, X);
  return spx_act_backward(ctx, SPX_ACT_RELU, 0, &a, &g, &d);
}
static spx_status bn_f(void) {
  spx_tensor x = T(0, 1, W, H, X), y = T(1, 1, W, H, X), p = T(3, W, 1, 1, 1);
  spx_tensor b = spx_tensor_view(big[3], W, W, 1, 1, 1), rm = spx_tensor_view(big[3], 2 * W, W, 1, 1, 1);
  spx_tensor rv = spx_tensor_view(big[3], 3 * W, W, 1, 1, 1), sv = spx_tensor_view(big[3], 4 * W, 2 * W, 1, 1, 1);
  return spx_bn_train_forward(ctx, &x, &p, &b, &rm, &rv, 0.1f, 1e-5f, 1, &sv, &y);
}
static spx_status bn_b(void) {
  spx_tensor x = T(0, 1, W, H, X), g = T(1, 1, W, H, X), d = T(2, 1, W, H, X), p = T(3, W, 1, 1, 1);
  spx_tensor sv = spx_tensor_view(big[3], 4 * W, 2 * W, 1, 1, 1), dw = spx_tensor_view(big[3], 6 * W, W, 1, 1, 1);
  spx_tensor db = spx_tensor_view(big[3], 7 * W, W, 1, 1, 1);
  return spx_bn_train_backward(ctx, &x, &p, &sv, &g, &d, &dw, &db);
}
static spx_status pool_f(void) {
  spx_tensor x = T(0, 1, W, H, X), y = T(1, 1, W, H / 2, X / 2);
  return spx_maxpool_forward(ctx, &x, &y);
}
static spx_status pool_b(void) {
  spx_tensor x = T(0, 1, W, H, X), g = T(1, 1, W, H / 2, X / 2), d = T(2, 1, W, H, X);
  return spx_maxpool_backward(ctx, &x, &g, &d);
}
static spx_status up_f(void) {
  spx_tensor x = T(0, 1, W, H / 2, X / 2), y = T(1, 1, W, H, X);
  return spx_upsample2x_forward(ctx, &x, 1, &y);
}
static spx_status up_b(void) {
  spx_tensor g = T(1, 1, W, H, X), d = T(2, 1, W, H / 2, X / 2);
  return spx_upsample2x_backward(ctx, &g, 1, &d);
}
static spx_status cat_f(void) {
  spx_tensor a = T(0, 1, W, H, X), b = T(1, 1, W, H, X), o = T(2, 1, 2 * W, H, X);
  return spx_concat_forward(ctx, &a, &b, &o);
}
static spx_status cat_b(void) {
  spx_tensor a = T(0, 1, W, H, X), b = T(1, 1, W, H, X), o = T(2, 1, 2 * W, H, X);
  return spx_concat_backward(ctx, &o, &a, &b);
}
/* The UNet's last up-block input: concat(skip, upsample2x(x)), as the chain and as one op */
static spx_status upcat_chain_f(void) {
  spx_tensor x = T(0, 1, W, H / 2, X / 2), u = T(3, 1, W, H, X), s = T(1, 1, W, H, X), o = T(2, 1, 2 * W, H, X);
  spx_status st = spx_upsample2x_forward(ctx, &x, 1, &u);
  return st ? st : spx_concat_forward(ctx, &s, &u, &o);
}
static spx_status upcat_f(void) {
  spx_tensor x = T(0, 1, W, H / 2, X / 2), s = T(1, 1, W, H, X), o = T(2, 1, 2 * W, H, X);
  return spx_upcat_forward(ctx, &s, &x, 0, 0, 1, &o);
}
static spx_status upcat_chain_b(void) {
  spx_tensor g = T(2, 1, 2 * W, H, X), u = T(3, 1, W, H, X), ds = T(1, 1, W, H, X), dx = T(0, 1, W, H / 2, X / 2);
  spx_status st = spx_fill(ctx, &u, 0.0f);
  if (!st) st = spx_concat_backward(ctx, &g, &ds, &u);
  return st ? st : spx_upsample2x_backward(ctx, &u, 1, &dx);
}
static spx_status upcat_b(void) {
  spx_tensor g = T(2, 1, 2 * W, H, X), ds = T(1, 1, W, H, X), dx = T(0, 1, W, H / 2, X / 2);
  return spx_upcat_backward(ctx, &g, 0, 0, 1, &ds, &dx);
}
static spx_status mse_fb(void) {
  spx_tensor p = T(0, 1, 3, H, X), t = T(1, 1, 3, H, X), d = T(2, 1, 3, H, X), o = T(3, 1, 1, 1, 1);
  spx_status st = spx_loss_forward(ctx, SPX_LOSS_MSE, SPX_REDUCE_MEAN, &p, &t, &o);
  return st ? st : spx_loss_backward(ctx, SPX_LOSS_MSE, SPX_REDUCE_MEAN, &p, &t, &o, &d, NULL);
}
static spx_status sum_big(void) {
  spx_tensor x = T(0, 1, W, H, X), o = T(3, 1, 1, 1, 1);
  return spx_reduce(ctx, SPX_REDUCE_SUM, &x, &o);
}
static const int NP = 17263491; /* ~ the milesial UNet at width 64 */
static spx_status adam(void) {
  spx_adam_params a = {1e-3, 0.9, 0.999, 1e-8, 0};
  spx_tensor p = T(0, NP, 1, 1, 1), g = T(1, NP, 1, 1, 1), m = T(2, NP, 1, 1, 1);
  spx_tensor v = spx_tensor_view(big[2], (size_t)NP, NP, 1, 1, 1);
  return spx_adam_step(ctx, &a, 3, &p, &g, &m, &v);
}

int main(int argc, char **argv) {
  if (argc > 1) W = atoi(argv[1]);
  if (argc > 2) only = argv[2];
  if (W < 1 || W > 256) return 2;
  if (spx_ctx_create(&ctx) || spx_device_open(ctx, NULL)) {
    fprintf(stderr, "bench_nn_ops: %s\n", spx_ctx_message(ctx));
    return 1;
  }
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  size_t act = (size_t)W * H * X, cap = 2 * act > 2 * (size_t)NP ? 2 * act : 2 * (size_t)NP;
  for (int i = 0; i < 4; i++)
    if (spx_cl_alloc(ctx, cap * sizeof(float), "bench buffer", &big[i]) || spx_cl_fill_f32(ctx, big[i], 0, cap, 0.5f)) {
      fprintf(stderr, "bench_nn_ops: %s\n", spx_ctx_message(ctx));
      return 1;
    }
  printf("device: %s; activations 1x%dx%dx%d\n", info.name, W, H, X);
  double b = 4.0 * act;
  bench("relu forward", relu_f, 2 * b);
  bench("relu backward", relu_b, 4 * b);
  bench("batchnorm train forward", bn_f, 2 * b);
  bench("batchnorm train backward", bn_b, 4 * b);
  bench("maxpool forward", pool_f, 1.25 * b);
  bench("maxpool backward", pool_b, 3.25 * b);
  bench("upsample x2 (ac) forward", up_f, 1.25 * b);
  bench("upsample x2 (ac) backward", up_b, 1.5 * b);
  bench("concat forward", cat_f, 4 * b);
  bench("concat backward", cat_b, 6 * b);
  bench("up block chain forward", upcat_chain_f, 5.25 * b);
  bench("upcat (fused) forward", upcat_f, 3.25 * b);
  bench("up block chain backward", upcat_chain_b, 8.5 * b);
  bench("upcat (fused) backward", upcat_b, 5.5 * b);
  bench("mse loss fwd+bwd (3 ch)", mse_fb, 4 * 4.0 * 3 * H * X);
  bench("sum reduction", sum_big, b);
  bench("adam step (17.3M params)", adam, 7 * 4.0 * NP);
  for (int i = 0; i < 4; i++) spx_cl_free(&big[i]);
  spx_ctx_destroy(ctx);
  return 0;
}
