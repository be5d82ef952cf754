/* The network engine's bits, dumped for a before / after comparison of a change that must not
 * move a single bit (a refactor, a kernel rewrite that claims "same bits"):
 *
 *   nn_bytecheck OUT.bin      then, after the change:   nn_bytecheck NEW.bin && cmp OUT.bin NEW.bin
 *
 * Writes, in order, as raw float32: for UNet widths 16 and 8 at 45x83 and 37x150 (batch 2;
 * Winograd on every 3x3 layer of 16+ channels, training forwards and backward included): the eval
 * output from host data, the eval output from a device tensor, the training loss, every parameter
 * gradient, the loss after one Adam step and the next eval output (running statistics refolded);
 * then one stage-2 step (UNet width 8, a 2-scale PatchGAN, a random VGG19 at width 4) at 37x45:
 * its loss terms, every generator gradient-driven parameter after the step, and the next step's
 * terms. Prints one line per block with a checksum, and the UNet's device bytes (its planned arena)
 * after eval and after training. Exit 1 (message on stderr) on any failure. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench_common.h"
#include "smplpix/smplpix.h"

static FILE *out;

/* FNV-1a over the bytes, and the floats appended to the dump */
static int dump(const char *what, const float *v, size_t n) {
  uint64_t h = 1469598103934665603ULL;
  const unsigned char *b = (const unsigned char *)v;
  for (size_t i = 0; i < n * sizeof(float); i++) h = (h ^ b[i]) * 1099511628211ULL;
  printf("  %-44s %9zu floats  %016llx\n", what, n, (unsigned long long)h);
  return fwrite(v, sizeof(float), n, out) == n ? 0 : -1;
}

/* every parameter's gradient (field SPX_UNET_GRAD) or value */
static spx_status dump_unet(spx_unet *u, spx_unet_field field, const char *tag) {
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    int nd = 0;
    int64_t sh[4] = {0};
    const char *name = spx_unet_tensor_name(u, i, &nd, sh);
    if (field == SPX_UNET_GRAD && strstr(name, "running_")) continue;
    size_t n = 1;
    for (int k = 0; k < nd; k++) n *= (size_t)sh[k];
    float *buf = malloc(n * sizeof(float));
    if (!buf) return SPX_E_NOMEM;
    spx_status st = spx_unet_read(u, name, field, buf, n);
    char what[96];
    snprintf(what, sizeof what, "%s %s", tag, name);
    if (!st && dump(what, buf, n)) st = SPX_E_IO;
    free(buf);
    if (st) return st;
  }
  return SPX_OK;
}

static spx_status unet_case(spx_ctx *ctx, int width, int h, int w) {
  enum { N = 2 };
  size_t hw = (size_t)h * w;
  float *in = malloc(N * 4 * hw * sizeof(float)), *tg = malloc(N * 3 * hw * sizeof(float));
  float *y = malloc(N * 3 * hw * sizeof(float));
  spx_unet *u = NULL;
  spx_device_tensor *dt = NULL;
  spx_status st = in && tg && y ? SPX_OK : SPX_E_NOMEM;
  uint64_t s = 0xb17e5ULL + (uint64_t)width * 1000 + (uint64_t)h;
  for (size_t k = 0; !st && k < N * 4 * hw; k++) in[k] = bench_unif(&s);
  for (size_t k = 0; !st && k < N * 3 * hw; k++) tg[k] = bench_unif(&s);
  char what[64];
  float loss = 0;
  printf("unet width %d, %dx4x%dx%d\n", width, N, h, w);
  if (!st) st = spx_unet_create(ctx, width, 1, 5, &u);
  if (!st) st = spx_unet_forward(u, in, N, h, w, 0, y);
  if (!st && dump("eval output", y, N * 3 * hw)) st = SPX_E_IO;
  if (!st) printf("  device bytes after eval: %zu\n", spx_unet_device_bytes(u)); /* the arena's plan */
  if (!st) st = spx_device_tensor_create(ctx, N, 4, h, w, &dt);
  if (!st) st = spx_device_tensor_write(ctx, dt, in);
  if (!st) st = spx_unet_forward_tensor(u, dt, y);
  if (!st && dump("eval output (device input)", y, N * 3 * hw)) st = SPX_E_IO;
  if (!st) st = spx_unet_zero_grad(u);
  if (!st) st = spx_unet_forward_loss(u, in, tg, N, h, w, y, &loss);
  if (!st && (dump("training output", y, N * 3 * hw) || dump("training loss", &loss, 1))) st = SPX_E_IO;
  if (!st) st = spx_unet_backward(u);
  if (!st) st = dump_unet(u, SPX_UNET_GRAD, "grad");
  if (!st) printf("  device bytes after training: %zu\n", spx_unet_device_bytes(u));
  if (!st) st = spx_unet_adam_step(u, 1e-3);
  if (!st) st = spx_unet_forward_loss(u, in, tg, N, h, w, NULL, &loss);
  if (!st && dump("loss after a step", &loss, 1)) st = SPX_E_IO;
  if (!st) st = spx_unet_forward(u, in, N, h, w, 0, y);
  snprintf(what, sizeof what, "eval output after a step");
  if (!st && dump(what, y, N * 3 * hw)) st = SPX_E_IO;
  spx_device_tensor_free(dt);
  spx_unet_destroy(u);
  free(in), free(tg), free(y);
  return st;
}

