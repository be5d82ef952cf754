/* bench_bn_stats: the batch-norm statistics a trained UNet uses at eval, for the "what blurs"
 * measurements of benchmarks/blur_variants.sh (benchmarks/RESULTS.md).
 *   bench_bn_stats recalibrate --checkpoint W --inputs DIR --out W2 [--passes P] [--batch B]
 *       the running statistics estimated again at W's final weights: P passes (default 4) of
 *       training-mode forwards (batch statistics; each updates the running mean and variance with
 *       the network's momentum, 0.1) over the RGB-D inputs of DIR (.exr / .npy, sorted by name) in
 *       batches of B (default 4), no weight changes; W2 = W's weights with those statistics.
 *       During training the running statistics trail the weights (each an average of batches
 *       seen at older weights): this removes the lag.
 *   bench_bn_stats render --checkpoint W --inputs DIR --out-dir O [--batch B]
 *       every input of DIR through W with batch statistics instead of the running ones (a
 *       training-mode forward of B inputs at a time, default 1: each image normalised by its own
 *       statistics), written as O/NAME.png (clamped to [0, 1]).
 * Bad input: one line naming the file, exit 1. */
#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/smplpix.h"

static int fail(const char *what, const char *msg) {
  fprintf(stderr, "bench_bn_stats: error: %s%s%s\n", what, msg[0] ? ": " : "", msg);
  return 1;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* The .exr / .npy files of dir, sorted; *n of them. NULL on failure (printed). */
static char **list_inputs(const char *dir, int *n) {
  DIR *d = opendir(dir);
  if (!d) return fail(dir, strerror(errno)), NULL;
  char **v = NULL;
  int cap = 0;
  *n = 0;
  struct dirent *e;
  while ((e = readdir(d))) {
    const char *dot = strrchr(e->d_name, '.');
    if (e->d_name[0] == '.' || !dot || (strcmp(dot, ".exr") && strcmp(dot, ".npy"))) continue;
    if (*n == cap) {
      char **nv = realloc(v, sizeof *v * (size_t)(cap = cap ? 2 * cap : 64));
      if (!nv) break;
      v = nv;
    }
    size_t len = strlen(dir) + strlen(e->d_name) + 2;
    if (!(v[*n] = malloc(len))) break;
    snprintf(v[(*n)++], len, "%s/%s", dir, e->d_name);
  }
  closedir(d);
  if (!*n) return fail(dir, "no .exr or .npy inputs"), free(v), NULL;
  qsort(v, (size_t)*n, sizeof *v, cmp_str);
  return v;
}

/* Inputs [i0, i0 + nb) of names as an NCHW batch in x (h, w from the first; all must match). */
static int load_batch(spx_ctx *ctx, char **names, int i0, int nb, int *h, int *w, float **x) {
  for (int k = 0; k < nb; k++) {
    spx_image im = {0};
    if (spx_image_read(ctx, names[i0 + k], &im)) return fail(names[i0 + k], spx_ctx_message(ctx));
    if (im.channels < 4) return spx_image_free(&im), fail(names[i0 + k], "not an RGB-D (4-channel) input");
    if (!*x) {
      *h = im.height, *w = im.width;
      if (!(*x = malloc(sizeof(float) * 4 * (size_t)nb * (size_t)*h * (size_t)*w)))
        return spx_image_free(&im), fail("out of memory", "");
    }
    if (im.height != *h || im.width != *w) return spx_image_free(&im), fail(names[i0 + k], "another size than the first");
    size_t hw = (size_t)*h * (size_t)*w;
    for (size_t p = 0; p < hw; p++)
      for (int c = 0; c < 4; c++) (*x)[((size_t)k * 4 + (size_t)c) * hw + p] = im.data[p * (size_t)im.channels + (size_t)c];
    spx_image_free(&im);
  }
  return 0;
}

/* The output of image k of an NCHW batch y as O/NAME.png. */
static int write_png(spx_ctx *ctx, const char *outdir, const char *in_path, const float *y, int k, int h, int w) {
  const char *base = strrchr(in_path, '/');
  base = base ? base + 1 : in_path;
  char path[4200];
  snprintf(path, sizeof path, "%s/%.*s.png", outdir, (int)(strrchr(base, '.') - base), base);
  spx_image im = {0};
  if (spx_image_alloc(ctx, w, h, 3, &im)) return fail(path, spx_ctx_message(ctx));
  size_t hw = (size_t)h * (size_t)w;
  for (size_t p = 0; p < hw; p++)
    for (int c = 0; c < 3; c++) {
      float v = y[((size_t)k * 3 + (size_t)c) * hw + p];
      im.data[p * 3 + (size_t)c] = v < 0 ? 0 : v > 1 ? 1 : v;
    }
  int rc = spx_png_write(ctx, path, &im) ? fail(path, spx_ctx_message(ctx)) : 0;
  spx_image_free(&im);
  return rc;
}

int main(int argc, char **argv) {
  const char *mode = argc > 1 ? argv[1] : "", *ckpt = NULL, *inputs = NULL, *out = NULL;
  long passes = 4, batch = -1;
  for (int i = 2; i + 1 < argc; i += 2) {
    if (!strcmp(argv[i], "--checkpoint")) ckpt = argv[i + 1];
    else if (!strcmp(argv[i], "--inputs")) inputs = argv[i + 1];
    else if (!strcmp(argv[i], "--out") || !strcmp(argv[i], "--out-dir")) out = argv[i + 1];
    else if (!strcmp(argv[i], "--passes")) passes = strtol(argv[i + 1], NULL, 10);
    else if (!strcmp(argv[i], "--batch")) batch = strtol(argv[i + 1], NULL, 10);
    else return fail(argv[i], "unknown option"), 2;
  }
  int recal = !strcmp(mode, "recalibrate");
  if ((!recal && strcmp(mode, "render")) || !ckpt || !inputs || !out || passes < 1 || (argc % 2)) {
    fprintf(stderr, "usage: bench_bn_stats recalibrate --checkpoint W --inputs DIR --out W2 [--passes P] [--batch B]\n"
                    "       bench_bn_stats render --checkpoint W --inputs DIR --out-dir O [--batch B]\n");
    return 2;
  }
  if (batch < 0) batch = recal ? 4 : 1;
  if (batch < 1) return fail("--batch", "must be at least 1"), 2;
  spx_ctx *ctx = NULL;
  spx_unet *u = NULL;
  int n = 0, rc = 1, h = 0, w = 0;
  float *x = NULL, *y = NULL;
  char **names = NULL;
  if (spx_ctx_create(&ctx)) return fail("out of memory", "");
  if (spx_device_open(ctx, NULL) || spx_unet_load(ctx, ckpt, &u)) {
    rc = fail(ckpt, spx_ctx_message(ctx));
    goto done;
  }
  if (!(names = list_inputs(inputs, &n))) goto done;
  for (long p = 0; p < (recal ? passes : 1); p++)
    for (int i0 = 0; i0 < n; i0 += (int)batch) {
      int nb = n - i0 < batch ? n - i0 : (int)batch;
      free(x), free(y), x = y = NULL;
      if (load_batch(ctx, names, i0, nb, &h, &w, &x)) goto done;
      if (!recal && !(y = malloc(sizeof(float) * 3 * (size_t)nb * (size_t)h * (size_t)w))) {
        rc = fail("out of memory", "");
        goto done;
      }
      if (spx_unet_forward(u, x, nb, h, w, 1, y)) {
        rc = fail(ckpt, spx_ctx_message(ctx));
        goto done;
      }
      for (int k = 0; !recal && k < nb; k++)
        if (write_png(ctx, out, names[i0 + k], y, k, h, w)) goto done;
    }
  if (recal && spx_unet_save(u, out, 0)) {
    rc = fail(out, spx_ctx_message(ctx));
    goto done;
  }
  printf("%s: %d inputs%s\n", recal ? "recalibrated" : "rendered with batch statistics", n, recal ? "" : "");
  rc = 0;
done:
  for (int i = 0; i < n && names; i++) free(names[i]);
  free(names), free(x), free(y);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
  return rc;
}
