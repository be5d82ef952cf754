/* Plain-C reference of the projection (single-thread z-buffer with the kernel's float
 * arithmetic, kernels/project.cl) and of its backward; also the argument checks both share. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/project_internal.h"

void spx_project_cam_floats(const spx_camera *cam, float o[SPX_CAM_FLOATS]) {
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) {
      o[r * 3 + c] = (float)cam->K[r][c];
      o[9 + r * 3 + c] = (float)cam->R[r][c];
    }
  for (int r = 0; r < 3; r++) o[18 + r] = (float)cam->t[r];
}

spx_status spx_project_check(spx_ctx *ctx, const char *fn, int32_t batch, int32_t nverts, int32_t ncams,
                             const spx_camera *cams) {
  if (batch < 1 || ncams < 1 || nverts < 0)
    return spx_fail(ctx, SPX_E_ARG, "%s: batch %d, cameras %d, vertices %d: need batch >= 1, cameras >= 1, vertices >= 0",
                    fn, batch, ncams, nverts);
  if (!cams) return spx_fail(ctx, SPX_E_ARG, "%s: no cameras", fn);
  for (int32_t c = 0; c < ncams; c++) {
    const spx_camera *k = &cams[c];
    char name[96];
    snprintf(name, sizeof name, "%s: camera %d", fn, c);
    spx_status st = spx_camera_validate(ctx, name, k);
    if (st) return st;
    if (k->width != cams[0].width || k->height != cams[0].height)
      return spx_fail(ctx, SPX_E_ARG, "%s: camera %d is %dx%d but camera 0 is %dx%d (one batch needs one size)", fn, c,
                      k->width, k->height, cams[0].width, cams[0].height);
    float f[SPX_CAM_FLOATS];
    spx_project_cam_floats(k, f);
    for (int i = 0; i < SPX_CAM_FLOATS; i++)
      if (!isfinite(f[i])) return spx_fail(ctx, SPX_E_NUMERIC, "%s: K, R or t overflows float32", name);
  }
  size_t hw = (size_t)cams[0].width * (size_t)cams[0].height, t;
  if (!spx_mul_size((size_t)batch, (size_t)ncams, &t) || !spx_mul_size(t, hw, &t) || t > 0x7fffffffu ||
      !spx_mul_size((size_t)batch * (size_t)ncams, (size_t)nverts, &t) || t > 0x7fffffffu)
    return spx_fail(ctx, SPX_E_ARG, "%s: %d sets x %d cameras x %d vertices (or pixels) is too large", fn, batch, ncams,
                    nverts);
  return SPX_OK;
}

/* Same arithmetic as spx_project_point in kernels/project.cl. */
static int project_point(const float *cam, const float *xp, int W, int H, int *pix, float *depth) {
  const float *K = cam, *R = cam + 9, *t = cam + 18;
  float x = xp[0], y = xp[1], z = xp[2];
  float p0 = ((R[0] * x + R[1] * y) + R[2] * z) + t[0];
  float p1 = ((R[3] * x + R[4] * y) + R[5] * z) + t[1];
  float p2 = ((R[6] * x + R[7] * y) + R[8] * z) + t[2];
  float uq = (K[0] * p0 + K[1] * p1) + K[2] * p2;
  float vq = (K[3] * p0 + K[4] * p1) + K[5] * p2;
  float d = (K[6] * p0 + K[7] * p1) + K[8] * p2;
  if (!(d > 0.0f) || !isfinite(d) || !isfinite(uq) || !isfinite(vq)) return 0;
  float u = uq / d, v = vq / d;
  if (!(u >= 0.0f && u < (float)W && v >= 0.0f && v < (float)H)) return 0;
  *pix = (int)v * W + (int)u;
  *depth = d;
  return 1;
}

