/* OpenEXR I/O: bit-exact float round trips, conversion of half/tiled/windowed files written here
 * with the OpenEXR C API, missing Z, hostile files, and atomic writes. */
#include <OpenEXR/openexr.h>
#include <dirent.h>
#include <signal.h>
#include <string.h>
#include <sys/resource.h>

#include "io/exr_internal.h"
#include "smplpix/smplpix.h"
#include "test.h"

static spx_ctx *ctx;

static int bits_equal(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

static int count_tmp_files(void) {
  DIR *d = opendir(spx_t_tmpdir());
  int n = 0;
  if (!d) return -1;
  for (struct dirent *e; (e = readdir(d));)
    if (strstr(e->d_name, ".tmp.")) n++;
  closedir(d);
  return n;
}

static void roundtrip(int w, int h, int c, unsigned long long seed) {
  char path[512];
  snprintf(path, sizeof path, "%s/rt_%dx%dx%d.exr", spx_t_tmpdir(), w, h, c);
  spx_image img, back;
  CHECK_OK(ctx, spx_image_alloc(ctx, w, h, c, &img));
  for (size_t i = 0; i < (size_t)w * h * c; i++) {
    double u = spx_t_uniform(&seed);
    /* a mix of ordinary, negative, tiny (denormal) and large values */
    img.data[i] = i % 7 == 3 ? (float)(-u * 1e6) : i % 11 == 5 ? 1e-40f * (float)u : (float)u;
  }
  CHECK_OK(ctx, spx_exr_write(ctx, path, &img));
  CHECK_OK(ctx, spx_exr_read(ctx, path, &back));
  CHECK(back.width == w && back.height == h && back.channels == 4);
  int bad = 0;
  if (back.data)
    for (size_t p = 0; p < (size_t)w * h; p++)
      for (int k = 0; k < 4; k++) {
        float want = k < c ? img.data[p * c + k] : 1.0f; /* no Z written → background depth 1 */
        if (!bits_equal(back.data[p * 4 + k], want)) bad++;
      }
  CHECK_MSG(bad == 0, "%dx%dx%d: %d values differ", w, h, c, bad);
  spx_image_free(&img);
  spx_image_free(&back);
}

static void test_roundtrip(void) {
  roundtrip(1, 1, 4, 1);
  roundtrip(37, 53, 4, 2);
  roundtrip(410, 308, 4, 3);
  roundtrip(5, 40, 3, 4); /* RGB only: Z reads as 1 */
}

/* Write a file with the C API directly: channels `chans` (comma-less string, e.g. "RGB" or "Y"),
 * pixel type ptype, optionally tiled, with the given display and data windows. The value of
 * channel k at pixel (x, y) is val(x, y, k). */
static int g_uint; /* 1 while writing/checking a uint file: values are the integers ival() */
static unsigned ival(int x, int y, int k) { return (unsigned)(((x + 64) * 3 + (y + 64) * 5 + k * 7) % 64); }
static float val(int x, int y, int k) { return g_uint ? (float)ival(x, y, k) : (float)ival(x, y, k) / 8.0f - 2.0f; }

static int write_custom(const char *path, const char *chans, exr_pixel_type_t ptype, int tiled,
                        exr_attr_box2i_t disp, exr_attr_box2i_t dw) {
  exr_context_t e;
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  int part, ok = 1;
  if (exr_start_write(&e, path, EXR_WRITE_FILE_DIRECTLY, &init) != EXR_ERR_SUCCESS) return 0;
  ok &= exr_add_part(e, "p", tiled ? EXR_STORAGE_TILED : EXR_STORAGE_SCANLINE, &part) == EXR_ERR_SUCCESS;
  exr_attr_v2f_t swc = {{{0.f, 0.f}}};
  ok &= exr_initialize_required_attr(e, part, &disp, &dw, 1.f, &swc, 1.f, EXR_LINEORDER_INCREASING_Y,
                                     EXR_COMPRESSION_ZIP) == EXR_ERR_SUCCESS;
  int nc = (int)strlen(chans);
  for (int c = 0; c < nc; c++) {
    char nm[2] = {chans[c], 0};
    ok &= exr_add_channel(e, part, nm, ptype, EXR_PERCEPTUALLY_LINEAR, 1, 1) == EXR_ERR_SUCCESS;
  }
  int tw = 16, th = 8;
  if (tiled) ok &= exr_set_tile_descriptor(e, part, tw, th, EXR_TILE_ONE_LEVEL, EXR_TILE_ROUND_DOWN) == EXR_ERR_SUCCESS;
  ok &= exr_write_header(e) == EXR_ERR_SUCCESS;
  int W = dw.max.x - dw.min.x + 1, H = dw.max.y - dw.min.y + 1;
  /* planar source, one float plane per channel, with values by absolute coordinates */
  float *planes = malloc(sizeof(float) * (size_t)W * H * nc);
  for (int c = 0; c < nc; c++)
    for (int y = 0; y < H; y++)
      for (int x = 0; x < W; x++) {
        int slot = chans[c] == 'R' ? 0 : chans[c] == 'G' ? 1 : chans[c] == 'B' ? 2 : 3;
        if (ptype == EXR_PIXEL_UINT) {
          uint32_t u = ival(x + dw.min.x, y + dw.min.y, slot);
          memcpy(&planes[((size_t)c * H + y) * W + x], &u, 4); /* same size as float */
        } else {
          planes[((size_t)c * H + y) * W + x] = val(x + dw.min.x, y + dw.min.y, slot);
        }
      }
  exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
  int first = 1;
  int32_t lpc = 1;
  if (!tiled) exr_get_scanlines_per_chunk(e, part, &lpc);
  int ny = tiled ? (H + th - 1) / th : (H + lpc - 1) / lpc, nx = tiled ? (W + tw - 1) / tw : 1;
  for (int ty = 0; ok && ty < ny; ty++)
    for (int tx = 0; ok && tx < nx; tx++) {
      exr_chunk_info_t ci;
      int x0 = tiled ? tx * tw : 0, y0 = tiled ? ty * th : ty * lpc;
      ok &= (tiled ? exr_write_tile_chunk_info(e, part, tx, ty, 0, 0, &ci)
                   : exr_write_scanline_chunk_info(e, part, y0 + dw.min.y, &ci)) == EXR_ERR_SUCCESS;
      if (!ok) break;
      ok &= (first ? exr_encoding_initialize(e, part, &ci, &enc) : exr_encoding_update(e, part, &ci, &enc)) ==
            EXR_ERR_SUCCESS;
      for (int c = 0; ok && c < enc.channel_count; c++) {
        int src = (int)(strchr(chans, enc.channels[c].channel_name[0]) - chans);
        enc.channels[c].encode_from_ptr = (const uint8_t *)(planes + ((size_t)src * H + y0) * W + x0);
        enc.channels[c].user_pixel_stride = 4;
        enc.channels[c].user_line_stride = 4 * W;
        enc.channels[c].user_bytes_per_element = 4;
        enc.channels[c].user_data_type = ptype == EXR_PIXEL_UINT ? EXR_PIXEL_UINT : EXR_PIXEL_FLOAT;
      }
      if (ok && first) ok &= exr_encoding_choose_default_routines(e, part, &enc) == EXR_ERR_SUCCESS;
      first = 0;
      if (ok) ok &= exr_encoding_run(e, part, &enc) == EXR_ERR_SUCCESS;
    }
  if (!first) exr_encoding_destroy(e, &enc);
  ok &= exr_finish(&e) == EXR_ERR_SUCCESS;
  free(planes);
  return ok;
}

static exr_attr_box2i_t box(int x0, int y0, int x1, int y1) {
  exr_attr_box2i_t b;
  b.min.x = x0;
  b.min.y = y0;
  b.max.x = x1;
  b.max.y = y1;
  return b;
}

/* Compare a read image (display window disp) with val() inside dw, background outside. */
static int check_custom(const spx_image *img, exr_attr_box2i_t disp, exr_attr_box2i_t dw, int has_z) {
  int bad = 0;
  for (int y = 0; y < img->height; y++)
    for (int x = 0; x < img->width; x++) {
      int ax = x + disp.min.x, ay = y + disp.min.y;
      int inside = ax >= dw.min.x && ax <= dw.max.x && ay >= dw.min.y && ay <= dw.max.y;
      for (int k = 0; k < 4; k++) {
        float want = inside && (k < 3 || has_z) ? val(ax, ay, k) : 1.0f;
        if (img->data[((size_t)y * img->width + x) * 4 + k] != want) bad++;
      }
    }
  return bad;
}

static void test_half_and_layouts(void) {
  struct {
    const char *chans;
    exr_pixel_type_t pt;
    int tiled;
    exr_attr_box2i_t disp, dw;
  } cases[] = {
      {"RGB", EXR_PIXEL_HALF, 0, box(0, 0, 20, 17), box(0, 0, 20, 17)},
      {"ZRGB", EXR_PIXEL_HALF, 0, box(0, 0, 40, 33), box(0, 0, 40, 33)},
      {"RGBZ", EXR_PIXEL_HALF, 1, box(0, 0, 37, 21), box(0, 0, 37, 21)},
      {"RGB", EXR_PIXEL_FLOAT, 1, box(0, 0, 37, 21), box(5, 3, 30, 19)},      /* data window inside */
      {"RGBZ", EXR_PIXEL_UINT, 0, box(-4, -2, 25, 30), box(-10, 5, 12, 44)}, /* overlapping windows */
      /* extra channels that are not read (OpenEXR 3.1 crashed when they had no buffer) */
      {"ARGB", EXR_PIXEL_HALF, 0, box(0, 0, 20, 17), box(0, 0, 20, 17)},
      {"RGBAYZ", EXR_PIXEL_HALF, 1, box(0, 0, 40, 30), box(0, 0, 40, 30)},
      {"RGBY", EXR_PIXEL_FLOAT, 0, box(0, 0, 5, 5), box(0, 0, 5, 5)},
      {"RGBY", EXR_PIXEL_HALF, 0, box(0, 0, 5, 5), box(0, 0, 5, 5)},
      {"RGBY", EXR_PIXEL_HALF, 1, box(0, 0, 5, 5), box(0, 0, 5, 5)},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    char path[512];
    snprintf(path, sizeof path, "%s/custom%zu.exr", spx_t_tmpdir(), i);
    g_uint = cases[i].pt == EXR_PIXEL_UINT;
    CHECK_MSG(write_custom(path, cases[i].chans, cases[i].pt, cases[i].tiled, cases[i].disp, cases[i].dw),
              "case %zu: C API write failed", i);
    spx_image img;
    CHECK_OK(ctx, spx_exr_read(ctx, path, &img));
    if (!img.data) continue;
    CHECK(img.width == cases[i].disp.max.x - cases[i].disp.min.x + 1);
    CHECK(img.height == cases[i].disp.max.y - cases[i].disp.min.y + 1);
    CHECK(img.channels == 4);
    g_uint = cases[i].pt == EXR_PIXEL_UINT;
    int has_z = strchr(cases[i].chans, 'Z') != NULL;
    int bad = check_custom(&img, cases[i].disp, cases[i].dw, has_z);
    CHECK_MSG(bad == 0, "case %zu: %d values differ", i, bad);
    g_uint = 0;
    spx_image_free(&img);
  }
}

static void expect_format_error(const char *path, const char *what) {
  spx_image img;
  spx_status st = spx_exr_read(ctx, path, &img);
  CHECK_MSG(st == SPX_E_FORMAT, "%s: got %s (%s)", what, spx_status_name(st), spx_ctx_message(ctx));
  CHECK_MSG(strstr(spx_ctx_message(ctx), path) != NULL, "%s: message lacks the file name: %s", what,
            spx_ctx_message(ctx));
  CHECK(img.data == NULL);
  fprintf(stderr, "    %s -> %s\n", what, spx_ctx_message(ctx));
  spx_image_free(&img);
}

static void test_hostile(void) {
  char good[512], path[512];
  snprintf(good, sizeof good, "%s/rt_37x53x4.exr", spx_t_tmpdir());
  unsigned char *buf = NULL;
  size_t n = 0;
  FILE *f = fopen(good, "rb");
  CHECK(f != NULL);
  if (!f) return;
  fseek(f, 0, SEEK_END);
  n = (size_t)ftell(f);
  fseek(f, 0, SEEK_SET);
  buf = malloc(n);
  CHECK(fread(buf, 1, n, f) == n);
  fclose(f);
  /* truncated at several points: inside the header, inside the offset table, inside the data */
  size_t cuts[] = {3, 20, 200, n / 2, n - 1};
  for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
    snprintf(path, sizeof path, "%s/trunc%zu.exr", spx_t_tmpdir(), i);
    spx_t_write_bytes(path, buf, cuts[i]);
    expect_format_error(path, "truncated");
  }
  /* garbage */
  snprintf(path, sizeof path, "%s/garbage.exr", spx_t_tmpdir());
  unsigned long long s = 99;
  f = fopen(path, "wb");
  for (int i = 0; i < 4096; i++) fputc((int)(spx_t_rng_next(&s) & 255), f);
  fclose(f);
  expect_format_error(path, "garbage");
  /* garbage after a valid magic number and version */
  f = fopen(path, "wb");
  fwrite(buf, 1, 8, f);
  for (int i = 0; i < 4096; i++) fputc((int)(spx_t_rng_next(&s) & 255), f);
  fclose(f);
  expect_format_error(path, "garbage after magic");
  free(buf);
  /* corrupted compressed data (header intact): a constant image compresses well, so every
   * chunk is zlib data; flip bytes near the end of the last chunk */
  spx_image cst;
  CHECK_OK(ctx, spx_image_alloc(ctx, 30, 40, 4, &cst));
  for (size_t i = 0; i < 30 * 40 * 4; i++) cst.data[i] = 0.5f;
  snprintf(path, sizeof path, "%s/corrupt.exr", spx_t_tmpdir());
  CHECK_OK(ctx, spx_exr_write(ctx, path, &cst));
  spx_image_free(&cst);
  f = fopen(path, "r+b");
  fseek(f, 0, SEEK_END);
  n = (size_t)ftell(f);
  buf = malloc(n);
  fseek(f, 0, SEEK_SET);
  CHECK(fread(buf, 1, n, f) == n);
  for (size_t i = n - 12; i < n; i++) buf[i] ^= 0x5a;
  fseek(f, 0, SEEK_SET);
  fwrite(buf, 1, n, f);
  fclose(f);
  expect_format_error(path, "corrupt chunk");
  free(buf);
  /* only a Y channel */
  snprintf(path, sizeof path, "%s/yonly.exr", spx_t_tmpdir());
  CHECK(write_custom(path, "Y", EXR_PIXEL_HALF, 0, box(0, 0, 7, 7), box(0, 0, 7, 7)));
  expect_format_error(path, "Y only");
  CHECK(strstr(spx_ctx_message(ctx), "R, G, B") != NULL);
  /* missing file: an I/O error, not a format error */
  spx_image img;
  CHECK(spx_exr_read(ctx, "/nonexistent/dir/x.exr", &img) == SPX_E_IO);
}

