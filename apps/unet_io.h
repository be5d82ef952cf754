/* Image files <-> NCHW float tensors for the network subcommands (render, train). */
#ifndef SPX_APPS_UNET_IO_H
#define SPX_APPS_UNET_IO_H

#include "smplpix/smplpix.h"

/* A batch of images as one NCHW float array. */
typedef struct spx_app_batch {
  int n, c, h, w;
  int hwc; /* loaded from a single HWC image (EXR, PNG, HxWxC .npy) rather than an NCHW .npy */
  float *data;
} spx_app_batch;

/* Errors: every failure, the library's or one found here (wrong channel count, unknown
 * extension, ...), leaves its one-line message in ctx. Print it as "smplpix <cmd>: error: ..." and return the exit code. */
int spx_cli_error(const char *cmd, spx_ctx *ctx);

/* Load `path` (.exr, .png, .npy) as `channels` channels (4: RGB-D input, 3: RGB target).
 * A 3-channel image asked for 4 gets depth 1 (background), like an EXR without Z; RGBA PNGs
 * drop alpha when 3 are asked for. .npy: HxWxC (one image) or NxCxHxW (a batch). Errors name the
 * file and what was expected. */
spx_status spx_app_load(spx_ctx *ctx, const char *path, int channels, spx_app_batch *out);
/* Write a 3-channel batch: .png (8 bit, clamped) and .exr need n == 1; .npy writes HxWx3 when
 * hwc and n == 1, else NxCxHxW. */
spx_status spx_app_save(spx_ctx *ctx, const char *path, const spx_app_batch *b);
void spx_app_batch_free(spx_app_batch *b);

#endif