spx_status spx_project_ref(spx_ctx *ctx, const spx_project_args *a, float *out, int32_t *winners) {
  if (!a || !out) return spx_fail(ctx, SPX_E_ARG, "spx_project_ref: NULL arguments");
  spx_status st = spx_project_check(ctx, "spx_project_ref", a->batch, a->nverts, a->ncams, a->cams);
  if (st) return st;
  if (a->nverts > 0 && !a->pos) return spx_fail(ctx, SPX_E_ARG, "spx_project_ref: no positions");
  int W = a->cams[0].width, H = a->cams[0].height;
  size_t hw = (size_t)W * H, nimg = (size_t)a->batch * a->ncams;
  int32_t *win = winners;
  if (!win && !(win = spx_alloc_array(ctx, hw, sizeof *win, "spx_project_ref"))) return SPX_E_NOMEM;
  for (size_t img = 0; img < nimg; img++) {
    int32_t *w = winners ? winners + img * hw : win;
    float *o = out + img * hw * 4;
    int b = (int)(img / (size_t)a->ncams), c = (int)(img % (size_t)a->ncams);
    float cam[SPX_CAM_FLOATS];
    spx_project_cam_floats(&a->cams[c], cam);
    for (size_t i = 0; i < hw; i++) w[i] = -1;
    for (size_t i = 0; i < hw * 4; i++) o[i] = 1.0f;
    float *zd = o + 3; /* z-buffer: the image's own depth channel, valid where w >= 0 */
    for (int32_t v = 0; v < a->nverts; v++) {
      int pix;
      float d;
      if (!project_point(cam, a->pos + ((size_t)b * a->nverts + v) * 3, W, H, &pix, &d)) continue;
      if (w[pix] >= 0 && !(d < zd[(size_t)pix * 4])) continue; /* nearer wins; ties: first (smallest) index */
      w[pix] = v;
      float *px = o + (size_t)pix * 4;
      const float *cv = a->col ? a->col + ((size_t)b * a->nverts + v) * 3 : NULL;
      px[0] = cv ? cv[0] : 1.0f;
      px[1] = cv ? cv[1] : 1.0f;
      px[2] = cv ? cv[2] : 1.0f;
      px[3] = d;
    }
    if (a->layout == SPX_LAYOUT_NCHW) { /* built in HWC, transposed to NCHW through a copy */
      float *tmp = malloc(hw * 4 * sizeof *tmp);
      if (!tmp) {
        if (!winners) free(win);
        return spx_fail(ctx, SPX_E_NOMEM, "spx_project_ref: out of memory");
      }
      memcpy(tmp, o, hw * 4 * sizeof *tmp);
      for (size_t i = 0; i < hw; i++)
        for (int k = 0; k < 4; k++) o[k * hw + i] = tmp[i * 4 + k];
      free(tmp);
    }
  }
  if (!winners) free(win);
  return SPX_OK;
}

void spx_project_backward_ref(const spx_project_args *a, const int32_t *winners, const float *grad_img,
                              float *grad_col, float *grad_pos) {
  if (!a || !a->cams || !winners || !grad_img || a->batch < 1 || a->ncams < 1) return;
  size_t hw = (size_t)a->cams[0].width * a->cams[0].height;
  for (int32_t b = 0; b < a->batch; b++)
    for (int32_t c = 0; c < a->ncams; c++) {
      size_t img = (size_t)b * a->ncams + c;
      float cam[SPX_CAM_FLOATS];
      spx_project_cam_floats(&a->cams[c], cam);
      const float *K = cam, *R = cam + 9;
      float dd[3];
      for (int j = 0; j < 3; j++) dd[j] = (K[6] * R[j] + K[7] * R[3 + j]) + K[8] * R[6 + j];
      for (size_t p = 0; p < hw; p++) {
        int32_t w = winners[img * hw + p];
        if (w < 0 || w >= a->nverts) continue;
        float g[4];
        for (int k = 0; k < 4; k++)
          g[k] = a->layout == SPX_LAYOUT_HWC ? grad_img[(img * hw + p) * 4 + k] : grad_img[(img * 4 + k) * hw + p];
        size_t v = (size_t)b * a->nverts + w;
        if (grad_col)
          for (int k = 0; k < 3; k++) grad_col[v * 3 + k] += g[k];
        if (grad_pos)
          for (int j = 0; j < 3; j++) grad_pos[v * 3 + j] += g[3] * dd[j];
      }
    }
}
