/* Image files by extension: one dispatch for .exr, .png and .npy (smplpix/image.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/files.h"
#include "smplpix/image.h"
#include "smplpix/npy.h"

int spx_image_ext_ok(const char *path) {
  char ext[16];
  spx_path_ext(path, ext, sizeof ext);
  return !strcmp(ext, "exr") || !strcmp(ext, "png") || !strcmp(ext, "npy");
}

spx_status spx_image_write(spx_ctx *ctx, const char *path, const spx_image *img) {
  char ext[16];
  spx_path_ext(path, ext, sizeof ext);
  if (!strcmp(ext, "exr")) return spx_exr_write(ctx, path, img);
  if (!strcmp(ext, "png")) return img->channels >= 3 ? spx_png_write_rgb(ctx, path, img) : spx_png_write(ctx, path, img);
  if (!strcmp(ext, "npy")) {
    int64_t shape[3] = {img->height, img->width, img->channels};
    return spx_npy_save_f32(ctx, path, img->data, 3, shape);
  }
  return spx_fail(ctx, SPX_E_ARG, "%s: unknown image type (expected .exr, .png or .npy)", path);
}

spx_status spx_image_npy_values(spx_ctx *ctx, const char *path, const struct spx_array *a, float **out) {
  *out = NULL;
  if (a->dtype != SPX_U8 && a->dtype != SPX_F16 && a->dtype != SPX_F32 && a->dtype != SPX_F64)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: %s image: integer images must be uint8 (read as value/255, like PNG) or "
                    "floating point", path, spx_dtype_name(a->dtype));
  spx_status st = spx_array_to_f32(ctx, a, out);
  if (st) return spx_fail(ctx, st, "%s: %s", path, spx_ctx_message(ctx)); /* out of memory: name the file */
  if (a->dtype != SPX_U8) return SPX_OK;
  size_t n = 1;
  for (int d = 0; d < a->ndim; d++) n *= (size_t)a->shape[d];
  for (size_t i = 0; i < n; i++) (*out)[i] /= 255.0f;
  return SPX_OK;
}

/* .npy: HxW or HxWxC (C in 1..64), as float HWC by spx_image_npy_values. */
static spx_status read_npy(spx_ctx *ctx, const char *path, spx_image *img) {
  spx_array a;
  spx_status st = spx_npy_load(ctx, path, &a);
  if (st) return st;
  float *f = NULL;
  if (a.ndim != 2 && a.ndim != 3)
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: expected an HxWxC or HxW image, not %d dimensions", path, a.ndim);
  else if (a.shape[0] < 1 || a.shape[1] < 1 || a.shape[0] > 65536 || a.shape[1] > 65536 ||
           (a.ndim == 3 && (a.shape[2] < 1 || a.shape[2] > 64)))
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: unsupported image shape %lldx%lld%s", path, (long long)a.shape[0],
                  (long long)a.shape[1], a.ndim == 3 ? "xC (C in 1..64)" : "");
  else
    st = spx_image_npy_values(ctx, path, &a, &f);
  int C = a.ndim == 3 ? (int)a.shape[2] : 1;
  for (size_t i = 0, n = st ? 0 : (size_t)a.shape[0] * (size_t)a.shape[1] * (size_t)C; i < n; i++)
    if (!isfinite(f[i])) { /* as in every image input: refused, never used (a NaN mask is no mask) */
      size_t px = i / (size_t)C;
      st = spx_fail(ctx, SPX_E_NUMERIC, "%s: %s in channel %d at pixel (%zu, %zu) (image values must be finite)", path, isnan(f[i]) ? "NaN" : "Inf",
                    (int)(i % (size_t)C), px % (size_t)a.shape[1], px / (size_t)a.shape[1]);
      free(f);
      f = NULL;
      break;
    }
  if (!st) {
    img->height = (int32_t)a.shape[0], img->width = (int32_t)a.shape[1];
    img->channels = a.ndim == 3 ? (int32_t)a.shape[2] : 1;
    img->data = f;
  }
  spx_array_free(&a);
  return st;
}

spx_status spx_image_read(spx_ctx *ctx, const char *path, spx_image *out) {
  char ext[16];
  memset(out, 0, sizeof *out);
  spx_path_ext(path, ext, sizeof ext);
  if (!strcmp(ext, "exr")) return spx_exr_read(ctx, path, out);
  if (!strcmp(ext, "png")) return spx_png_read(ctx, path, out);
  if (!strcmp(ext, "npy")) return read_npy(ctx, path, out);
  return spx_fail(ctx, SPX_E_ARG, "%s: unknown image type (expected .png, .exr or .npy)", path);
}
