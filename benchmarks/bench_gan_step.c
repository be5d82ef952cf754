/* One stage-2 training step of the paper (§3.3): the SMPLpix UNet generator, pix2pixHD's 3-scale
 * PatchGAN and the frozen VGG19 perceptual loss; generator loss L_VGG + L_GAN + 0.1 L_FM, one Adam
 * step for G and one for D (spx_unet_gan_step). Random weights (the VGG19 ones written to a
 * temporary safetensors file first), random input / target of N x 4 x H x W. Minimum over reps
 * after one warm-up (which plans the arenas and builds the kernels).
 * Peer: benchmarks/peer_gan_step_torch.py; driver: benchmarks/gan_vs_torch.sh.
 *
 *   bench_gan_step [--width 64] [--disc-width 64] [--size 308x410] [--batch 1] [--reps 2]
 *
 * Prints one machine-readable line:
 *   ROW impl=smplpix mode=gan_step width=W batch=N h=H w=W reps=R ms=... mem_bytes=(G only)
 *       peak_bytes=(device high-water mark of the process: G, D, VGG, scratch) rss_bytes=(ru_maxrss) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "bench_common.h"
#include "smplpix/smplpix.h"

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv) {
  int width = 64, dwidth = 64, h = 308, w = 410, n = 1, reps = 2;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--width") && i + 1 < argc) width = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--disc-width") && i + 1 < argc) dwidth = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--size") && i + 1 < argc) {
      if (sscanf(argv[++i], "%dx%d", &h, &w) != 2) return fprintf(stderr, "bench_gan_step: --size HxW\n"), 2;
    } else if (!strcmp(argv[i], "--batch") && i + 1 < argc) n = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
    else return fprintf(stderr, "usage: bench_gan_step [--width W] [--disc-width D] [--size HxW] [--batch N] [--reps R]\n"), 2;
  }
  if (width < 1 || dwidth < 1 || h < 16 || w < 16 || n < 1 || reps < 1) return fprintf(stderr, "bench_gan_step: bad arguments\n"), 2;
  spx_ctx *ctx = NULL;
  spx_unet *g = NULL;
  spx_patchgan *d = NULL;
  spx_vgg *v = NULL;
  float *in = NULL, *tg = NULL;
  int rc = 1;
  char vpath[256];
  snprintf(vpath, sizeof vpath, "/tmp/bench_gan_vgg_%d.safetensors", (int)getpid());
  if (spx_ctx_create(&ctx) || spx_device_open(ctx, NULL)) {
    fprintf(stderr, "bench_gan_step: no device: %s\n", ctx ? spx_ctx_message(ctx) : "");
    goto done;
  }
  if (bench_write_vgg19(ctx, vpath, 64) || spx_vgg_open(ctx, vpath, &v)) goto err;
  remove(vpath);
  if (spx_unet_create(ctx, width, 0, 1, &g) || spx_patchgan_new(ctx, dwidth, 3, 2, &d)) goto err;
  size_t hw = (size_t)h * w;
  in = malloc((size_t)n * 4 * hw * 4), tg = malloc((size_t)n * 3 * hw * 4);
  if (!in || !tg) goto done;
  uint64_t s = 11;
  for (size_t k = 0; k < (size_t)n * 4 * hw; k++) in[k] = bench_unif(&s);
  for (size_t k = 0; k < (size_t)n * 3 * hw; k++) tg[k] = bench_unif(&s);
  double best = 1e30;
  spx_gan_losses l;
  for (int r = 0; r <= reps; r++) {
    double t0 = now();
    if (spx_unet_gan_step(g, d, v, in, tg, n, h, w, 1e-5, 1e-5, &l)) goto err;
    double t = now() - t0;
    if (r > 0 && t < best) best = t;
    fprintf(stderr, "  %s %.1f ms (VGG %.4f GAN %.4f FM %.4f D %.4f)\n", r ? "step" : "warm-up", 1e3 * t, l.vgg, l.gan,
            l.fm, l.d_total);
  }
  printf("ours: stage-2 step (G width %d + 3 D width %d + VGG19), %dx4x%dx%d: %.1f ms (min of %d)\n", width, dwidth, n,
         h, w, 1e3 * best, reps);
  struct rusage ru;
  long maxrss = getrusage(RUSAGE_SELF, &ru) == 0 ? ru.ru_maxrss : 0; /* KiB on Linux */
  printf("ROW impl=smplpix mode=gan_step width=%d batch=%d h=%d w=%d reps=%d ms=%.3f mem_bytes=%zu peak_bytes=%zu "
         "rss_bytes=%ld\n",
         width, n, h, w, reps, 1e3 * best, spx_unet_device_bytes(g), spx_device_peak_bytes(ctx), maxrss * 1024);
  rc = 0;
  goto done;
err:
  fprintf(stderr, "bench_gan_step: %s\n", spx_ctx_message(ctx));
done:
  remove(vpath);
  free(in), free(tg);
  spx_vgg_destroy(v);
  spx_patchgan_destroy(d);
  spx_unet_destroy(g);
  spx_ctx_destroy(ctx);
  return rc;
}
