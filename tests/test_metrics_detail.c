/* Detail (lib/metrics/detail.c) against a plain computation written another way: the forward
 * differences of the whole image first (dx[y][x] = I(x+1,y) - I(x,y), dy likewise), then each
 * interior pixel's gradient from the two differences either side of it, then the means over the
 * region. Also values known by hand (a one-pixel stripe pattern scores 1 per pixel, a flat image
 * 0), the region rules (the mask's first channel; without a mask the target's non-white pixels;
 * the image border left out), a blur lowering the ratio, and the argument errors. */
#include "test.h"

#include "smplpix/metrics.h"

static spx_ctx *ctx;

static uint64_t rng_state = 0x9E3779B97F4A7C15ULL;
static double urand(void) {
  rng_state ^= rng_state << 13, rng_state ^= rng_state >> 7, rng_state ^= rng_state << 17;
  return (double)(rng_state >> 11) / 9007199254740992.0;
}

static spx_image make(int w, int h, int c) {
  spx_image img = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, w, h, c, &img));
  return img;
}

static double px(const spx_image *im, int x, int y, int c) {
  return im->data[((size_t)y * (size_t)im->width + (size_t)x) * (size_t)im->channels + (size_t)c];
}

/* The plain computation: mean gradient of img over the region's interior pixels. */
static double plain_mean(const spx_image *img, const spx_image *region, int64_t *count) {
  const int w = img->width, h = img->height;
  double *dx = calloc((size_t)w * (size_t)h * 3, sizeof(double)), *dy = calloc((size_t)w * (size_t)h * 3, sizeof(double));
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++)
      for (int c = 0; c < 3; c++) {
        size_t i = ((size_t)y * (size_t)w + (size_t)x) * 3 + (size_t)c;
        if (x + 1 < w) dx[i] = px(img, x + 1, y, c) - px(img, x, y, c);
        if (y + 1 < h) dy[i] = px(img, x, y + 1, c) - px(img, x, y, c);
      }
  double sum = 0;
  int64_t n = 0;
  for (int y = 1; y < h - 1; y++)
    for (int x = 1; x < w - 1; x++) {
      if (region && px(region, x, y, 0) == 0) continue;
      for (int c = 0; c < 3; c++) {
        size_t i = ((size_t)y * (size_t)w + (size_t)x) * 3 + (size_t)c, l = i - 3, u = i - (size_t)w * 3;
        sum += (fabs(dx[i]) + fabs(dx[l])) / 2 + (fabs(dy[i]) + fabs(dy[u])) / 2;
      }
      n++;
    }
  free(dx), free(dy);
  *count = n;
  return n ? sum / (3.0 * (double)n) : NAN;
}

/* Random pred / target on a white background (a random blob of foreground), 4 channels in pred. */
static void test_plain(void) {
  const int w = 37, h = 29;
  spx_image p = make(w, h, 4), t = make(w, h, 3), m = make(w, h, 2);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      int fg = (x - 18) * (x - 18) + (y - 14) * (y - 14) * 2 < 150;
      for (int c = 0; c < 3; c++) {
        t.data[((size_t)y * w + x) * 3 + (size_t)c] = fg ? (float)urand() : 1.0f;
        p.data[((size_t)y * w + x) * 4 + (size_t)c] = (float)urand();
      }
      p.data[((size_t)y * w + x) * 4 + 3] = (float)(x % 5); /* depth: ignored */
      m.data[((size_t)y * w + x) * 2] = (x + y) % 3 == 0;
      m.data[((size_t)y * w + x) * 2 + 1] = 1; /* second channel: ignored */
    }
  int64_t n_lib = 0, n_plain = 0;
  double g;
  /* one image, a region and the whole image */
  CHECK_OK(ctx, spx_image_gradient_mean(ctx, &p, &m, &g, &n_lib));
  CHECK_NEAR(g, plain_mean(&p, &m, &n_plain), 1e-12, 1e-12);
  CHECK(n_lib == n_plain && n_lib > 0);
  CHECK_OK(ctx, spx_image_gradient_mean(ctx, &t, NULL, &g, &n_lib));
  CHECK_NEAR(g, plain_mean(&t, NULL, &n_plain), 1e-12, 1e-12);
  CHECK(n_lib == (int64_t)(w - 2) * (h - 2));
  /* the ratio with a mask, and without one (the target's non-white pixels) */
  spx_detail d;
  CHECK_OK(ctx, spx_image_detail(ctx, &p, &t, &m, &d));
  int64_t k;
  double want = plain_mean(&p, &m, &k) / plain_mean(&t, &m, &k);
  CHECK_NEAR(d.ratio, want, 1e-12, 1e-12);
  CHECK(d.pixels == k);
  CHECK_NEAR(d.ratio_full, plain_mean(&p, NULL, &k) / plain_mean(&t, NULL, &k), 1e-12, 1e-12);
  spx_image fg = make(w, h, 1);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) fg.data[(size_t)y * w + x] = px(&t, x, y, 0) < 1 || px(&t, x, y, 1) < 1 || px(&t, x, y, 2) < 1;
  CHECK_OK(ctx, spx_image_detail(ctx, &p, &t, NULL, &d));
  CHECK_NEAR(d.ratio, plain_mean(&p, &fg, &k) / plain_mean(&t, &fg, &k), 1e-12, 1e-12);
  CHECK_NEAR(d.pred, plain_mean(&p, &fg, &k), 1e-12, 1e-12);
  CHECK(d.pixels == k && k > 20);
  spx_image fm = {0};
  CHECK_OK(ctx, spx_image_foreground(ctx, &t, &fm));
  CHECK(fm.channels == 1 && !memcmp(fm.data, fg.data, sizeof(float) * (size_t)w * h));
  spx_image_free(&p), spx_image_free(&t), spx_image_free(&m), spx_image_free(&fg), spx_image_free(&fm);
}

