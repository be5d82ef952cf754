/* The colours of a scan's surface at any points (smplpix/avatar.h: spx_avatar_scan_colors). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/avatar.h"

/* Bilinear sample (clamped to the edge) of an RGB(A) image at uv, (0,0) = bottom-left: texel
 * coordinates (u W - 0.5, (1 - v) H - 0.5), as the rasterizer samples (smplpix/raster.h). */
static void sample(const spx_image *t, double u, double v, float rgb[3]) {
  double x = u * t->width - 0.5, y = (1.0 - v) * t->height - 0.5;
  x = fmin(fmax(x, 0.0), t->width - 1.0), y = fmin(fmax(y, 0.0), t->height - 1.0);
  int32_t x0 = (int32_t)x, y0 = (int32_t)y, x1 = x0 + 1 < t->width ? x0 + 1 : x0, y1 = y0 + 1 < t->height ? y0 + 1 : y0;
  double fx = x - x0, fy = y - y0;
  const int C = t->channels;
  for (int c = 0; c < 3; c++) {
    double a = t->data[((size_t)y0 * t->width + x0) * C + c], b = t->data[((size_t)y0 * t->width + x1) * C + c];
    double d = t->data[((size_t)y1 * t->width + x0) * C + c], e = t->data[((size_t)y1 * t->width + x1) * C + c];
    rgb[c] = (float)((1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * d + fx * e));
  }
}

spx_status spx_avatar_scan_colors(spx_ctx *ctx, const spx_mesh *scan, const spx_image *tex, int32_t n,
                                  const float *pts, float *col) {
  if (!scan || !pts || !col || n < 1) return spx_fail(ctx, SPX_E_ARG, "scan colours: missing argument");
  if (scan->nf < 1) return spx_fail(ctx, SPX_E_ARG, "scan colours: the scan has no faces");
  if (tex && (!scan->uv || !scan->face_uv || tex->channels < 3 || tex->width < 1 || tex->height < 1))
    return spx_fail(ctx, SPX_E_ARG, "scan colours: a texture needs the scan's texture coordinates and 3 or 4 channels");
  if (!tex && !scan->col) return spx_fail(ctx, SPX_E_ARG, "scan colours: the scan has no colours and no texture");
  int32_t *face = spx_alloc_array(ctx, (size_t)n, sizeof(int32_t), "scan colours");
  float *bary = spx_alloc_array(ctx, (size_t)n, 3 * sizeof(float), "scan colours");
  spx_status st = !face || !bary ? SPX_E_NOMEM
                                 : spx_fit_closest_points(ctx, pts, n, scan->pos, scan->nv, scan->faces, scan->nf, 1,
                                                          face, bary, NULL);
  for (int32_t i = 0; i < n && !st; i++) {
    const float *b = bary + (size_t)i * 3;
    float *out = col + (size_t)i * 3;
    if (tex) {
      const int32_t *T = scan->face_uv + (size_t)face[i] * 3;
      double u = 0, v = 0;
      for (int k = 0; k < 3; k++) u += b[k] * scan->uv[(size_t)T[k] * 2], v += b[k] * scan->uv[(size_t)T[k] * 2 + 1];
      sample(tex, u, v, out);
    } else {
      const int32_t *F = scan->faces + (size_t)face[i] * 3;
      for (int c = 0; c < 3; c++) {
        double s = 0;
        for (int k = 0; k < 3; k++) s += b[k] * scan->col[(size_t)F[k] * 3 + c];
        out[c] = (float)s;
      }
    }
  }
  free(face), free(bary);
  return st;
}
