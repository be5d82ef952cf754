/* PNG through libpng's classic API (no gamma or color-space conversion: sample values are
 * mapped linearly, v / 255 or v / 65535).
 *
 * Read: gray → 1 channel; gray + alpha (or gray with a tRNS color key) → RGBA; RGB → 3;
 * RGBA → 4; palette → RGB, or RGBA when it has transparency; 1/2/4-bit samples are expanded.
 * Write: 1 (gray), 3 (RGB) or 4 (RGBA) channels of [0,1] floats to 8 bits: NaN → 0, clamp to
 * [0,1], then floor(v * 255 + 0.5) (round half up); the file is written to a temporary name and
 * renamed over the target only when complete. */
#include <math.h>
#include <png.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "io/png_internal.h"
#include "io/image_internal.h"

#define PNG_MAX_FILE ((size_t)1 << 31)

typedef struct {
  char msg[200];
} png_err_state;

static void png_err_fn(png_structp png, png_const_charp msg) {
  png_err_state *e = png_get_error_ptr(png);
  if (e) snprintf(e->msg, sizeof e->msg, "%s", msg ? msg : "libpng error");
  png_longjmp(png, 1);
}

static void png_warn_fn(png_structp png, png_const_charp msg) {
  (void)png;
  (void)msg; /* warnings (unknown chunks, bad ancillary data) are not errors */
}

/* ---------------- read ---------------- */

typedef struct {
  const unsigned char *data;
  size_t size, pos;
} png_mem_src;

static void png_mem_read(png_structp png, png_bytep out, size_t len) {
  png_mem_src *s = png_get_io_ptr(png);
  if (len > s->size - s->pos) png_error(png, "file is truncated");
  memcpy(out, s->data + s->pos, len);
  s->pos += len;
}

typedef struct {
  png_structp png;
  png_infop info;
  png_mem_src src;
  png_err_state err;
  unsigned char *pixels; /* decoded rows */
  png_bytep *rows;
  int64_t max_pixels;
  uint32_t width, height;
  int channels, bit_depth;
  size_t rowbytes;
  const char *toolarge; /* set when the header is rejected by our own bounds */
  int oom;              /* the pixels could not be allocated */
} png_read_state;

