/* A depth image as a scan (smplpix/fit.h): every pixel with depth (not 0, NaN or inf) is
 * back-projected through the pinhole camera at its centre, with its colour when an image
 * registered to the depth is given. */
#include <math.h>
#include <string.h>

#include "fit/fit_internal.h"

void spx_fit_camera_eye(const spx_camera *cam, double eye[3]) {
  for (int d = 0; d < 3; d++) eye[d] = -(cam->R[0][d] * cam->t[0] + cam->R[1][d] * cam->t[1] + cam->R[2][d] * cam->t[2]);
}

spx_status spx_fit_depth_points(spx_ctx *ctx, const char *name, const spx_camera *cam, const float *depth,
                                int32_t width, int32_t height, const float *rgb, spx_mesh *out) {
  memset(out, 0, sizeof *out);
  if (!name) name = "depth image";
  if (!cam || !depth || width < 1 || height < 1) return spx_fail(ctx, SPX_E_ARG, "%s: no depth image", name);
  if (width != cam->width || height != cam->height)
    return spx_fail(ctx, SPX_E_ARG, "%s: the depth image is %dx%d, the camera %dx%d", name, width, height, cam->width,
                    cam->height);
  size_t npx = (size_t)width * (size_t)height, n = 0;
  for (size_t p = 0; p < npx; p++) {
    float d = depth[p];
    if (d < 0)
      return spx_fail(ctx, SPX_E_ARG, "%s: depth at pixel (%d, %d) is negative (%g)", name, (int)(p % (size_t)width),
                      (int)(p / (size_t)width), (double)d);
    n += d > 0 && isfinite(d);
  }
  if (n == 0) return spx_fail(ctx, SPX_E_ARG, "%s: no pixel has depth (all 0, NaN or inf)", name);
  if (n > INT32_MAX) return spx_fail(ctx, SPX_E_ARG, "%s: too many pixels", name);
  out->pos = spx_alloc_array(ctx, n, 3 * sizeof(float), "depth points");
  if (rgb) out->col = spx_alloc_array(ctx, n, 3 * sizeof(float), "depth points");
  if (!out->pos || (rgb && !out->col)) {
    spx_mesh_free(out);
    return SPX_E_NOMEM;
  }
  /* K upper-triangular: x_c = d ((u - cx - s y) / fx, (v - cy) / fy, 1) with y = (v - cy) / fy */
  double fx = cam->K[0][0], s = cam->K[0][1], cx = cam->K[0][2], fy = cam->K[1][1], cy = cam->K[1][2];
  int32_t k = 0;
  for (int32_t j = 0; j < height; j++)
    for (int32_t i = 0; i < width; i++) {
      size_t p = (size_t)j * width + i;
      double d = depth[p];
      if (!(d > 0) || !isfinite(d)) continue;
      double y = (j + 0.5 - cy) / fy, x = (i + 0.5 - cx - s * y) / fx;
      double c[3] = {d * x - cam->t[0], d * y - cam->t[1], d - cam->t[2]};
      for (int r = 0; r < 3; r++)
        out->pos[(size_t)k * 3 + r] = (float)(cam->R[0][r] * c[0] + cam->R[1][r] * c[1] + cam->R[2][r] * c[2]);
      if (rgb) memcpy(out->col + (size_t)k * 3, rgb + p * 3, 3 * sizeof(float));
      k++;
    }
  out->nv = k;
  return SPX_OK;
}
