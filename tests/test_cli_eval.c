/* `smplpix eval` end to end: two files (values from the scikit-image goldens), two folders matched
 * by name with mixed extensions (.png/.exr/.npy), --per-image, --json (null for inf and for values
 * not asked for), --mask (file and folder), --lpips (the lpips-package golden), LPIPS from the
 * cache of `make weights` without --lpips (and --no-lpips); then every error:
 * one line naming the file, exit 1 (2 for usage), no JSON written. */
#include <unistd.h>

#include <cjson/cJSON.h>

#include "cli_test.h"
#include "lpips_weights.h"
#include "smplpix/smplpix.h"

static spx_ctx *ctx;

static void src(char *p, size_t cap, const char *name) { snprintf(p, cap, "%s/metrics/%s.npy", SPX_TEST_DATA, name); }

static spx_image load_src(const char *name) {
  char p[1024];
  src(p, sizeof p, name);
  spx_array a;
  spx_image img = {0};
  float *f = NULL;
  if (spx_npy_load(ctx, p, &a) == SPX_OK) {
    if (spx_array_to_f32(ctx, &a, &f) == SPX_OK)
      img = (spx_image){(int32_t)a.shape[1], (int32_t)a.shape[0], a.ndim == 3 ? (int32_t)a.shape[2] : 1, f};
    spx_array_free(&a);
  }
  CHECK(img.data != NULL);
  return img;
}

/* Copy a golden .npy into dir/rel. */
static void put(const char *name, const char *rel) {
  char a[1024], cmd[2600];
  src(a, sizeof a, name);
  snprintf(cmd, sizeof cmd, "cp '%s' '%s/%s'", a, dir, rel);
  CHECK(spx_t_system(cmd) == 0);
}

/* The one-channel image *m written as an [height, width] .npy mask dir/rel, then freed. */
static void put_mask(spx_image *m, const char *rel) {
  char p[700];
  path_of(p, sizeof p, rel);
  int64_t shape[2] = {m->height, m->width};
  CHECK_OK(ctx, spx_npy_save_f32(ctx, p, m->data, 2, shape));
  spx_image_free(m);
}

static char *slurp(const char *name) {
  char p[700];
  path_of(p, sizeof p, name);
  FILE *f = fopen(p, "rb");
  if (!f) return NULL;
  char *buf = calloc(1, 1 << 16);
  if (buf) fread(buf, 1, (1 << 16) - 1, f);
  fclose(f);
  return buf;
}

static int out_has(const char *needle) {
  char *s = slurp("out.txt");
  int ok = s && strstr(s, needle);
  if (!ok) fprintf(stderr, "  stdout was: %s\n  (looking for %s)\n", s ? s : "(none)", needle);
  free(s);
  return ok;
}

static int out_lacks(const char *needle) {
  char *s = slurp("out.txt");
  int ok = s && !strstr(s, needle);
  if (!ok) fprintf(stderr, "  stdout was: %s\n  (it should not hold %s)\n", s ? s : "(none)", needle);
  free(s);
  return ok;
}

static cJSON *json(const char *name) {
  char *s = slurp(name);
  cJSON *j = s ? cJSON_Parse(s) : NULL;
  free(s);
  return j;
}

static double num(const cJSON *o, const char *key) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}
static int is_null(const cJSON *o, const char *key) { return cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(o, key)); }

