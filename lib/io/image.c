/* In-memory HWC float images: allocation and release; the whole-file read of the PNG and EXR
 * readers (io/image_internal.h). */
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "io/image_internal.h"
#include "smplpix/image.h"

spx_status spx_image_alloc(spx_ctx *ctx, int32_t width, int32_t height, int32_t channels, spx_image *out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "spx_image_alloc: out is NULL");
  memset(out, 0, sizeof *out);
  if (width <= 0 || height <= 0 || channels <= 0)
    return spx_fail(ctx, SPX_E_ARG, "spx_image_alloc: invalid size %dx%dx%d", (int)width, (int)height,
                    (int)channels);
  size_t n;
  if (!spx_mul_size((size_t)width, (size_t)height, &n) || !spx_mul_size(n, (size_t)channels, &n))
    return spx_fail(ctx, SPX_E_ARG, "spx_image_alloc: size %dx%dx%d overflows", (int)width, (int)height,
                    (int)channels);
  /* calloc: zeroed, and a large image's pages are not touched before its pixels are written */
  float *d = n <= SIZE_MAX / sizeof(float) ? calloc(n ? n : 1, sizeof(float)) : NULL;
  if (!d)
    return spx_fail(ctx, SPX_E_NOMEM, "image: cannot allocate %dx%dx%d floats (%zu MB)", (int)width, (int)height,
                    (int)channels, n / (1u << 20) * sizeof(float));
  out->width = width;
  out->height = height;
  out->channels = channels;
  out->data = d;
  return SPX_OK;
}

void spx_image_free(spx_image *img) {
  if (!img) return;
  free(img->data);
  memset(img, 0, sizeof *img);
}

spx_status spx_image_read_file(spx_ctx *ctx, const char *fn, const char *path, size_t max_file, int64_t max_pixels,
                               spx_image_decode_fn dec, spx_image *out) {
  spx_status st = spx_read_args(ctx, fn, out, sizeof *out, path);
  if (st != SPX_OK) return st;
  unsigned char *buf = NULL;
  size_t n = 0;
  st = spx_read_file(ctx, path, max_file, &buf, &n);
  if (st != SPX_OK) return st;
  st = dec(ctx, path, buf, n, max_pixels, out);
  free(buf);
  return st;
}
