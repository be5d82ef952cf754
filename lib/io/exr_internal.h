/* Private OpenEXR entry points (fuzzers, tests). */
#ifndef SPX_IO_EXR_INTERNAL_H
#define SPX_IO_EXR_INTERNAL_H

#include "smplpix/image.h"

/* Largest width or height (display and data window) accepted by the EXR reader. */
#define SPX_EXR_MAX_DIM 16384

/* Decode an EXR held in memory (same rules as spx_exr_read; `name` is used in messages).
 * Files whose display or data window has more than max_pixels pixels are rejected with
 * SPX_E_FORMAT before any pixel buffer is allocated (spx_exr_read uses SPX_EXR_MAX_DIM^2). */
spx_status spx_exr_read_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, int64_t max_pixels,
                            spx_image *out);

/* The same for a depth image (lib/io/depth.c): the file needs a Z channel, or without one a Y
 * channel (OpenCV writes one-channel images as Y) read as Z (R, G, B optional: 1 when missing); NaN and Inf in Z are kept (a sensor's
 * "no data"), in R, G, B refused as always. */
spx_status spx_exr_read_depth_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, int64_t max_pixels,
                                  spx_image *out);

#endif