static void test_files(void) {
  put("odd_pred", "p.npy");
  put("odd_target", "t.npy");
  CHECK(tool("eval --pred p.npy --target t.npy --json r.json") == 0);
  CHECK(out_has("mean over 1 images: PSNR 20.498 dB, SSIM 0.9452; detail ")); /* expected.txt: 20.4975, 0.94523 */
  cJSON *j = json("r.json");
  CHECK(j != NULL);
  CHECK(num(j, "count") == 1 && is_null(j, "lpips"));
  CHECK_NEAR(num(j, "psnr"), 20.497547425670323, 1e-8, 0);
  CHECK_NEAR(num(j, "ssim"), 0.94523415120003795, 1e-9, 0);
  const cJSON *im = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(j, "images"), 0);
  CHECK(im && !strcmp(cJSON_GetObjectItemCaseSensitive(im, "name")->valuestring, "p"));
  CHECK_NEAR(num(im, "ssim"), 0.94523415120003795, 1e-9, 0);
  { /* detail without a mask: over the target's non-background pixels, as the library computes it */
    spx_image op = load_src("odd_pred"), ot = load_src("odd_target");
    spx_detail d;
    CHECK_OK(ctx, spx_image_detail(ctx, &op, &ot, NULL, &d));
    CHECK(isfinite(d.ratio) && d.pixels > 0);
    CHECK_NEAR(num(j, "detail"), d.ratio, 1e-9, 0);
    CHECK_NEAR(num(im, "detail"), d.ratio, 1e-9, 0);
    CHECK_NEAR(num(j, "detail_full"), d.ratio_full, 1e-9, 0);
    char line[96];
    snprintf(line, sizeof line, "; detail %.3f (non-background), %.3f (full image)\n", d.ratio, d.ratio_full);
    CHECK(out_has(line));
    spx_image_free(&op), spx_image_free(&ot);
  }
  cJSON_Delete(j);
  /* identical images: inf on the line, null in the JSON */
  put("identical_pred", "ip.npy");
  put("identical_target", "it.npy");
  CHECK(tool("eval --pred ip.npy --target it.npy --json r2.json --per-image") == 0);
  CHECK(out_has("ip: PSNR inf dB, SSIM 1.0000; detail 1.000 (non-background), 1.000 (full image)\n"
                "mean over 1 images: PSNR inf dB, SSIM 1.0000; detail 1.000"));
  j = json("r2.json");
  CHECK(j && is_null(j, "psnr") && num(j, "ssim") == 1);
  cJSON_Delete(j);
  /* a file mask */
  put("masked_pred", "mp.npy");
  put("masked_target", "mt.npy");
  put("masked_mask", "mm.npy");
  CHECK(tool("eval --pred mp.npy --target mt.npy --mask mm.npy --json r3.json") == 0);
  CHECK(out_has("mean over 1 images: PSNR 27.498 dB, SSIM 0.8088; masked: PSNR 22.074 dB, SSIM 0.6483; detail "));
  j = json("r3.json");
  CHECK_NEAR(num(j, "psnr_masked"), 22.074080173902484, 1e-8, 0);
  CHECK_NEAR(num(j, "ssim_masked"), 0.64834196113444498, 1e-9, 0);
  cJSON_Delete(j);
  /* constant images (tests/data/metrics/expected.txt: 7.9588, 0.72419) */
  put("constant_pred", "cp.npy");
  put("constant_target", "ct.npy");
  CHECK(tool("eval --pred cp.npy --target ct.npy") == 0);
  CHECK(out_has("mean over 1 images: PSNR 7.959 dB, SSIM 0.7242; detail "));
  /* a mask whose foreground is only at the border: masked SSIM undefined, n/a and null */
  spx_image bm = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, 19, 16, 1, &bm));
  bm.data[0] = 1;
  put_mask(&bm, "corner.npy");
  CHECK(tool("eval --pred cp.npy --target ct.npy --mask corner.npy --json rc.json") == 0);
  CHECK(out_has("; masked: PSNR 7.959 dB, SSIM n/a; detail "));
  j = json("rc.json");
  CHECK(j && is_null(j, "ssim_masked") && fabs(num(j, "psnr_masked") - 7.9588) < 1e-4);
  cJSON_Delete(j);
  CHECK(tool("eval --help") == 0 && out_has("--pred P --target T"));
}

