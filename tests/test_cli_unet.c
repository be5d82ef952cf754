/* End to end: `smplpix train` and `smplpix render` on a tiny generated data set.
 *  - training runs, writes a checkpoint with the right step count, and lowers the loss on a
 *    learnable task (target = the input's RGB);
 *  - --resume continues exactly: 1 epoch + resume to 3 epochs == 3 epochs in one go (bit for bit:
 *    the data order depends only on the seed and the epoch);
 *  - render writes PNG / EXR / NPY, and the NPY equals the library's own eval forward;
 *  - bad input gives exit 1 with the file named, bad options exit 2.
 * Skipped (reported) if the tool was built without the render/train subcommands. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "nn_testutil.h"
#include "smplpix/npy.h"
#include "smplpix/smplpix.h"
#include "st_compare.h"

enum { H = 36, W = 40 }; /* bottleneck 2x2: batch norm can train on a batch of 1 */

static char dir[512];

static void path_in(char *out, size_t cap, const char *rel) { snprintf(out, cap, "%s/%s", dir, rel); }

static int run(const char *args, const char *log) { return spx_t_tool_log(args, log, 0); }

static int log_has(const char *log, const char *needle) {
  FILE *f = fopen(log, "r");
  if (!f) return 0;
  char buf[8192];
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  fclose(f);
  buf[n] = 0;
  return strstr(buf, needle) != NULL;
}

/* images: input RGB-D with smooth random content, target = input RGB */
static void make_pair(spx_ctx *ctx, const char *split, const char *name, int in_kind, int out_kind,
                      unsigned long long *s) {
  float in[H * W * 4], tg[H * W * 3];
  spx_t_smooth_pair(in, tg, H, W, s);
  char p[1024];
  snprintf(p, sizeof p, "%s/%s/input/%s.%s", dir, split, name, in_kind ? "exr" : "npy");
  if (in_kind) {
    spx_image img = {W, H, 4, in};
    CHECK_OK(ctx, spx_exr_write(ctx, p, &img));
  } else {
    int64_t shape[3] = {H, W, 4};
    CHECK_OK(ctx, spx_npy_save_f32(ctx, p, in, 3, shape));
  }
  snprintf(p, sizeof p, "%s/%s/output/%s.%s", dir, split, name, out_kind ? "npy" : "png");
  if (out_kind) {
    int64_t shape[3] = {H, W, 3};
    CHECK_OK(ctx, spx_npy_save_f32(ctx, p, tg, 3, shape));
  } else {
    spx_image img = {W, H, 3, tg};
    CHECK_OK(ctx, spx_png_write(ctx, p, &img));
  }
}

static void mk(const char *rel) {
  char p[1024];
  path_in(p, sizeof p, rel);
  mkdir(p, 0777);
}

static double parse_losses(const char *log, double *first, double *last) {
  FILE *f = fopen(log, "r");
  int n = 0;
  char line[512];
  while (f && fgets(line, sizeof line, f)) {
    const char *p = strstr(line, "train L1 ");
    if (!p) continue;
    double v = atof(p + 9);
    if (n++ == 0) *first = v;
    *last = v;
  }
  if (f) fclose(f);
  return n;
}

/* The last epoch's validation PSNR / SSIM (log of `train`) equal what `smplpix eval` gives for the
 * checkpoint's output on validation/input/v (clamped to [0, 1], as validation clamps it). */
