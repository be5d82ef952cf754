/* Private PNG entry points (fuzzers, tests). */
#ifndef SPX_IO_PNG_INTERNAL_H
#define SPX_IO_PNG_INTERNAL_H

#include "smplpix/image.h"

/* Largest width or height accepted by the PNG reader. */
#define SPX_PNG_MAX_DIM 16384

/* Decode a PNG held in memory; `name` is used in error messages. Images with more than
 * max_pixels pixels (width * height) are rejected with SPX_E_FORMAT before any pixel buffer is
 * allocated (spx_png_read uses SPX_PNG_MAX_DIM^2; the fuzzer passes less). */
spx_status spx_png_read_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, int64_t max_pixels,
                            spx_image *out);

#endif