/* two folders, matched by name with different extensions, and a mask folder */
static void test_folders(void) {
  spx_t_system("true");
  char cmd[700];
  snprintf(cmd, sizeof cmd, "cd '%s' && rm -rf P T M && mkdir P T M", dir);
  CHECK(spx_t_system(cmd) == 0);
  spx_image op = load_src("odd_pred"), ot = load_src("odd_target"), mp = load_src("masked_pred"),
            mt = load_src("masked_target"), mm = load_src("masked_mask");
  char p[700];
  path_of(p, sizeof p, "P/a.png");
  CHECK_OK(ctx, spx_png_write(ctx, p, &op)); /* 8-bit: compare against what it reads back as */
  spx_image opq = {0};
  CHECK_OK(ctx, spx_png_read(ctx, p, &opq));
  path_of(p, sizeof p, "T/a.exr");
  CHECK_OK(ctx, spx_exr_write(ctx, p, &ot));
  put("masked_pred", "P/b.npy");
  put("masked_target", "T/b.npy");
  /* masks: a.png all foreground, b.npy the blob */
  spx_image full = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, op.width, op.height, 1, &full));
  for (int i = 0; i < op.width * op.height; i++) full.data[i] = 1;
  path_of(p, sizeof p, "M/a.png");
  CHECK_OK(ctx, spx_png_write(ctx, p, &full));
  put("masked_mask", "M/b.npy");
  spx_metrics ra, rb;
  CHECK_OK(ctx, spx_image_metrics(ctx, &opq, &ot, &full, &ra));
  CHECK_OK(ctx, spx_image_metrics(ctx, &mp, &mt, &mm, &rb));
  CHECK(tool("eval --pred P --target T --mask M --per-image --json f.json") == 0);
  char line[256];
  snprintf(line, sizeof line, "a: PSNR %.3f dB, SSIM %.4f; masked: PSNR %.3f dB, SSIM %.4f; detail ", ra.psnr, ra.ssim,
           ra.psnr_fg, ra.ssim_fg);
  CHECK(out_has(line));
  snprintf(line, sizeof line, "mean over 2 images: PSNR %.3f dB, SSIM %.4f;", (ra.psnr + rb.psnr) / 2,
           (ra.ssim + rb.ssim) / 2);
  CHECK(out_has(line));
  cJSON *j = json("f.json");
  CHECK(j && num(j, "count") == 2 && is_null(j, "lpips"));
  CHECK_NEAR(num(j, "psnr"), (ra.psnr + rb.psnr) / 2, 1e-8, 0);
  CHECK_NEAR(num(j, "ssim_masked"), (ra.ssim_fg + rb.ssim_fg) / 2, 1e-9, 0);
  const cJSON *ims = cJSON_GetObjectItemCaseSensitive(j, "images");
  CHECK(cJSON_GetArraySize(ims) == 2);
  const cJSON *b = cJSON_GetArrayItem(ims, 1);
  CHECK(b && !strcmp(cJSON_GetObjectItemCaseSensitive(b, "name")->valuestring, "b"));
  CHECK_NEAR(num(b, "psnr_masked"), 22.074080173902484, 1e-8, 0);
  CHECK(b && is_null(b, "lpips"));
  /* detail inside the masks, per image and the mean */
  spx_detail da, db;
  CHECK_OK(ctx, spx_image_detail(ctx, &opq, &ot, &full, &da));
  CHECK_OK(ctx, spx_image_detail(ctx, &mp, &mt, &mm, &db));
  CHECK(da.ratio != db.ratio);
  CHECK_NEAR(num(cJSON_GetArrayItem(ims, 0), "detail"), da.ratio, 1e-9, 0);
  CHECK_NEAR(num(b, "detail"), db.ratio, 1e-9, 0);
  CHECK_NEAR(num(j, "detail"), (da.ratio + db.ratio) / 2, 1e-9, 0);
  CHECK_NEAR(num(j, "detail_full"), (da.ratio_full + db.ratio_full) / 2, 1e-9, 0);
  snprintf(line, sizeof line, "; detail %.3f (mask), %.3f (full image)\nmean over 2 images:", db.ratio, db.ratio_full);
  CHECK(out_has(line));
  cJSON_Delete(j);
  spx_image_free(&op), spx_image_free(&ot), spx_image_free(&mp), spx_image_free(&mt), spx_image_free(&mm);
  spx_image_free(&opq), spx_image_free(&full);
}

