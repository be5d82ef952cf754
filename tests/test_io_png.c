/* PNG I/O: exact round trips of 8-bit values, clamping/rounding, and reading gray, gray+alpha,
 * RGBA, palette (with and without transparency), 1-bit, 16-bit and interlaced files that the
 * test writes with libpng directly. */
#include <png.h>
#include <setjmp.h>
#include <string.h>
#include <zlib.h>

#include "io/png_internal.h"
#include "smplpix/smplpix.h"
#include "test.h"

static spx_ctx *ctx;

/* Write raw PNG rows with libpng (rowbytes per row in `pix`). */
static int write_raw(const char *path, int w, int h, int ctype, int depth, int interlace, const unsigned char *pix,
                     size_t rowbytes, const png_color *pal, int npal, const unsigned char *trns, int ntrns,
                     const png_color_16 *trns_color) {
  FILE *f = fopen(path, "wb");
  if (!f) return 0;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
  png_infop info = png_create_info_struct(png);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    fclose(f);
    return 0;
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, depth, ctype, interlace, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  if (pal) png_set_PLTE(png, info, pal, npal);
  if (trns || trns_color) png_set_tRNS(png, info, trns, ntrns, trns_color);
  png_write_info(png, info);
  int passes = png_set_interlace_handling(png);
  for (int p = 0; p < passes; p++)
    for (int y = 0; y < h; y++) png_write_row(png, pix + (size_t)y * rowbytes);
  png_write_end(png, NULL);
  png_destroy_write_struct(&png, &info);
  fclose(f);
  return 1;
}

static void test_roundtrip(void) {
  int chans[3] = {1, 3, 4};
  for (int ci = 0; ci < 3; ci++) {
    int c = chans[ci], w = 37, h = 53;
    char path[512];
    snprintf(path, sizeof path, "%s/rt%d.png", spx_t_tmpdir(), c);
    spx_image img, back;
    CHECK_OK(ctx, spx_image_alloc(ctx, w, h, c, &img));
    for (size_t i = 0; i < (size_t)w * h * c; i++) img.data[i] = (float)((i * 37 + 11) % 256) / 255.0f;
    CHECK_OK(ctx, spx_png_write(ctx, path, &img));
    CHECK_OK(ctx, spx_png_read(ctx, path, &back));
    CHECK(back.width == w && back.height == h && back.channels == c);
    int bad = 0;
    for (size_t i = 0; back.data && i < (size_t)w * h * c; i++)
      if (back.data[i] != img.data[i]) bad++;
    CHECK_MSG(bad == 0, "%d channels: %d values differ", c, bad);
    spx_image_free(&img);
    spx_image_free(&back);
  }
}

static void test_clamp_round(void) {
  /* value → expected byte */
  const float in[] = {-1.0f, 0.0f, 1.0f, 2.0f, NAN, INFINITY, -INFINITY, 0.5f / 255.0f, 1.5f / 255.0f,
                      0.49f / 255.0f, 254.5f / 255.0f, 0.5f, 1e-30f};
  const int want[] = {0, 0, 255, 255, 0, 255, 0, 1, 2, 0, 255, 128, 0};
  int n = (int)(sizeof in / sizeof in[0]);
  spx_image img, back;
  CHECK_OK(ctx, spx_image_alloc(ctx, n, 1, 1, &img));
  memcpy(img.data, in, sizeof in);
  char path[512];
  spx_t_path(path, sizeof path, "clamp.png");
  CHECK_OK(ctx, spx_png_write(ctx, path, &img));
  CHECK_OK(ctx, spx_png_read(ctx, path, &back));
  for (int i = 0; back.data && i < n; i++)
    CHECK_MSG(back.data[i] == (float)want[i] / 255.0f, "value %d (%g): got %g, want %d/255", i, (double)in[i],
              (double)back.data[i] * 255.0, want[i]);
  spx_image_free(&img);
  spx_image_free(&back);
}