/* spx_exr_write with the process's file-size limit at `limit` bytes: writes past it fail (EFBIG,
 * SIGXFSZ ignored), as on a disk that fills up while the file is written. */
static spx_status write_with_size_limit(const char *path, const spx_image *img, rlim_t limit) {
  struct rlimit old, lim;
  CHECK(getrlimit(RLIMIT_FSIZE, &old) == 0);
  lim = old;
  lim.rlim_cur = limit;
  void (*prev)(int) = signal(SIGXFSZ, SIG_IGN);
  CHECK(setrlimit(RLIMIT_FSIZE, &lim) == 0);
  spx_status st = spx_exr_write(ctx, path, img);
  CHECK(setrlimit(RLIMIT_FSIZE, &old) == 0);
  signal(SIGXFSZ, prev);
  return st;
}

static long file_size(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return -1;
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fclose(f);
  return n;
}

static void test_atomic_write(void) {
  char path[512];
  spx_t_path(path, sizeof path, "atomic.exr");
  spx_image a, b, back;
  CHECK_OK(ctx, spx_image_alloc(ctx, 30, 70, 4, &a));
  CHECK_OK(ctx, spx_image_alloc(ctx, 30, 70, 4, &b));
  unsigned long long seed = 7;
  for (size_t i = 0; i < 30 * 70 * 4; i++) { /* b: values ZIP cannot shrink much, so its 5 chunks fill the file */
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    a.data[i] = 0.25f;
    b.data[i] = i ? 0.5f + (float)(seed >> 40) / (float)(1ULL << 25) : 0.75f;
  }
  char whole[512];
  spx_t_path(whole, sizeof whole, "atomic_whole.exr");
  CHECK_OK(ctx, spx_exr_write(ctx, whole, &b));
  long b_size = file_size(whole);
  CHECK(b_size > 20000);
  remove(whole);
  CHECK_OK(ctx, spx_exr_write(ctx, path, &a));
  int tmp_before = count_tmp_files();
  /* the disk full half-way through b's chunks: error, target untouched, no temporary left */
  spx_status st = write_with_size_limit(path, &b, (rlim_t)(b_size / 2));
  CHECK(st == SPX_E_IO);
  CHECK(strstr(spx_ctx_message(ctx), "rows from") != NULL);
  CHECK(count_tmp_files() == tmp_before);
  CHECK_OK(ctx, spx_exr_read(ctx, path, &back));
  CHECK(back.data && back.data[0] == 0.25f && back.data[30 * 70 * 4 - 1] == 0.25f);
  spx_image_free(&back);
  /* a failed write to a fresh path leaves no file */
  char fresh[512];
  spx_t_path(fresh, sizeof fresh, "never.exr");
  remove(fresh);
  CHECK(write_with_size_limit(fresh, &b, 0) == SPX_E_IO);
  CHECK(!spx_t_file_exists(fresh));
  /* unwritable directory */
  CHECK(spx_exr_write(ctx, "/nonexistent/dir/x.exr", &b) == SPX_E_IO);
  CHECK(strstr(spx_ctx_message(ctx), "/nonexistent/dir/x.exr") != NULL);
  /* bad arguments */
  spx_image two = a;
  two.channels = 2;
  CHECK(spx_exr_write(ctx, path, &two) == SPX_E_ARG);
  /* a successful overwrite replaces the content */
  CHECK_OK(ctx, spx_exr_write(ctx, path, &b));
  CHECK_OK(ctx, spx_exr_read(ctx, path, &back));
  CHECK(back.data && back.data[0] == 0.75f);
  CHECK(count_tmp_files() == tmp_before);
  spx_image_free(&back);
  spx_image_free(&a);
  spx_image_free(&b);
}