static int dump_losses(const char *tag, const spx_gan_losses *l) {
  float v[8] = {l->rec, l->vgg, l->gan, l->fm, l->g_total, l->d_fake, l->d_real, l->d_total};
  return dump(tag, v, 8);
}

static spx_status gan_case(spx_ctx *ctx, const char *vpath) {
  enum { N = 2, H = 37, W = 45 };
  size_t hw = (size_t)H * W;
  float in[N * 4 * H * W], tg[N * 3 * H * W];
  uint64_t s = 0x6a11;
  for (size_t k = 0; k < N * 4 * hw; k++) in[k] = bench_unif(&s);
  for (size_t k = 0; k < N * 3 * hw; k++) tg[k] = bench_unif(&s);
  spx_unet *g = NULL;
  spx_patchgan *d = NULL;
  spx_vgg *v = NULL;
  spx_gan_losses l;
  printf("gan step: unet width 8, patchgan ndf 8 x 2 scales, vgg19 width 4, %dx4x%dx%d\n", N, H, W);
  spx_status st = bench_write_vgg19(ctx, vpath, 4);
  if (!st) st = spx_vgg_open(ctx, vpath, &v);
  if (!st) st = spx_unet_create(ctx, 8, 0, 3, &g);
  if (!st) st = spx_patchgan_new(ctx, 8, 2, 9, &d);
  if (!st) st = spx_unet_gan_step(g, d, v, in, tg, N, H, W, 1e-3, 1e-3, &l);
  if (!st && dump_losses("gan step 1 losses", &l)) st = SPX_E_IO;
  if (!st) st = dump_unet(g, SPX_UNET_VALUE, "G after step 1");
  if (!st) st = spx_unet_gan_step(g, d, v, in, tg, N, H, W, 1e-3, 1e-3, &l);
  if (!st && dump_losses("gan step 2 losses", &l)) st = SPX_E_IO;
  if (!st) st = spx_unet_gan_step(g, d, NULL, in, tg, N, H, W, 1e-3, 1e-3, &l);
  if (!st && dump_losses("gan step 3 (L1) losses", &l)) st = SPX_E_IO;
  if (!st) st = spx_unet_vgg_step(g, v, in, tg, N, H, W, 1e-3, &l);
  if (!st && dump_losses("vgg step losses", &l)) st = SPX_E_IO;
  if (!st) st = dump_unet(g, SPX_UNET_VALUE, "G after step 4");
  spx_vgg_destroy(v);
  spx_patchgan_destroy(d);
  spx_unet_destroy(g);
  return st;
}

int main(int argc, char **argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: nn_bytecheck OUT.bin\n");
    return 2;
  }
  spx_ctx *ctx = NULL;
  char vpath[256];
  snprintf(vpath, sizeof vpath, "/tmp/nn_bytecheck_vgg_%d.safetensors", (int)getpid());
  if (!(out = fopen(argv[1], "wb"))) {
    fprintf(stderr, "nn_bytecheck: %s: cannot create\n", argv[1]);
    return 1;
  }
  spx_status st = spx_ctx_create(&ctx);
  if (!st) st = spx_device_open(ctx, NULL);
  /* Winograd on every 3x3 layer of 16+ channels, training and small images included */
  if (!st) st = spx_device_set_tunable(ctx, "CONV_WINO_MINC", 16);
  if (!st) st = spx_device_set_tunable(ctx, "CONV_WINO_TRAIN", 1);
  static const int cases[4][3] = {{16, 45, 83}, {16, 37, 150}, {8, 45, 83}, {8, 37, 150}};
  for (int i = 0; i < 4 && !st; i++) st = unet_case(ctx, cases[i][0], cases[i][1], cases[i][2]);
  if (!st) st = gan_case(ctx, vpath);
  remove(vpath);
  int bad = fclose(out) != 0;
  if (st || bad) {
    fprintf(stderr, "nn_bytecheck: %s\n", st && ctx ? spx_ctx_message(ctx) : "write failed");
    remove(argv[1]);
  }
  spx_ctx_destroy(ctx);
  return st || bad ? 1 : 0;
}
