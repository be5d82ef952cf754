/* UNet benchmark: eval forward (batch norm folded, fused ReLU) and one training step (zero grad +
 * forward + L1 + backward + Adam) of the SMPLpix UNet on an Nx4xHxW input, on the open device;
 * minimum over reps after one warm-up (which also plans the arenas and builds the kernels).
 * Peer: benchmarks/peer_unet_torch.py times the same model in PyTorch and prints the same ROW
 * lines; benchmarks/unet_vs_torch.sh (`make bench-unet`) runs both back to back and compares.
 *
 *   bench_unet [--width W] [--size HxW] [--reps N] [--batch N] [--eval-batch N] [--no-train] [--no-eval]
 *   defaults: width 16, 308x410, 3 reps, train batch 1, eval batch 1
 *
 * GFLOP convention: forward = 2 x multiply-adds of every convolution (batch norm, ReLU, pooling,
 * upsampling, concat and the loss are not counted) x batch; a training step counts 3x the forward
 * (forward + input gradient + weight gradient). GFLOP/s = those FLOPs / the minimum time.
 * Bytes in the same model (benchmarks/roofline.h): every convolution's input, weights and output
 * once (weights once per pass, activations per image); a training step 3x. Against the device's
 * roofline, measured at the start as `smplpix devices --peak` does: the share of the FMA peak (and
 * of the bandwidth). Per layer: SPX_TAPE_PROFILE=2 adds the same figures to every op's line.
 *
 * Memory: the bytes of every device buffer the network holds at the end of the row
 * (spx_unet_device_bytes: parameter, gradient, Adam and state slabs + the arena of activations,
 * activation gradients and the ops' scratch; all grow-only, so this is the peak of the rows run so
 * far in this process). peak_bytes: the context's device-memory high-water mark over the row
 * (spx_device_peak_bytes, reset before the row's warm-up: every device buffer, per-call scratch
 * included); rss_bytes: this process's peak resident set (getrusage ru_maxrss: with PoCL the device
 * memory is host memory, so this is the figure to set beside the torch peer's ru_maxrss).
 *
 * Besides the human-readable lines, every row prints one machine-readable line:
 *   ROW impl=smplpix mode=eval|train width=W batch=N h=H w=W reps=R ms=... gflop=... gflops=...
 *       mem_bytes=... mem_kind=device peak_bytes=... rss_bytes=... gbyte=... gbs=... peak_gflops=...
 *       peak_gbs=... pct_peak=... pct_bw=... bound=compute|memory pct_roof=... */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "bench_common.h"
#include "roofline.h"
#include "smplpix/smplpix.h"

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int fail(spx_ctx *ctx, const char *what) {
  fprintf(stderr, "bench_unet: %s: %s\n", what, spx_ctx_message(ctx));
  return 1;
}

/* 2 x multiply-adds of every convolution of the width-wd UNet on one h x w input, in GFLOP */
static double unet_gflop(int wd, int h, int w) {
  const int io[9][3] = {{4, wd, wd},           {wd, 2 * wd, 2 * wd},     {2 * wd, 4 * wd, 4 * wd},
                        {4 * wd, 8 * wd, 8 * wd}, {8 * wd, 8 * wd, 8 * wd}, {16 * wd, 8 * wd, 4 * wd},
                        {8 * wd, 4 * wd, 2 * wd}, {4 * wd, 2 * wd, wd},     {2 * wd, wd, wd}};
  int hs[5] = {h, h / 2, h / 4, h / 8, h / 16}, ws[5] = {w, w / 2, w / 4, w / 8, w / 16};
  const int lvl[9] = {0, 1, 2, 3, 4, 3, 2, 1, 0};
  double f = 0;
  for (int i = 0; i < 9; i++) {
    double px = (double)hs[lvl[i]] * ws[lvl[i]];
    f += 2.0 * px * 9 * ((double)io[i][0] * io[i][1] + (double)io[i][1] * io[i][2]);
  }
  f += 2.0 * (double)h * w * wd * 3;
  return f * 1e-9;
}