/* Everything that can longjmp lives here; resources are kept in *s so the caller frees them. */
static int png_read_inner(png_read_state *s) {
  if (setjmp(png_jmpbuf(s->png))) return 0;
  png_set_read_fn(s->png, &s->src, png_mem_read);
  png_set_user_limits(s->png, SPX_PNG_MAX_DIM, SPX_PNG_MAX_DIM);
  png_set_chunk_malloc_max(s->png, (png_alloc_size_t)64 << 20);
  png_read_info(s->png, s->info);
  png_uint_32 w, h;
  int depth, ctype, interlace;
  png_get_IHDR(s->png, s->info, &w, &h, &depth, &ctype, &interlace, NULL, NULL);
  if ((int64_t)w * (int64_t)h > s->max_pixels) {
    s->toolarge = "image";
    s->width = w;
    s->height = h;
    return 0;
  }
  /* the file's own rows (a filter byte each) compressed by deflate, which packs at most ~1032:1:
   * a header that claims more pixels than the file's bytes can hold is refused before allocating */
  double raw = ((double)png_get_rowbytes(s->png, s->info) + 1) * (double)h;
  if (raw / 1032.0 > (double)s->src.size + 1024) {
    s->toolarge = "file";
    s->width = w;
    s->height = h;
    return 0;
  }
  int has_trns = png_get_valid(s->png, s->info, PNG_INFO_tRNS) != 0;
  if (ctype == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(s->png);
  if (ctype == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(s->png);
  if (has_trns) png_set_tRNS_to_alpha(s->png);
  if (ctype == PNG_COLOR_TYPE_GRAY_ALPHA || (ctype == PNG_COLOR_TYPE_GRAY && has_trns))
    png_set_gray_to_rgb(s->png);
  png_set_interlace_handling(s->png);
  png_read_update_info(s->png, s->info);
  s->width = w;
  s->height = h;
  s->channels = png_get_channels(s->png, s->info);
  s->bit_depth = png_get_bit_depth(s->png, s->info);
  s->rowbytes = png_get_rowbytes(s->png, s->info);
  if ((s->channels != 1 && s->channels != 3 && s->channels != 4) || (s->bit_depth != 8 && s->bit_depth != 16) ||
      s->rowbytes != (size_t)w * (size_t)s->channels * (size_t)(s->bit_depth / 8))
    png_error(s->png, "unexpected pixel layout after conversion");
  size_t total;
  if (!spx_mul_size(s->rowbytes, h, &total)) png_error(s->png, "image too large");
  s->pixels = malloc(total ? total : 1);
  s->rows = malloc(sizeof *s->rows * (h ? h : 1));
  if (!s->pixels || !s->rows) {
    s->oom = 1;
    png_error(s->png, "out of memory");
  }
  for (uint32_t y = 0; y < h; y++) s->rows[y] = s->pixels + (size_t)y * s->rowbytes;
  png_read_image(s->png, s->rows);
  png_read_end(s->png, NULL);
  return 1;
}

spx_status spx_png_read_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, int64_t max_pixels,
                            spx_image *out) {
  spx_status st = spx_read_mem_args(ctx, "spx_png_read", out, sizeof *out, &name, data, size);
  if (st != SPX_OK) return st;
  if (size < 8 || png_sig_cmp((png_const_bytep)data, 0, 8) != 0)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: not a PNG file (bad signature)", name);
  png_read_state s;
  memset(&s, 0, sizeof s);
  s.src.data = data;
  s.src.size = size;
  s.max_pixels = max_pixels;
  s.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &s.err, png_err_fn, png_warn_fn);
  if (s.png) s.info = png_create_info_struct(s.png);
  if (!s.png || !s.info) {
    st = spx_fail(ctx, SPX_E_NOMEM, "%s: cannot create libpng reader", name);
    goto done;
  }
  if (!png_read_inner(&s)) {
    if (s.toolarge && !strcmp(s.toolarge, "file"))
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: %ux%u pixels cannot be in a file of %zu bytes (truncated or corrupt)", name,
                    (unsigned)s.width, (unsigned)s.height, size);
    else if (s.toolarge)
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: %ux%u pixels is more than the %lld allowed", name, (unsigned)s.width,
                    (unsigned)s.height, (long long)max_pixels);
    else if (s.oom)
      st = spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate the %ux%u image (out of memory)", name, (unsigned)s.width,
                    (unsigned)s.height);
    else
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: invalid PNG: %s", name, s.err.msg[0] ? s.err.msg : "decode error");
    goto done;
  }
  st = spx_image_alloc(ctx, (int32_t)s.width, (int32_t)s.height, s.channels, out);
  if (st != SPX_OK) {
    st = spx_fail(ctx, st, "%s: %s", name, spx_ctx_message(ctx));
    goto done;
  }
  size_t n = (size_t)s.width * s.height * (size_t)s.channels;
  if (s.bit_depth == 8) {
    for (size_t i = 0; i < n; i++) out->data[i] = (float)s.pixels[i] / 255.0f;
  } else {
    for (size_t i = 0; i < n; i++)
      out->data[i] = (float)((unsigned)s.pixels[2 * i] << 8 | s.pixels[2 * i + 1]) / 65535.0f;
  }
done:
  if (s.png) png_destroy_read_struct(&s.png, s.info ? &s.info : NULL, NULL);
  free(s.pixels);
  free(s.rows);
  return st;
}

spx_status spx_png_read(spx_ctx *ctx, const char *path, spx_image *out) {
  return spx_image_read_file(ctx, "spx_png_read", path, PNG_MAX_FILE, (int64_t)SPX_PNG_MAX_DIM * SPX_PNG_MAX_DIM, spx_png_read_mem, out);
}

/* ---------------- write ---------------- */

static unsigned char png_to_u8(float v) {
  if (!(v > 0.0f)) return 0; /* NaN and <= 0 */
  if (v >= 1.0f) return 255;
  return (unsigned char)floorf(v * 255.0f + 0.5f);
}