static void check_validation_metrics(spx_ctx *ctx, const char *log, const char *w) {
  FILE *f = fopen(log, "r");
  char line[512];
  double psnr = NAN, ssim = NAN;
  while (f && fgets(line, sizeof line, f)) {
    const char *p = strstr(line, "validation L1 ");
    if (p && (p = strstr(p, "PSNR ")) && sscanf(p, "PSNR %lf dB, SSIM %lf", &psnr, &ssim) != 2) psnr = ssim = NAN;
  }
  if (f) fclose(f);
  CHECK_MSG(isfinite(psnr) && isfinite(ssim), "no 'PSNR x dB, SSIM y' on the validation line of %s", log);
  char in[1024], raw[1024], clamped[1024], tg[1024], out[1024], args[4096];
  path_in(in, sizeof in, "validation/input/v.exr");
  path_in(raw, sizeof raw, "v_raw.npy");
  path_in(clamped, sizeof clamped, "v_clamped.npy");
  path_in(tg, sizeof tg, "validation/output/v.png");
  path_in(out, sizeof out, "eval.txt");
  snprintf(args, sizeof args, "render --checkpoint \"%s\" --input \"%s\" --out \"%s\"", w, in, raw);
  CHECK(run(args, out) == 0);
  spx_array a;
  memset(&a, 0, sizeof a);
  CHECK_OK(ctx, spx_npy_load(ctx, raw, &a));
  if (a.ndim == 3 && a.dtype == SPX_F32) {
    float *v = a.data;
    for (int64_t k = 0; k < spx_array_numel(&a); k++) v[k] = v[k] < 0 ? 0 : v[k] > 1 ? 1 : v[k];
    CHECK_OK(ctx, spx_npy_save_f32(ctx, clamped, v, 3, a.shape));
  }
  spx_array_free(&a);
  char js[1024];
  path_in(js, sizeof js, "eval.json");
  snprintf(args, sizeof args, "eval --pred \"%s\" --target \"%s\" --json \"%s\"", clamped, tg, js);
  CHECK(run(args, out) == 0);
  double ep = NAN, es = NAN;
  f = fopen(js, "r");
  if (f && fgets(line, sizeof line, f)) sscanf(line, "{\"count\": 1, \"psnr\": %lf, \"ssim\": %lf", &ep, &es);
  if (f) fclose(f);
  CHECK_NEAR(ep, psnr, 0.00501, 0); /* train prints 2 decimals, the JSON has 10 digits */
  CHECK_NEAR(es, ssim, 0.0000501, 0); /* train prints 4 decimals */
}