/* bytes of every convolution's input, weights and output once, in GB: act_gb per image, wts_gb per pass */
static void unet_gbyte(int wd, int h, int w, double *act_gb, double *wts_gb) {
  const int io[9][3] = {{4, wd, wd},           {wd, 2 * wd, 2 * wd},     {2 * wd, 4 * wd, 4 * wd},
                        {4 * wd, 8 * wd, 8 * wd}, {8 * wd, 8 * wd, 8 * wd}, {16 * wd, 8 * wd, 4 * wd},
                        {8 * wd, 4 * wd, 2 * wd}, {4 * wd, 2 * wd, wd},     {2 * wd, wd, wd}};
  int hs[5] = {h, h / 2, h / 4, h / 8, h / 16}, ws[5] = {w, w / 2, w / 4, w / 8, w / 16};
  const int lvl[9] = {0, 1, 2, 3, 4, 3, 2, 1, 0};
  double a = 0, k = 0;
  for (int i = 0; i < 9; i++) {
    double px = (double)hs[lvl[i]] * ws[lvl[i]];
    a += px * ((double)io[i][0] + 2.0 * io[i][1] + io[i][2]); /* conv 1: in -> mid, conv 2: mid -> out */
    k += 9.0 * ((double)io[i][0] * io[i][1] + (double)io[i][1] * io[i][2]);
  }
  a += (double)h * w * (wd + 3), k += 3.0 * wd; /* the 1x1 output layer */
  *act_gb = 4.0 * a * 1e-9, *wts_gb = 4.0 * k * 1e-9;
}

static bench_roof roof;

static void row(spx_ctx *ctx, const char *mode, int width, int n, int h, int w, int reps, double s, double gflop,
                double gbyte, size_t bytes) {
  struct rusage ru;
  long maxrss = getrusage(RUSAGE_SELF, &ru) == 0 ? ru.ru_maxrss : 0; /* KiB on Linux */
  bench_roof_cell c = bench_roof_eval(&roof, gflop, gbyte, 1e3 * s);
  printf("roofline %s: %.3f GFLOP, %.1f MB in %.3f ms: %.1f GFLOP/s = %.1f%% of the FMA peak, %.1f GB/s = %.1f%% of the "
         "bandwidth (%s-bound by the model)\n",
         mode, gflop, gbyte * 1e3, 1e3 * s, c.gflops, c.pct_peak, c.gbs, c.pct_bw, c.memory_bound ? "memory" : "compute");
  /* the fields before mem_bytes keep their order: scripts read ROW lines as key=value pairs */
  printf("ROW impl=smplpix mode=%s width=%d batch=%d h=%d w=%d reps=%d ms=%.3f gflop=%.3f gflops=%.3f "
         "mem_bytes=%zu mem_kind=device peak_bytes=%zu rss_bytes=%ld gbyte=%.5f gbs=%.3f peak_gflops=%.1f "
         "peak_gbs=%.1f pct_peak=%.2f pct_bw=%.2f bound=%s pct_roof=%.2f\n",
         mode, width, n, h, w, reps, 1e3 * s, gflop, gflop / s, bytes, spx_device_peak_bytes(ctx), maxrss * 1024, gbyte,
         c.gbs, roof.gflops, roof.gbs, c.pct_peak, c.pct_bw, c.memory_bound ? "memory" : "compute", c.pct_roof);
}

