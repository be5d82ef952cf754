/* The local-memory Winograd F(4x4,3x3) variant for GPU-class devices (kernels/conv2d_winograd_lds.cl),
 * run on PoCL with the GPU column of lib/cl/tuning.c (SPX_TUNE_CLASS=gpu: CONV_WINO_LDS = 1):
 * forward (bias, fused affine + ReLU) and backward data (accumulating) of every case against the
 * double reference within the bound derived at the top of tests/test_nn_conv2d_winograd.c (the
 * runner is tests/wino_case.h), and bit for bit against the CPU variant (kernels/
 * conv2d_winograd.cl, CONV_WINO_LDS = 0) with the same data, for several work-group / register /
 * channel-block shapes. Bit-identical, not merely bounded, because both variants compute every
 * transformed value with the same expressions (kernels/winograd_tf.h) and sum each GEMM over the
 * input channels in the same order with fma from zero; only where the sums are kept (registers of
 * different work-items, local memory) and the order of independent outputs differ. The cases
 * have edge tiles in both directions, channel counts that are not multiples of the channel
 * block or of the group's channels, a 1x1 image, batch 2, and several groups along every axis. */
#include "smplpix/smplpix.h"
#include "test.h"
#include "wino_case.h"

static const wcase cases[] = {
    {1, 3, 5, 7, 4, 1, 0, 0},     /* partial tiles on both sides, fewer channels than a block */
    {2, 17, 13, 18, 19, 0, 1, 1}, /* batch 2, affine + ReLU, channels not multiples of the tiles */
    {1, 33, 21, 39, 40, 1, 1, 0}, /* several channel blocks and groups of channels and tiles */
    {1, 5, 1, 1, 3, 1, 0, 1},     /* 1x1 image: only the centre tap sees data */
    {2, 24, 40, 52, 9, 1, 0, 1},  /* many tile rows and groups of tiles, batch 2 */
};

/* The tile shapes: TM, TN (register tile), WM, WN (work-items per position), KB (channel block). */
static const char *shapes[][5] = {
    {"4", "4", "2", "2", "8"}, /* the GPU column's defaults */
    {"1", "1", "1", "1", "1"}, /* 36 work-items, one channel per block */
    {"2", "3", "4", "1", "5"}, /* uneven: channel groups of 8, tile groups of 3, blocks of 5 */
    {"3", "2", "1", "4", "16"},
};

/* Every case on a device opened with CONV_WINO_LDS = lds (tunables are read when it opens); the
 * outputs of case i in outs[i] (y, dx). */
static void run_all(int lds, float *outs[][2]) {
  setenv("SPX_TUNE_CONV_WINO_LDS", lds ? "1" : "0", 1);
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(spx_conv2d_winograd_lds_applies(ctx) == lds);
  spx_op_workspace ws = {0};
  unsigned long long keep = rng;
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) run_case(ctx, &cases[i], i % 2 ? &ws : NULL, outs[i]);
  rng = keep; /* the next run sees the same data */
  spx_op_workspace_release(&ws);
  spx_ctx_destroy(ctx);
}

static void compare(float *a[][2], float *b[][2], const char *what) {
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    const wcase *c = &cases[i];
    size_t ny = (size_t)c->n * c->cout * c->h * c->w + 3 + 8, nx = (size_t)c->n * c->cin * c->h * c->w;
    CHECK_MSG(!memcmp(a[i][0], b[i][0], ny * 4), "n=%d cin=%d %dx%d cout=%d: forward differs (%s)", c->n, c->cin,
              c->h, c->w, c->cout, what);
    CHECK_MSG(!memcmp(a[i][1], b[i][1], nx * 4), "n=%d cin=%d %dx%d cout=%d: backward data differs (%s)", c->n,
              c->cin, c->h, c->w, c->cout, what);
  }
}

static void release(float *o[][2]) {
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) free(o[i][0]), free(o[i][1]);
}

static void test_lds_vs_cpu_variant(void) {
  enum { NC = sizeof cases / sizeof cases[0] };
  float *cpu[NC][2], *gpu[NC][2], *again[NC][2];
  run_all(0, cpu);
  for (size_t s = 0; s < sizeof shapes / sizeof shapes[0]; s++) {
    static const char *names[5] = {"SPX_TUNE_CONV_WLDS_TM", "SPX_TUNE_CONV_WLDS_TN", "SPX_TUNE_CONV_WLDS_WM",
                                   "SPX_TUNE_CONV_WLDS_WN", "SPX_TUNE_CONV_WLDS_KB"};
    for (int k = 0; k < 5; k++) setenv(names[k], shapes[s][k], 1);
    printf("local-memory variant, TM %s TN %s WM %s WN %s KB %s:\n", shapes[s][0], shapes[s][1], shapes[s][2],
           shapes[s][3], shapes[s][4]);
    run_all(1, gpu);
    compare(cpu, gpu, "local-memory variant vs the CPU variant");
    if (s == 0) { /* reruns: same bits */
      run_all(1, again);
      compare(gpu, again, "rerun");
      release(again);
    }
    release(gpu);
    for (int k = 0; k < 5; k++) unsetenv(names[k]);
  }
  release(cpu);
}

/* Where the group does not fit the device (here: more work-items than its limit), the CPU
 * variant runs instead. */
static void test_fallback(void) {
  setenv("SPX_TUNE_CONV_WINO_LDS", "1", 1);
  setenv("SPX_TUNE_CONV_WLDS_WM", "28", 1);
  setenv("SPX_TUNE_CONV_WLDS_WN", "28", 1);
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  CHECK(36 * 28 * 28 > (int)ctx->dev->info.max_work_group);
  CHECK(!spx_conv2d_winograd_lds_applies(ctx));
  run_case(ctx, &cases[1], NULL, NULL);
  spx_ctx_destroy(ctx);
  unsetenv("SPX_TUNE_CONV_WLDS_WM");
  unsetenv("SPX_TUNE_CONV_WLDS_WN");
}

int main(void) {
  setenv("SPX_TUNE_CLASS", "gpu", 1);
  /* every 3x3/s1/p1 layer takes the Winograd path, training calls (backward data) included */
  setenv("SPX_TUNE_CONV_WINO_MINC", "1", 1);
  setenv("SPX_TUNE_CONV_WINO_TRAIN", "1", 1);
  SPX_RUN(test_lds_vs_cpu_variant);
  SPX_RUN(test_fallback);
  return spx_test_summary();
}
