/* Images: HWC float32 in memory; OpenEXR (RGB-D: float channels R,G,B,Z) and PNG (8-bit). */
#ifndef SMPLPIX_IMAGE_H
#define SMPLPIX_IMAGE_H

#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_image {
  int32_t width, height, channels;
  float *data; /* height*width*channels, row-major, channel-interleaved (HWC) */
} spx_image;

/* Allocate a zeroed image. */
spx_status spx_image_alloc(spx_ctx *ctx, int32_t width, int32_t height, int32_t channels, spx_image *out);
void spx_image_free(spx_image *img);

/* OpenEXR through the OpenEXR C API. Write: 3 channels → R,G,B; 4 → R,G,B,Z; float32,
 * ZIP compression, atomically. Read: R,G,B (+Z if present; missing Z reads as 1 = background)
 * as a 4-channel image; any pixel type is converted to float; a file without R,G,B is an error.
 * The image has the size of the display window; pixels outside the data window read as
 * (1,1,1,1) = background. Scanline and tiled files (level 0) are read; deep files are an error;
 * windows larger than 16384 on a side are rejected. */
spx_status spx_exr_write(spx_ctx *ctx, const char *path, const spx_image *img);
spx_status spx_exr_read(spx_ctx *ctx, const char *path, spx_image *out);

/* PNG through libpng: write 1 (gray), 3 (RGB) or 4 (RGBA) channels of [0,1] floats as 8-bit
 * (clamped, rounded), atomically. An RGB-D image is written with `channels` = 3 by passing a
 * view, see spx_png_write_rgb. Read any PNG as float [0,1] with 1, 3 or 4 channels (palette and
 * 16-bit are converted). */
spx_status spx_png_write(spx_ctx *ctx, const char *path, const spx_image *img);
/* Write only the first three channels of a (>= 3 channel) image. */
spx_status spx_png_write_rgb(spx_ctx *ctx, const char *path, const spx_image *img);
spx_status spx_png_read(spx_ctx *ctx, const char *path, spx_image *out);

/* By extension (any case; lib/io/image_file.c). spx_image_ext_ok: the path ends in .exr, .png
 * or .npy. Write: .exr as spx_exr_write; .png the first three channels (spx_png_write_rgb: an
 * RGB-D image loses its depth) or a 1-channel gray image; .npy an HxWxC float32 array. Read:
 * .exr / .png as spx_exr_read / spx_png_read; .npy an HxW or HxWxC array (C <= 64) by the one
 * rule of spx_image_npy_values. Another extension is SPX_E_ARG naming the file. */
int spx_image_ext_ok(const char *path);
spx_status spx_image_write(spx_ctx *ctx, const char *path, const spx_image *img);
spx_status spx_image_read(spx_ctx *ctx, const char *path, spx_image *out);
/* The pixel values of an image array read from a .npy (any shape), by one rule for every reader:
 * float16/32/64 as they are; uint8 scaled by 1/255 like an 8-bit PNG; any other integer or bool
 * dtype refused (SPX_E_FORMAT naming path: its scale is unknown). *out: malloc'd floats. */
struct spx_array;
spx_status spx_image_npy_values(spx_ctx *ctx, const char *path, const struct spx_array *a, float **out);

#ifdef __cplusplus
}
#endif
#endif
