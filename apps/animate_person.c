/* The person of an `animate` / `render --avatar` frame and the drawing of a frame (apps/animate.h). */
#include <stdlib.h>
#include <string.h>

#include "animate.h"
#include "cli_scene.h"
#include "cmd_fit.h"

int spx_anim_person_open(const char *cmd, spx_ctx *ctx, const char *reg_path, const char *avatar_path,
                         const char *model, spx_anim_person *p) {
  memset(p, 0, sizeof *p);
  if (avatar_path) {
    if (spx_avatar_load(ctx, avatar_path, model, &p->av)) return spx_cli_error(cmd, ctx);
    spx_avatar_info info;
    spx_avatar_get_info(p->av, &info);
    p->body = spx_avatar_body(p->av), p->nv = info.vertices, p->col = spx_avatar_colors(p->av);
    p->faces = spx_avatar_faces(p->av, &p->nf);
    return SPX_EXIT_OK;
  }
  int rc = spx_cli_load_registration(cmd, ctx, reg_path, model, &p->r, &p->m);
  if (rc) return rc;
  p->body = &p->m, p->nv = p->m.nv, p->nf = p->m.nf, p->faces = p->m.faces, p->col = p->r.colors;
  p->work = malloc((size_t)p->m.nv * 3 * sizeof(double));
  if (!p->r.colors) p->col = p->own = malloc((size_t)p->m.nv * 3 * sizeof(float));
  if (!p->work || !p->col) return spx_cli_errorf(cmd, "out of memory");
  return SPX_EXIT_OK;
}

int spx_anim_person_pose(const char *cmd, spx_ctx *ctx, spx_anim_person *p, const double *pose, const double *trans,
                         float *pos) {
  if (p->av) return spx_avatar_pose(p->av, pose, trans, pos) ? spx_cli_error(cmd, ctx) : SPX_EXIT_OK;
  int rc = spx_cli_pose_registration(cmd, ctx, &p->m, &p->r, p->r.betas, pose, trans, p->work, pos);
  if (!rc && p->own) {
    spx_mesh view = {p->m.nv, p->m.nf, pos, NULL, NULL, p->m.faces, 0, NULL, NULL};
    spx_cli_normal_colors(&view, p->own);
  }
  return rc;
}

void spx_anim_person_close(spx_anim_person *p) {
  spx_avatar_destroy(p->av);
  spx_body_free(&p->m);
  spx_fit_result_free(&p->r);
  free(p->own), free(p->work);
  memset(p, 0, sizeof *p);
}

spx_status spx_anim_drawer_init(spx_ctx *ctx, spx_anim_drawer *d, int mode, spx_unet *u, int W, int H) {
  memset(d, 0, sizeof *d);
  d->mode = mode, d->u = u, d->W = W, d->H = H;
  if (!(d->buf = malloc((size_t)W * H * 4 * sizeof(float)))) return spx_fail(ctx, SPX_E_NOMEM, "out of memory");
  if (mode == SPX_ANIM_RASTER) return spx_rasterizer_create(ctx, &d->rast);
  spx_status st = spx_projector_create(ctx, &d->proj);
  if (!st && mode == SPX_ANIM_NETWORK) st = spx_device_tensor_create(ctx, 1, SPX_UNET_IN_CHANNELS, H, W, &d->tin);
  return st;
}

void spx_anim_drawer_free(spx_anim_drawer *d) {
  free(d->buf);
  spx_device_tensor_free(d->tin);
  spx_projector_destroy(d->proj);
  spx_rasterizer_destroy(d->rast);
  memset(d, 0, sizeof *d);
}

spx_status spx_anim_draw(spx_ctx *ctx, spx_anim_drawer *d, const spx_anim_person *p, const float *pos,
                         const spx_camera *cam, spx_image *img) {
  spx_status st;
  size_t hw = (size_t)d->W * (size_t)d->H;
  int nchw = d->mode == SPX_ANIM_NETWORK;
  if (d->mode == SPX_ANIM_RASTER) {
    spx_raster_args ra = {0};
    ra.nverts = p->nv, ra.pos = pos, ra.col = p->col, ra.nfaces = p->nf, ra.faces = p->faces;
    ra.ncams = 1, ra.cams = cam, ra.aa = 2, ra.layout = SPX_LAYOUT_HWC, ra.static_id = 1;
    st = spx_raster(ctx, d->rast, &ra, d->buf, NULL);
  } else {
    spx_project_args pa = {1, p->nv, pos, p->col, 1, cam, nchw ? SPX_LAYOUT_NCHW : SPX_LAYOUT_HWC};
    st = nchw ? spx_project_to_tensor(ctx, d->proj, &pa, d->tin) : spx_project(ctx, d->proj, &pa, d->buf, NULL);
    if (!st && nchw) st = spx_unet_forward_tensor(d->u, d->tin, d->buf);
  }
  if (st) return st;
  for (size_t q = 0; q < hw; q++) /* network output [3,H,W]; projection and raster HWC, 4 channels */
    for (int c = 0; c < 3; c++) img->data[q * 3 + (size_t)c] = nchw ? d->buf[(size_t)c * hw + q] : d->buf[q * 4 + (size_t)c];
  return SPX_OK;
}