/* Values by hand: one-pixel vertical stripes (columns alternately 0 and 1): every interior pixel
 * has |dx| = 1 on both sides and dy = 0, so the mean gradient is 1; a flat image 0; a 3-tap box
 * blur along x of the stripes keeps 1/3 of the contrast: ratio 1/3. */
static void test_by_hand(void) {
  const int w = 20, h = 16;
  spx_image s = make(w, h, 3), f = make(w, h, 3), b = make(w, h, 3);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++)
      for (int c = 0; c < 3; c++) {
        size_t i = ((size_t)y * w + x) * 3 + (size_t)c;
        s.data[i] = (float)(x % 2);
        f.data[i] = 0.25f;
        b.data[i] = x % 2 ? 1.0f / 3 : 2.0f / 3; /* (0 + 1 + 0) / 3 and (1 + 0 + 1) / 3 */
      }
  double g;
  CHECK_OK(ctx, spx_image_gradient_mean(ctx, &s, NULL, &g, NULL));
  CHECK_NEAR(g, 1.0, 1e-12, 0);
  CHECK_OK(ctx, spx_image_gradient_mean(ctx, &f, NULL, &g, NULL));
  CHECK(g == 0);
  spx_detail d;
  CHECK_OK(ctx, spx_image_detail(ctx, &b, &s, NULL, &d));
  CHECK_NEAR(d.ratio, 1.0 / 3, 1e-6, 0);
  CHECK_NEAR(d.ratio_full, 1.0 / 3, 1e-6, 0);
  CHECK_OK(ctx, spx_image_detail(ctx, &s, &s, NULL, &d));
  CHECK(d.ratio == 1 && d.ratio_full == 1);
  /* a flat target: the ratio is undefined */
  CHECK_OK(ctx, spx_image_detail(ctx, &s, &f, NULL, &d));
  CHECK(isnan(d.ratio) && isnan(d.ratio_full));
  /* the border is left out: a mask of the border ring only counts nothing */
  spx_image ring = make(w, h, 1);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) ring.data[(size_t)y * w + x] = x == 0 || y == 0 || x == w - 1 || y == h - 1;
  int64_t n = -1;
  CHECK_OK(ctx, spx_image_gradient_mean(ctx, &s, &ring, &g, &n));
  CHECK(n == 0 && isnan(g));
  spx_image_free(&s), spx_image_free(&f), spx_image_free(&b), spx_image_free(&ring);
}

static void test_errors(void) {
  spx_image a = make(20, 12, 3), b = make(12, 20, 3), g = make(20, 12, 1);
  spx_detail d;
  double v;
  CHECK(spx_image_detail(ctx, &a, &b, NULL, &d) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "20x12") && strstr(spx_ctx_message(ctx), "12x20"));
  CHECK(spx_image_detail(ctx, &a, &a, &b, &d) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "mask") != NULL);
  CHECK(spx_image_detail(ctx, &g, &a, NULL, &d) == SPX_E_ARG); /* one channel */
  CHECK(spx_image_gradient_mean(ctx, &a, &b, &v, NULL) == SPX_E_ARG);
  CHECK(spx_image_detail(ctx, NULL, &a, NULL, &d) == SPX_E_ARG);
  a.data[3 * 25 + 1] = NAN;
  CHECK(spx_image_gradient_mean(ctx, &a, NULL, &v, NULL) == SPX_E_NUMERIC);
  spx_image_free(&a), spx_image_free(&b), spx_image_free(&g);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_plain), SPX_TEST(test_by_hand), SPX_TEST(test_errors)};
  return spx_t_main_ctx(&ctx, 0, tests, 3);
}
