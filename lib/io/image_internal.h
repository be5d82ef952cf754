/* Private: the whole-file read that the PNG and EXR readers share. */
#ifndef SPX_IO_IMAGE_INTERNAL_H
#define SPX_IO_IMAGE_INTERNAL_H

#include "smplpix/image.h"

/* A decoder of an image held in memory (spx_png_read_mem, spx_exr_read_mem). */
typedef spx_status (*spx_image_decode_fn)(spx_ctx *ctx, const char *name, const void *data, size_t size,
                                          int64_t max_pixels, spx_image *out);

/* The body of a reader fn(ctx, path, out): the arguments checked (spx_read_args), the file at path
 * read whole (at most max_file bytes) and decoded by dec (at most max_pixels pixels). */
spx_status spx_image_read_file(spx_ctx *ctx, const char *fn, const char *path, size_t max_file, int64_t max_pixels,
                               spx_image_decode_fn dec, spx_image *out);

#endif