static void test_bounds(void) {
  /* a valid header declaring a window above the limits is rejected before allocation */
  char path[512];
  spx_t_path(path, sizeof path, "huge.exr");
  CHECK(write_custom(path, "RGB", EXR_PIXEL_HALF, 0, box(0, 0, 7, 7), box(0, 0, 7, 7)));
  FILE *f = fopen(path, "r+b");
  unsigned char hdr[4096];
  size_t n = fread(hdr, 1, sizeof hdr, f);
  int patched = 0;
  for (size_t i = 0; i + 40 < n; i++) /* "dataWindow\0box2i\0" size, xmin ymin xmax ymax */
    if (memcmp(hdr + i, "dataWindow\0box2i\0", 17) == 0 || memcmp(hdr + i, "displayWindow\0box2i\0", 20) == 0) {
      size_t v = i + (hdr[i + 1] == 'a' ? 17 : 20) + 4;
      int32_t big = 20000 - 1;
      memcpy(hdr + v + 8, &big, 4);
      memcpy(hdr + v + 12, &big, 4);
      patched++;
    }
  CHECK(patched == 2);
  fseek(f, 0, SEEK_SET);
  fwrite(hdr, 1, n, f);
  fclose(f);
  expect_format_error(path, "20000x20000");
  /* the in-memory reader's pixel cap */
  static const unsigned char magic[] = {0x76, 0x2f, 0x31, 0x01};
  spx_image img;
  CHECK(spx_exr_read_mem(ctx, "mem", magic, 4, 100, &img) == SPX_E_FORMAT);
}

int main(void) {
  if (spx_ctx_create(&ctx) != SPX_OK) return 1;
  SPX_RUN(test_roundtrip);
  SPX_RUN(test_half_and_layouts);
  SPX_RUN(test_hostile);
  SPX_RUN(test_atomic_write);
  SPX_RUN(test_bounds);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