static void test_train_render(void) {
  spx_t_path(dir, sizeof dir, "unetdata");
  char log[1024], args[4096], w1[1024], w3[1024], wr[1024], p[1024], q[1024];
  path_in(log, sizeof log, "log.txt");
  mkdir(dir, 0777);
  if (run("render --help", log) != 0) {
    fprintf(stderr, "  SKIP: %s has no render/train subcommands (apps/main.c table rows missing)\n", spx_t_tool());
    return;
  }
  spx_ctx *ctx = NULL;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  const char *dirs[] = {"train", "train/input", "train/output", "validation", "validation/input", "validation/output"};
  for (int i = 0; i < 6; i++) mk(dirs[i]);
  unsigned long long s = 5;
  make_pair(ctx, "train", "a", 0, 0, &s);
  make_pair(ctx, "train", "b", 1, 1, &s);
  make_pair(ctx, "train", "c", 0, 1, &s);
  make_pair(ctx, "train", "d", 1, 0, &s);
  make_pair(ctx, "train", "e", 0, 0, &s);
  make_pair(ctx, "validation", "v", 1, 0, &s);
  path_in(w1, sizeof w1, "w1.safetensors");
  path_in(w3, sizeof w3, "w3.safetensors");
  path_in(wr, sizeof wr, "wr.safetensors");

  /* 5 pairs, batch 2: 3 steps per epoch (the last batch has one image) */
  snprintf(args, sizeof args, "train --data \"%s\" --out \"%s\" --width 8 --batch 2 --epochs 3 --lr 3e-3 --seed 9", dir, w3);
  CHECK(run(args, log) == 0);
  CHECK(log_has(log, "validation L1"));
  double first = 0, last = 0;
  CHECK(parse_losses(log, &first, &last) == 3);
  CHECK_MSG(last < first, "training did not lower the loss: %g -> %g", first, last);
  spx_unet *u = NULL;
  CHECK(spx_device_open(ctx, NULL) == SPX_OK);
  CHECK_OK(ctx, spx_unet_load(ctx, w3, &u));
  if (u) CHECK(spx_unet_step(u) == 9 && spx_unet_width(u) == 8);

  /* resume: 1 epoch, then --resume to 3 epochs, equals the straight run */
  snprintf(args, sizeof args, "train --data \"%s\" --out \"%s\" --width 8 --batch 2 --epochs 1 --lr 3e-3 --seed 9", dir, wr);
  CHECK(run(args, log) == 0);
  snprintf(args, sizeof args, "train --data \"%s\" --out \"%s\" --batch 2 --epochs 3 --lr 3e-3 --seed 9 --resume", dir, wr);
  CHECK(run(args, log) == 0);
  CHECK_MSG(spx_t_same_safetensors(ctx, w3, wr), "resumed training differs from the straight run");
  check_validation_metrics(ctx, log, w3);

  /* render to npy equals the library's eval forward; png and exr outputs are written */
  path_in(p, sizeof p, "train/input/b.exr");
  path_in(q, sizeof q, "out.npy");
  snprintf(args, sizeof args, "render --checkpoint \"%s\" --input \"%s\" --out \"%s\"", w3, p, q);
  CHECK(run(args, log) == 0);
  spx_array a;
  spx_image img;
  memset(&a, 0, sizeof a);
  CHECK_OK(ctx, spx_npy_load(ctx, q, &a));
  if (a.ndim == 3 && a.shape[0] == H && a.shape[1] == W && a.shape[2] == 3 && a.dtype == SPX_F32) {
    CHECK_OK(ctx, spx_exr_read(ctx, p, &img));
    float in[4 * H * W], out[3 * H * W];
    for (int c = 0; c < 4; c++)
      for (int k = 0; k < H * W; k++) in[c * H * W + k] = img.data[k * img.channels + c];
    spx_image_free(&img);
    if (u) {
      CHECK_OK(ctx, spx_unet_forward(u, in, 1, H, W, 0, out));
      int same = 1;
      for (int c = 0; c < 3; c++)
        for (int k = 0; k < H * W; k++) same &= ((float *)a.data)[k * 3 + c] == out[c * H * W + k];
      CHECK_MSG(same, "render output differs from spx_unet_forward");
    }
  } else {
    CHECK_MSG(0, "render .npy output has the wrong shape");
  }
  spx_array_free(&a);
  path_in(q, sizeof q, "out.png");
  snprintf(args, sizeof args, "render --checkpoint \"%s\" --input \"%s\" --out \"%s\"", w3, p, q);
  CHECK(run(args, log) == 0);
  CHECK_OK(ctx, spx_png_read(ctx, q, &img));
  CHECK(img.width == W && img.height == H && img.channels == 3);
  spx_image_free(&img);
  path_in(q, sizeof q, "out.exr");
  snprintf(args, sizeof args, "render --checkpoint \"%s\" --input \"%s\" --out \"%s\" --sigmoid on", w3, p, q);
  CHECK(run(args, log) == 0);
  CHECK_OK(ctx, spx_exr_read(ctx, q, &img));
  int in01 = img.width == W && img.height == H;
  for (int k = 0; in01 && k < W * H; k++) /* R, G, B (the reader adds Z = 1) */
    for (int c = 0; c < 3; c++) in01 &= img.data[k * img.channels + c] > 0 && img.data[k * img.channels + c] < 1;
  CHECK_MSG(in01, "sigmoid output not in (0, 1)");
  spx_image_free(&img);

  /* errors */
  snprintf(args, sizeof args, "render --checkpoint \"%s\" --input \"%s\"", w3, p);
  CHECK(run(args, log) == 2);
  CHECK(run("train --data x --out y --bogus", log) == 2);
  snprintf(args, sizeof args, "render --checkpoint \"%s/missing.safetensors\" --input \"%s\" --out \"%s\"", dir, p, q);
  CHECK(run(args, log) == 1);
  CHECK(log_has(log, "missing.safetensors"));
  path_in(p, sizeof p, "train/output/e.png");
  remove(p);
  snprintf(args, sizeof args, "train --data \"%s\" --out \"%s\" --width 8 --steps 1", dir, w1);
  CHECK(run(args, log) == 1);
  CHECK(log_has(log, "e.npy") && log_has(log, "no target"));
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_train_render);
  return spx_test_summary();
}