static void test_write_rgb(void) {
  spx_image img, back;
  CHECK_OK(ctx, spx_image_alloc(ctx, 4, 3, 4, &img));
  for (size_t i = 0; i < 4 * 3 * 4; i++) img.data[i] = (i % 4 == 3) ? 7.5f : (float)i / 255.0f;
  char path[512];
  spx_t_path(path, sizeof path, "rgbd.png");
  CHECK_OK(ctx, spx_png_write_rgb(ctx, path, &img));
  CHECK_OK(ctx, spx_png_read(ctx, path, &back));
  CHECK(back.channels == 3 && back.width == 4 && back.height == 3);
  int bad = 0;
  for (size_t p = 0; back.data && p < 12; p++)
    for (int k = 0; k < 3; k++)
      if (back.data[p * 3 + k] != img.data[p * 4 + k]) bad++;
  CHECK(bad == 0);
  spx_image two = img;
  two.channels = 2;
  CHECK(spx_png_write(ctx, path, &two) == SPX_E_ARG);
  CHECK(spx_png_write_rgb(ctx, path, &two) == SPX_E_ARG);
  CHECK(spx_png_write(ctx, "/nonexistent/dir/a.png", &back) == SPX_E_IO);
  spx_image_free(&img);
  spx_image_free(&back);
}

