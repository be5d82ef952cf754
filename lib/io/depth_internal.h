/* Private depth-image entry point (fuzzers, tests): lib/io/depth.c. */
#ifndef SPX_IO_DEPTH_INTERNAL_H
#define SPX_IO_DEPTH_INTERNAL_H

#include "smplpix/depth.h"

/* spx_depth_read's decoding and checks (without a camera) of a file held in memory; the format
 * comes from name's extension. Images over max_pixels pixels are refused before any pixel buffer
 * is allocated. */
spx_status spx_depth_read_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, int64_t max_pixels,
                              spx_depth *out);

#endif
