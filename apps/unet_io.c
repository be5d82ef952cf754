/* Image files <-> NCHW float tensors (apps/unet_io.h). */
#include "unet_io.h"

#include "cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/npy.h"

static spx_status from_hwc(spx_ctx *ctx, const char *path, const float *src, int h, int w, int cin, int want,
                           spx_app_batch *out) {
  /* exact: an input is RGB-D (4) or RGB (3, depth taken as 1 = background); a target is RGB (3).
   * Extra channels are an error, never dropped (only a PNG's alpha is, by the caller). */
  if (cin != want && !(cin == 3 && want == 4))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: image has %d channels, expected %d%s", path, cin, want, want == 4 ? " (or 3)" : "");
  if (h < 1 || w < 1) return spx_fail(ctx, SPX_E_FORMAT, "%s: empty image (%dx%d)", path, w, h);
  size_t hw = (size_t)h * (size_t)w;
  out->data = malloc(hw * (size_t)want * sizeof(float));
  if (!out->data) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory for %dx%d pixels", path, w, h);
  for (int c = 0; c < want; c++)
    for (size_t p = 0; p < hw; p++) out->data[(size_t)c * hw + p] = c < cin ? src[p * (size_t)cin + (size_t)c] : 1.0f;
  out->n = 1, out->c = want, out->h = h, out->w = w, out->hwc = 1;
  return SPX_OK;
}

/* The colour channels (0-2) of the network's inputs and targets lie in 0..1 (depth, channel 3, is
 * any finite value): float colours in 0..255 would train or render garbage without a word. */
static spx_status colours_in_range(spx_ctx *ctx, const char *path, const spx_app_batch *b) {
  size_t hw = (size_t)b->h * (size_t)b->w;
  for (int n = 0; n < b->n; n++)
    for (int c = 0; c < 3 && c < b->c; c++) {
      const float *x = b->data + ((size_t)n * (size_t)b->c + (size_t)c) * hw;
      for (size_t p = 0; p < hw; p++)
        if (x[p] < 0 || x[p] > 1)
          return spx_fail(ctx, SPX_E_FORMAT, "%s: colour %g in channel %d at pixel (%zu, %zu)%s is outside 0..1 (an "
                          "image in 0..255 must be divided by 255, or saved as uint8)", path, x[p], c, p % (size_t)b->w,
                          p / (size_t)b->w, b->n > 1 ? " of a batch image" : "");
    }
  return SPX_OK;
}

spx_status spx_app_load(spx_ctx *ctx, const char *path, int channels, spx_app_batch *out) {
  memset(out, 0, sizeof *out);
  char ext[16];
  spx_path_ext(path, ext, sizeof ext);
  spx_status st;
  if (!strcmp(ext, "exr") || !strcmp(ext, "png")) {
    spx_image img;
    if ((st = spx_image_read(ctx, path, &img))) return st;
    int cin = img.channels;
    /* a PNG's alpha is not depth, and an RGB target does not use an EXR's depth: keep RGB */
    if (img.channels == 4 && (!strcmp(ext, "png") || channels == 3)) {
      size_t hw = (size_t)img.width * (size_t)img.height;
      for (size_t p = 0; p < hw; p++)
        for (int c = 0; c < 3; c++) img.data[p * 3 + (size_t)c] = img.data[p * 4 + (size_t)c];
      cin = 3;
    }
    st = from_hwc(ctx, path, img.data, img.height, img.width, cin, channels, out);
    spx_image_free(&img);
    if (!st && (st = colours_in_range(ctx, path, out))) spx_app_batch_free(out);
    return st;
  }
  if (!strcmp(ext, "npy")) {
    spx_array a;
    if ((st = spx_npy_load(ctx, path, &a))) return st;
    float *f = NULL;
    if ((st = spx_image_npy_values(ctx, path, &a, &f))) {
      spx_array_free(&a);
      return st;
    }
    if (a.ndim == 3 && a.shape[2] > 64) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: %lld channels, expected %d", path, (long long)a.shape[2], channels);
    } else if (a.ndim == 3 && a.shape[0] <= 65536 && a.shape[1] <= 65536) {
      st = from_hwc(ctx, path, f, (int)a.shape[0], (int)a.shape[1], (int)a.shape[2], channels, out);
    } else if (a.ndim == 4 && a.shape[1] == channels && a.shape[0] >= 1 && a.shape[0] <= 4096 && a.shape[2] >= 1 &&
               a.shape[2] <= 65536 && a.shape[3] >= 1 && a.shape[3] <= 65536) {
      out->n = (int)a.shape[0], out->c = channels, out->h = (int)a.shape[2], out->w = (int)a.shape[3];
      out->data = f;
      f = NULL;
    } else {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: expected an HxWxC image or an Nx%dxHxW batch (ndim %d)", path, channels,
                a.ndim);
    }
    for (size_t i = 0; !st && out->data && i < (size_t)out->n * out->c * out->h * out->w; i++)
      if (!isfinite(out->data[i])) st = spx_fail(ctx, SPX_E_NUMERIC, "%s: NaN or Inf at element %ld", path, (long)i);
    if (!st && out->data) st = colours_in_range(ctx, path, out);
    if (st) spx_app_batch_free(out);
    free(f);
    spx_array_free(&a);
    return st;
  }
  return spx_fail(ctx, SPX_E_ARG, "%s: unknown image type (expected .exr, .png or .npy)", path);
}

spx_status spx_app_save(spx_ctx *ctx, const char *path, const spx_app_batch *b) {
  char ext[16];
  spx_path_ext(path, ext, sizeof ext);
  size_t hw = (size_t)b->h * (size_t)b->w;
  if (!strcmp(ext, "npy") && !(b->hwc && b->n == 1)) { /* a batch: NxCxHxW */
    int64_t shape[4] = {b->n, b->c, b->h, b->w};
    return spx_npy_save_f32(ctx, path, b->data, 4, shape);
  }
  if (!spx_image_ext_ok(path))
    return spx_fail(ctx, SPX_E_ARG, "%s: unknown output type (expected .png, .exr or .npy)", path);
  if (b->n != 1) return spx_fail(ctx, SPX_E_ARG, "%s: a batch of %d images needs a .npy output", path, b->n);
  spx_image img; /* one image: HWC, written by its extension */
  spx_status st = spx_image_alloc(ctx, b->w, b->h, b->c, &img);
  if (st) return st;
  for (int c = 0; c < b->c; c++)
    for (size_t p = 0; p < hw; p++) img.data[p * (size_t)b->c + (size_t)c] = b->data[(size_t)c * hw + p];
  st = spx_image_write(ctx, path, &img);
  spx_image_free(&img);
  return st;
}

void spx_app_batch_free(spx_app_batch *b) {
  free(b->data);
  memset(b, 0, sizeof *b);
}