static void test_input_kinds(void) {
  char path[512];
  spx_image img;
  enum { W = 9, H = 7 };
  unsigned char pix[W * H * 8];
  /* 8-bit gray */
  for (int i = 0; i < W * H; i++) pix[i] = (unsigned char)(i * 4);
  spx_t_path(path, sizeof path, "gray8.png");
  CHECK(write_raw(path, W, H, PNG_COLOR_TYPE_GRAY, 8, PNG_INTERLACE_NONE, pix, W, NULL, 0, NULL, 0, NULL));
  CHECK_OK(ctx, spx_png_read(ctx, path, &img));
  CHECK(img.channels == 1 && img.width == W && img.height == H);
  CHECK(img.data && img.data[5] == 20.0f / 255.0f);
  spx_image_free(&img);
  /* gray + alpha → RGBA */
  for (int i = 0; i < W * H; i++) {
    pix[2 * i] = (unsigned char)(i * 3);
    pix[2 * i + 1] = (unsigned char)(255 - i);
  }
  spx_t_path(path, sizeof path, "graya.png");
  CHECK(write_raw(path, W, H, PNG_COLOR_TYPE_GRAY_ALPHA, 8, PNG_INTERLACE_NONE, pix, 2 * W, NULL, 0, NULL, 0, NULL));
  CHECK_OK(ctx, spx_png_read(ctx, path, &img));
  CHECK(img.channels == 4);
  if (img.data) {
    const float *p = img.data + 4 * 10;
    CHECK(p[0] == 30.0f / 255.0f && p[1] == p[0] && p[2] == p[0] && p[3] == 245.0f / 255.0f);
  }
  spx_image_free(&img);
  /* RGBA, interlaced */
  for (int i = 0; i < W * H * 4; i++) pix[i] = (unsigned char)(i * 7 + 1);
  spx_t_path(path, sizeof path, "rgba_adam7.png");
  CHECK(write_raw(path, W, H, PNG_COLOR_TYPE_RGBA, 8, PNG_INTERLACE_ADAM7, pix, 4 * W, NULL, 0, NULL, 0, NULL));
  CHECK_OK(ctx, spx_png_read(ctx, path, &img));
  CHECK(img.channels == 4);
  int bad = 0;
  for (int i = 0; img.data && i < W * H * 4; i++)
    if (img.data[i] != (float)pix[i] / 255.0f) bad++;
  CHECK_MSG(bad == 0, "rgba interlaced: %d differ", bad);
  spx_image_free(&img);
  /* palette without and with transparency, 4-bit indices */
  png_color pal[3] = {{255, 0, 0}, {0, 128, 0}, {10, 20, 30}};
  unsigned char trns[3] = {255, 0, 77};
  size_t rb4 = (W * 4 + 7) / 8;
  memset(pix, 0, sizeof pix);
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++) {
      int idx = (x + y) % 3;
      pix[y * rb4 + x / 2] |= (unsigned char)(x % 2 ? idx : idx << 4);
    }
  spx_t_path(path, sizeof path, "pal.png");
  CHECK(write_raw(path, W, H, PNG_COLOR_TYPE_PALETTE, 4, PNG_INTERLACE_NONE, pix, rb4, pal, 3, NULL, 0, NULL));
  CHECK_OK(ctx, spx_png_read(ctx, path, &img));
  CHECK(img.channels == 3);
  if (img.data) { /* pixel (2,0) → index 2 */
    CHECK(img.data[6] == 10.0f / 255.0f && img.data[7] == 20.0f / 255.0f && img.data[8] == 30.0f / 255.0f);
    CHECK(img.data[3 * (W + 0) + 1] == 128.0f / 255.0f); /* (0,1) → index 1 */
  }
  spx_image_free(&img);
  spx_t_path(path, sizeof path, "pal_trns.png");
  CHECK(write_raw(path, W, H, PNG_COLOR_TYPE_PALETTE, 4, PNG_INTERLACE_NONE, pix, rb4, pal, 3, trns, 3, NULL));
  CHECK_OK(ctx, spx_png_read(ctx, path, &img));
  CHECK(img.channels == 4);
  if (img.data) {
    CHECK(img.data[3] == 1.0f);                 /* (0,0) index 0 opaque */
    CHECK(img.data[4 + 3] == 0.0f);             /* (1,0) index 1 transparent */
    CHECK(img.data[8 + 3] == 77.0f / 255.0f);   /* (2,0) index 2 */
    CHECK(img.data[8] == 10.0f / 255.0f);
  }
  spx_image_free(&img);
  /* 1-bit gray */
  size_t rb1 = (W + 7) / 8;
  memset(pix, 0, sizeof pix);
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++)
      if ((x * y) % 2) pix[y * rb1 + x / 8] |= (unsigned char)(0x80 >> (x % 8));
  spx_t_path(path, sizeof path, "gray1.png");
  CHECK(write_raw(path, W, H, PNG_COLOR_TYPE_GRAY, 1, PNG_INTERLACE_NONE, pix, rb1, NULL, 0, NULL, 0, NULL));
  CHECK_OK(ctx, spx_png_read(ctx, path, &img));
  CHECK(img.channels == 1);
  bad = 0;
  for (int y = 0; img.data && y < H; y++)
    for (int x = 0; x < W; x++)
      if (img.data[y * W + x] != ((x * y) % 2 ? 1.0f : 0.0f)) bad++;
  CHECK_MSG(bad == 0, "1-bit gray: %d differ", bad);
  spx_image_free(&img);
  /* 16-bit RGB, big endian samples → v / 65535 */
  for (int i = 0; i < W * H * 3; i++) {
    unsigned v = (unsigned)(i * 1009 + 3) & 0xffff;
    pix[2 * i] = (unsigned char)(v >> 8);
    pix[2 * i + 1] = (unsigned char)(v & 255);
  }
  spx_t_path(path, sizeof path, "rgb16.png");
  CHECK(write_raw(path, W, H, PNG_COLOR_TYPE_RGB, 16, PNG_INTERLACE_NONE, pix, 6 * W, NULL, 0, NULL, 0, NULL));
  CHECK_OK(ctx, spx_png_read(ctx, path, &img));
  CHECK(img.channels == 3);
  bad = 0;
  for (int i = 0; img.data && i < W * H * 3; i++)
    if (img.data[i] != (float)((unsigned)(i * 1009 + 3) & 0xffff) / 65535.0f) bad++;
  CHECK_MSG(bad == 0, "16-bit: %d differ", bad);
  spx_image_free(&img);
  /* 16-bit gray with a tRNS color key → RGBA, keyed pixels transparent */
  png_color_16 key = {0, 0, 0, 0, 0x1234};
  for (int i = 0; i < W * H; i++) {
    unsigned v = i == 4 ? 0x1234u : (unsigned)i * 300u;
    pix[2 * i] = (unsigned char)(v >> 8);
    pix[2 * i + 1] = (unsigned char)(v & 255);
  }
  spx_t_path(path, sizeof path, "gray16_key.png");
  CHECK(write_raw(path, W, H, PNG_COLOR_TYPE_GRAY, 16, PNG_INTERLACE_NONE, pix, 2 * W, NULL, 0, NULL, 0, &key));
  CHECK_OK(ctx, spx_png_read(ctx, path, &img));
  CHECK(img.channels == 4);
  if (img.data) {
    CHECK(img.data[4 * 4 + 3] == 0.0f && img.data[4 * 5 + 3] == 1.0f);
    CHECK(img.data[4 * 5] == 1500.0f / 65535.0f);
  }
  spx_image_free(&img);
}