static void test_lpips(void) {
  char w[700];
  path_of(w, sizeof w, "lp.safetensors");
  CHECK(spx_t_lpips_weights(ctx, w, NULL, NULL));
  put("lp_random_pred", "lpp.npy");
  put("lp_random_target", "lpt.npy");
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --lpips lp.safetensors --json l.json") == 0);
  CHECK(out_has(", LPIPS 0.1852; detail "));
  cJSON *j = json("l.json");
  CHECK_NEAR(num(j, "lpips"), 0.18518037343347837, 0, 1e-5); /* tests/data/metrics/lpips_expected.txt */
  CHECK(j && !cJSON_GetObjectItem(j, "lpips_masked")); /* no mask, no masked value */
  cJSON_Delete(j);
  /* with a mask: the lpips package's spatial map averaged over it (lpips_masked_expected.txt: the
   * rectangle x in [W/4, 3W/4), y in [H/5, 4H/5) of the 40x48 pair) */
  spx_image rect = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, 40, 48, 1, &rect));
  for (int y = 0; y < 48; y++)
    for (int x = 0; x < 40; x++) rect.data[y * 40 + x] = x >= 10 && x < 30 && y >= 9 && y < 38;
  put_mask(&rect, "lprect.npy");
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --mask lprect.npy --lpips lp.safetensors --json lm.json") == 0);
  CHECK(out_has(", LPIPS 0.1852; masked: PSNR ") && out_has(", LPIPS 0.1842; detail "));
  j = json("lm.json");
  CHECK_NEAR(num(j, "lpips"), 0.18518037343347837, 0, 1e-5);
  CHECK_NEAR(num(j, "lpips_masked"), 0.18420818097205149, 0, 1e-5);
  cJSON_Delete(j);
  path_of(w, sizeof w, "lpbad.safetensors");
  CHECK(spx_t_lpips_weights(ctx, w, "net.slice4.8.bias", NULL));
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --lpips lpbad.safetensors --json lb.json") == 1);
  CHECK(err_one_line_with("lpbad.safetensors: tensor net.slice4.8.bias is missing"));
  CHECK(!exists("lb.json"));
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --lpips nothere.safetensors") == 1);
  CHECK(err_one_line_with("nothere.safetensors"));
  put("odd_pred", "small.npy");
  CHECK(tool("eval --pred small.npy --target small.npy --lpips lp.safetensors") == 0); /* 53x37 >= 31x31 */
  put("constant_pred", "c1.npy");
  CHECK(tool("eval --pred c1.npy --target c1.npy --lpips lp.safetensors --json lc.json") == 1);
  CHECK(err_one_line_with("31x31"));
  CHECK(!exists("lc.json"));
}

/* LPIPS without --lpips: the weights `make weights` puts in ${SPX_CACHE_DIR}/weights (here the
 * golden's random AlexNet); n/a for images too small; --no-lpips; a damaged cached file. */
static void test_cached_lpips(void) {
  char cache[700], w[800], cmd[3400];
  const char *old = getenv("SPX_CACHE_DIR");
  char *keep = old ? strdup(old) : NULL;
  path_of(cache, sizeof cache, "cache");
  snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s/weights'", cache, cache);
  CHECK(spx_t_system(cmd) == 0);
  snprintf(w, sizeof w, "%s/weights/lpips_alex.safetensors", cache);
  setenv("SPX_CACHE_DIR", cache, 1);
  put("lp_random_pred", "lpp.npy");
  put("lp_random_target", "lpt.npy");
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --json c.json") == 0); /* without the file */
  CHECK(out_lacks("LPIPS"));
  CHECK(spx_t_lpips_weights(ctx, w, NULL, NULL));
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --json c.json") == 0);
  CHECK(out_has(", LPIPS 0.1852; detail "));
  cJSON *j = json("c.json");
  CHECK_NEAR(num(j, "lpips"), 0.18518037343347837, 0, 1e-5);
  cJSON_Delete(j);
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --no-lpips --json c.json") == 0);
  CHECK(out_lacks("LPIPS"));
  j = json("c.json");
  CHECK(j && is_null(j, "lpips") && num(j, "psnr") > 0);
  cJSON_Delete(j);
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --no-lpips --lpips lp.safetensors") == 2);
  put("constant_pred", "c1.npy"); /* smaller than 31x31: n/a with the cached weights */
  CHECK(tool("eval --pred c1.npy --target c1.npy --json c.json") == 0);
  CHECK(out_has(", LPIPS n/a"));
  j = json("c.json");
  CHECK(j && is_null(j, "lpips"));
  cJSON_Delete(j);
  /* a damaged cached file: one line naming it, no JSON */
  snprintf(cmd, sizeof cmd, "head -c 5000 '%s' > '%s.part' && mv '%s.part' '%s'", w, w, w, w);
  CHECK(spx_t_system(cmd) == 0);
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --json cd.json") == 1);
  CHECK(err_one_line_with("lpips_alex.safetensors") && err_one_line_with("make weights"));
  CHECK(!exists("cd.json"));
  CHECK(tool("eval --pred lpp.npy --target lpt.npy --no-lpips") == 0);
  if (keep) setenv("SPX_CACHE_DIR", keep, 1);
  else unsetenv("SPX_CACHE_DIR");
  free(keep);
}

static void fails(const char *args, int code, const char *needle) {
  CHECK_MSG(tool(args) == code, "%s", args);
  CHECK_MSG(err_one_line_with(needle), "%s", args);
  CHECK_MSG(!exists("bad.json"), "%s left bad.json", args);
}

