/* "Photos" of a synthetic subject, or of any coloured surface: the posed mesh, shaded per vertex
 * (Lambert + ambient, light fixed in the world), rasterized with its colours or texture at twice
 * the size and box-filtered 2x2 (the rasterizer's aa = 2, done here so that the same pass also
 * yields the coverage mask). */
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/raster.h"
#include "smplpix/synth.h"

spx_status spx_synth_photo_surface(spx_ctx *ctx, spx_rasterizer *r, const spx_synth_surface *sf,
                                   const spx_camera *cam, const spx_synth_light *light, uint32_t static_id, float *rgb,
                                   uint8_t *mask) {
  if (!sf || !cam || !rgb || !mask || !light) return spx_fail(ctx, SPX_E_ARG, "synth photo: missing argument");
  int32_t W = cam->width, H = cam->height, W2 = 2 * W, H2 = 2 * H;
  spx_status st = SPX_OK;
  float *col = spx_alloc_array(ctx, (size_t)sf->nv, 3 * sizeof(float), "synth photo");
  float *img = spx_alloc_array(ctx, (size_t)W2 * H2, 4 * sizeof(float), "synth photo");
  int32_t *fid = spx_alloc_array(ctx, (size_t)W2 * H2, sizeof(int32_t), "synth photo");
  if (!col || !img || !fid) {
    st = SPX_E_NOMEM;
    goto done;
  }
  if ((st = spx_synth_shade(ctx, sf->nv, sf->pos, sf->nf, sf->faces, light->dir, light->ambient, light->diffuse, col)))
    goto done;
  if (sf->albedo)
    for (size_t i = 0; i < (size_t)sf->nv * 3; i++) col[i] *= sf->albedo[i];
  spx_camera c2 = *cam;
  c2.width = W2;
  c2.height = H2;
  for (int i = 0; i < 2; i++)
    for (int j = 0; j < 3; j++) c2.K[i][j] *= 2.0;
  spx_raster_args a = {0};
  a.nverts = sf->nv;
  a.pos = sf->pos;
  a.col = col;
  a.nfaces = sf->nf;
  a.faces = sf->faces;
  if (sf->tex) {
    a.nuv = sf->nuv;
    a.uv = sf->uv;
    a.face_uv = sf->face_uv;
    a.tex_width = sf->tex_width, a.tex_height = sf->tex_height;
    a.tex_channels = sf->tex_channels;
    a.tex = sf->tex;
  }
  a.wrap = SPX_WRAP_CLAMP;
  a.ncams = 1;
  a.cams = &c2;
  a.aa = 1;
  a.cull = SPX_CULL_NONE;
  a.layout = SPX_LAYOUT_HWC;
  a.static_id = static_id;
  if ((st = r ? spx_raster(ctx, r, &a, img, fid) : spx_raster_ref(ctx, &a, img, fid))) goto done;
  for (int32_t y = 0; y < H; y++)
    for (int32_t x = 0; x < W; x++) {
      int n = 0;
      for (int c = 0; c < 3; c++) {
        float sum = 0;
        for (int dy = 0; dy < 2; dy++)
          for (int dx = 0; dx < 2; dx++) sum += img[(((size_t)(2 * y + dy)) * W2 + 2 * x + dx) * 4 + c];
        rgb[((size_t)y * W + x) * 3 + c] = sum * 0.25f;
      }
      for (int dy = 0; dy < 2; dy++)
        for (int dx = 0; dx < 2; dx++) n += fid[((size_t)(2 * y + dy)) * W2 + 2 * x + dx] >= 0;
      mask[(size_t)y * W + x] = n >= 2 ? 255 : 0;
    }
done:
  free(col);
  free(img);
  free(fid);
  return st;
}

spx_status spx_synth_photo(spx_ctx *ctx, spx_rasterizer *r, const spx_body_model *m, const spx_synth_subject *s,
                           const double *pose, const double *trans, const spx_camera *cam,
                           const spx_synth_light *light, uint32_t static_id, float *rgb, uint8_t *mask,
                           float *posed) {
  if (!cam || !rgb || !mask || !light) return spx_fail(ctx, SPX_E_ARG, "synth photo: missing argument");
  float *own = posed ? NULL : spx_alloc_array(ctx, (size_t)s->nv, 3 * sizeof(float), "synth photo");
  float *v = posed ? posed : own;
  if (!v) return SPX_E_NOMEM;
  spx_status st = spx_synth_pose(ctx, m, s, pose, trans, v);
  if (!st) {
    spx_synth_surface sf = {s->nv, v, NULL, s->nf, s->faces, s->nuv, s->uv, s->face_uv, s->tex_size, s->tex_size, 3,
                            s->tex};
    st = spx_synth_photo_surface(ctx, r, &sf, cam, light, static_id, rgb, mask);
  }
  free(own);
  return st;
}