static void expect_format_error(const char *path, const char *what) {
  spx_image img;
  spx_status st = spx_png_read(ctx, path, &img);
  CHECK_MSG(st == SPX_E_FORMAT, "%s: got %s (%s)", what, spx_status_name(st), spx_ctx_message(ctx));
  CHECK_MSG(strstr(spx_ctx_message(ctx), path) != NULL, "%s: no file name in: %s", what, spx_ctx_message(ctx));
  CHECK(img.data == NULL);
  fprintf(stderr, "    %s -> %s\n", what, spx_ctx_message(ctx));
}

static void test_hostile(void) {
  char good[512], path[512];
  spx_t_path(good, sizeof good, "rt3.png");
  FILE *f = fopen(good, "rb");
  CHECK(f != NULL);
  if (!f) return;
  unsigned char buf[1 << 16];
  size_t n = fread(buf, 1, sizeof buf, f);
  fclose(f);
  size_t cuts[] = {0, 7, 20, 40, n / 2, n - 5};
  for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
    snprintf(path, sizeof path, "%s/trunc%zu.png", spx_t_tmpdir(), i);
    spx_t_write_bytes(path, buf, cuts[i]);
    expect_format_error(path, "truncated");
  }
  /* corrupted IDAT (CRC and zlib data): flip bytes in the middle */
  for (size_t i = n / 2; i < n / 2 + 16; i++) buf[i] ^= 0xff;
  spx_t_path(path, sizeof path, "corrupt.png");
  f = fopen(path, "wb");
  fwrite(buf, 1, n, f);
  fclose(f);
  expect_format_error(path, "corrupt");
  /* a header claiming 100000 x 100000 */
  f = fopen(good, "rb");
  n = fread(buf, 1, sizeof buf, f);
  fclose(f);
  buf[16] = 0, buf[17] = 1, buf[18] = 0x86, buf[19] = 0xa0; /* width = 100000 */
  unsigned long crc = crc32(0L, buf + 12, 17);                /* keep the IHDR CRC valid */
  buf[29] = (unsigned char)(crc >> 24), buf[30] = (unsigned char)(crc >> 16);
  buf[31] = (unsigned char)(crc >> 8), buf[32] = (unsigned char)crc;
  spx_t_path(path, sizeof path, "huge.png");
  f = fopen(path, "wb");
  fwrite(buf, 1, n, f);
  fclose(f);
  expect_format_error(path, "huge");
  /* memory reader pixel cap */
  spx_image img;
  spx_t_path(path, sizeof path, "rt3.png");
  f = fopen(path, "rb");
  n = fread(buf, 1, sizeof buf, f);
  fclose(f);
  CHECK(spx_png_read_mem(ctx, "mem", buf, n, 100, &img) == SPX_E_FORMAT);
  CHECK(spx_png_read_mem(ctx, "mem", buf, n, 37 * 53, &img) == SPX_OK);
  spx_image_free(&img);
  CHECK(spx_png_read(ctx, "/nonexistent/x.png", &img) == SPX_E_IO);
}

int main(void) {
  if (spx_ctx_create(&ctx) != SPX_OK) return 1;
  SPX_RUN(test_roundtrip);
  SPX_RUN(test_clamp_round);
  SPX_RUN(test_write_rgb);
  SPX_RUN(test_input_kinds);
  SPX_RUN(test_hostile);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