static void test_errors(void) {
  char cmd[700];
  snprintf(cmd, sizeof cmd, "cd '%s' && rm -rf E1 E2 E3 EM && mkdir E1 E2 E3 EM", dir);
  CHECK(spx_t_system(cmd) == 0);
  put("random_pred", "r32.npy");
  put("odd_target", "o53.npy");
  fails("eval --pred r32.npy --target o53.npy --json bad.json", 1, "r32.npy is 32x32 but o53.npy is 53x37");
  fails("eval --pred gone.npy --target o53.npy --json bad.json", 1, "gone.npy");
  write_text("junk.png", "not a png");
  fails("eval --pred junk.png --target o53.npy --json bad.json", 1, "junk.png");
  write_text("x.txt", "text");
  fails("eval --pred x.txt --target o53.npy --json bad.json", 1, "x.txt: unknown image type");
  /* folders: a name on one side only, each way; a missing mask; two files with one name */
  put("random_pred", "E1/a.npy");
  put("random_target", "E2/a.npy");
  put("random_pred", "E1/z.npy");
  fails("eval --pred E1 --target E2 --json bad.json", 1, "E1/z.npy has no target in E2");
  put("random_target", "E2/z.npy");
  put("random_target", "E2/q.npy");
  fails("eval --pred E1 --target E2 --json bad.json", 1, "E2/q.npy has no prediction in E1");
  snprintf(cmd, sizeof cmd, "rm '%s/E2/q.npy'", dir);
  spx_t_system(cmd);
  CHECK(tool("eval --pred E1 --target E2") == 0);
  put("masked_mask", "EM/a.npy");
  fails("eval --pred E1 --target E2 --mask EM --json bad.json", 1, "E1/z.npy has no mask in EM");
  put("random_pred", "E1/z.png.npy"); /* stem "z.png" differs from "z": its own pair */
  put("random_target", "E2/z.png.npy");
  put("random_pred", "E1/a.exr");
  fails("eval --pred E1 --target E2 --json bad.json", 1, "both a.exr and a.npy have the name a");
  fails("eval --pred E3 --target E2 --json bad.json", 1, "E3: no .png, .exr or .npy images");
  fails("eval --pred E1 --target o53.npy --json bad.json", 1, "E1 is a folder but o53.npy is a file");
  fails("eval --pred r32.npy --target r32.npy --mask E1 --json bad.json", 1, "E1 is a folder");
  /* masks: wrong size, no foreground */
  put("masked_mask", "m41.npy");
  fails("eval --pred r32.npy --target r32.npy --mask m41.npy --json bad.json", 1, "m41.npy is 45x41 but r32.npy is 32x32");
  spx_image z = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, 32, 32, 1, &z));
  char p[700];
  path_of(p, sizeof p, "zero.npy");
  int64_t shape[2] = {32, 32};
  CHECK_OK(ctx, spx_npy_save_f32(ctx, p, z.data, 2, shape));
  fails("eval --pred r32.npy --target r32.npy --mask zero.npy --json bad.json", 1, "zero.npy: the mask has no foreground");
  /* a one-channel image, an image below the SSIM window, NaN */
  fails("eval --pred zero.npy --target zero.npy --json bad.json", 1, "zero.npy: 1 channel, expected an RGB image");
  spx_image_free(&z);
  CHECK_OK(ctx, spx_image_alloc(ctx, 10, 10, 3, &z));
  path_of(p, sizeof p, "tiny.npy");
  int64_t s3[3] = {10, 10, 3};
  CHECK_OK(ctx, spx_npy_save_f32(ctx, p, z.data, 3, s3));
  fails("eval --pred tiny.npy --target tiny.npy --json bad.json", 1, "smaller than the 11x11 SSIM window");
  spx_image_free(&z);
  /* usage */
  fails("eval --pred r32.npy --json bad.json", 2, "--pred and --target are required");
  fails("eval --pred r32.npy --target r32.npy --bogus", 2, "unknown option --bogus");
  fails("eval --pred r32.npy --target", 2, "missing value for --target");
  /* an existing JSON is left as it was when the run fails */
  write_text("keep.json", "old");
  CHECK(tool("eval --pred r32.npy --target o53.npy --json keep.json") == 1);
  char *s = slurp("keep.json");
  CHECK(s && !strcmp(s, "old"));
  free(s);
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_files), SPX_TEST(test_folders), SPX_TEST(test_lpips),
                               SPX_TEST(test_cached_lpips), SPX_TEST(test_errors)};
  snprintf(dir, sizeof dir, "%s", spx_t_tmpdir());
  return spx_t_main_ctx(&ctx, 0, tests, 5);
}