typedef struct {
  png_structp png;
  png_infop info;
  png_err_state err;
  FILE *fp;
  const spx_image *img;
  int channels; /* channels written (<= img->channels) */
  unsigned char *row;
} png_write_state;

static int png_write_inner(png_write_state *s) {
  if (setjmp(png_jmpbuf(s->png))) return 0;
  const spx_image *img = s->img;
  int ctype = s->channels == 1 ? PNG_COLOR_TYPE_GRAY : s->channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGBA;
  png_init_io(s->png, s->fp);
  png_set_IHDR(s->png, s->info, (png_uint_32)img->width, (png_uint_32)img->height, 8, ctype, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(s->png, s->info);
  size_t stride = (size_t)img->channels;
  for (int32_t y = 0; y < img->height; y++) {
    const float *src = img->data + (size_t)y * (size_t)img->width * stride;
    for (int32_t x = 0; x < img->width; x++)
      for (int c = 0; c < s->channels; c++)
        s->row[(size_t)x * (size_t)s->channels + (size_t)c] = png_to_u8(src[(size_t)x * stride + (size_t)c]);
    png_write_row(s->png, s->row);
  }
  png_write_end(s->png, NULL);
  return 1;
}

static spx_status png_write_channels(spx_ctx *ctx, const char *path, const spx_image *img, int channels) {
  spx_status st = SPX_OK;
  spx_atomic_file af;
  int opened = 0;
  png_write_state s;
  memset(&s, 0, sizeof s);
  s.img = img;
  s.channels = channels;
  s.row = spx_alloc_array(ctx, (size_t)img->width, (size_t)channels, path);
  if (!s.row) return SPX_E_NOMEM;
  s.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &s.err, png_err_fn, png_warn_fn);
  if (s.png) s.info = png_create_info_struct(s.png);
  if (!s.png || !s.info) {
    st = spx_fail(ctx, SPX_E_NOMEM, "%s: cannot create libpng writer", path);
    goto done;
  }
  st = spx_atomic_open(ctx, path, &af);
  if (st != SPX_OK) goto done;
  opened = 1;
  s.fp = af.fp;
  if (!png_write_inner(&s)) {
    st = spx_fail(ctx, SPX_E_IO, "%s: PNG write failed: %s", path, s.err.msg[0] ? s.err.msg : "libpng error");
    goto done;
  }
  opened = 0;
  st = spx_atomic_commit(ctx, &af);
done:
  if (opened) spx_atomic_abort(&af);
  if (s.png) png_destroy_write_struct(&s.png, s.info ? &s.info : NULL);
  free(s.row);
  return st;
}

static spx_status png_check_image(spx_ctx *ctx, const char *path, const spx_image *img) {
  if (!path) return spx_fail(ctx, SPX_E_ARG, "spx_png_write: path is NULL");
  if (!img || !img->data || img->width <= 0 || img->height <= 0 || img->channels <= 0)
    return spx_fail(ctx, SPX_E_ARG, "%s: invalid image", path);
  if (img->width > SPX_PNG_MAX_DIM || img->height > SPX_PNG_MAX_DIM)
    return spx_fail(ctx, SPX_E_ARG, "%s: %dx%d is larger than %d pixels on a side", path, (int)img->width,
                    (int)img->height, SPX_PNG_MAX_DIM);
  return SPX_OK;
}

spx_status spx_png_write(spx_ctx *ctx, const char *path, const spx_image *img) {
  spx_status st = png_check_image(ctx, path, img);
  if (st != SPX_OK) return st;
  if (img->channels != 1 && img->channels != 3 && img->channels != 4)
    return spx_fail(ctx, SPX_E_ARG, "%s: PNG needs 1, 3 or 4 channels, image has %d", path, (int)img->channels);
  return png_write_channels(ctx, path, img, img->channels);
}

spx_status spx_png_write_rgb(spx_ctx *ctx, const char *path, const spx_image *img) {
  spx_status st = png_check_image(ctx, path, img);
  if (st != SPX_OK) return st;
  if (img->channels < 3)
    return spx_fail(ctx, SPX_E_ARG, "%s: spx_png_write_rgb needs >= 3 channels, image has %d", path,
                    (int)img->channels);
  return png_write_channels(ctx, path, img, 3);
}