int main(int argc, char **argv) {
  int width = 16, h = 308, w = 410, reps = 3, train = 1, eval = 1, batch = 1, ebatch = 1;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--width") && i + 1 < argc) width = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--size") && i + 1 < argc && sscanf(argv[++i], "%dx%d", &h, &w) == 2) {
    } else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--batch") && i + 1 < argc) batch = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--eval-batch") && i + 1 < argc) ebatch = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--no-train")) train = 0;
    else if (!strcmp(argv[i], "--no-eval")) eval = 0;
    else {
      fprintf(stderr, "usage: bench_unet [--width 8|16|32|64] [--size HxW] [--reps N] [--batch N] [--eval-batch N] "
                      "[--no-train] [--no-eval]\n");
      return 2;
    }
  }
  if (reps < 1) reps = 1;
  if (batch < 1 || batch > 64 || ebatch < 1 || ebatch > 64 || h < 16 || w < 16 || h > 8192 || w > 8192) {
    fprintf(stderr, "bench_unet: --batch/--eval-batch must be 1..64 and --size within 16..8192\n");
    return 2;
  }
  int nmax = batch > ebatch ? batch : ebatch;
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return 1;
  bench_profiles_from_env(ctx); /* SPX_TAPE_PROFILE=1|2, SPX_KERNEL_PROFILE=1 */
  spx_unet *u = NULL;
  int rc = 1;
  size_t nin = (size_t)nmax * 4 * h * w, nout = (size_t)nmax * 3 * h * w;
  float *in = malloc(nin * sizeof(float)), *tg = malloc(nout * sizeof(float)), *out = malloc(nout * sizeof(float));
  if (!in || !tg || !out) {
    fprintf(stderr, "bench_unet: out of host memory\n");
    goto done;
  }
  for (size_t i = 0; i < nin; i++) in[i] = (float)((i * 2654435761u) % 1000) / 1000.0f;
  for (size_t i = 0; i < nout; i++) tg[i] = (float)((i * 40503u) % 1000) / 1000.0f;
  if (spx_device_open(ctx, NULL)) {
    rc = fail(ctx, "device");
    goto done;
  }
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  printf("device: %s\n", info.name);
  bench_roof_measure(ctx, &roof);
  if (spx_unet_create(ctx, width, 0, 1, &u)) {
    rc = fail(ctx, "create");
    goto done;
  }
  double gf = unet_gflop(width, h, w), act_gb, wts_gb;
  unet_gbyte(width, h, w, &act_gb, &wts_gb);
  if (eval) {
    double best = 1e30;
    spx_device_reset_peak(ctx);
    for (int r = 0; r <= reps; r++) { /* r == 0: warm-up */
      double t0 = now();
      if (spx_unet_forward(u, in, ebatch, h, w, 0, out) || spx_device_finish(ctx)) {
        rc = fail(ctx, "eval forward");
        goto done;
      }
      double t = now() - t0;
      if (r && t < best) best = t;
    }
    size_t bytes = spx_unet_device_bytes(u);
    printf("unet width %d, %dx4x%dx%d: eval forward %.3f s (%.1f GFLOP, %.1f GFLOP/s), device memory %.1f MiB\n",
           width, ebatch, h, w, best, gf * ebatch, gf * ebatch / best, (double)bytes / 1048576.0);
    row(ctx, "eval", width, ebatch, h, w, reps, best, gf * ebatch, act_gb * ebatch + wts_gb, bytes);
  }
  if (train) {
    double best = 1e30;
    spx_device_reset_peak(ctx);
    float loss;
    for (int r = 0; r <= reps; r++) {
      double t0 = now();
      if (spx_unet_zero_grad(u) || spx_unet_forward_loss(u, in, tg, batch, h, w, NULL, &loss) || spx_unet_backward(u) ||
          spx_unet_adam_step(u, 1e-4) || spx_device_finish(ctx)) {
        rc = fail(ctx, "train step");
        goto done;
      }
      double t = now() - t0;
      if (r && t < best) best = t;
    }
    size_t bytes = spx_unet_device_bytes(u);
    printf("unet width %d, %dx4x%dx%d: train step (fwd + L1 + bwd + Adam) %.3f s (~%.1f GFLOP/s at 3x forward "
           "flops), device memory %.1f MiB\n",
           width, batch, h, w, best, 3 * gf * batch / best, (double)bytes / 1048576.0);
    row(ctx, "train", width, batch, h, w, reps, best, 3 * gf * batch, 3 * (act_gb * batch + wts_gb), bytes);
  }
  rc = 0;
done:
  free(in), free(tg), free(out);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
  return rc;
}
