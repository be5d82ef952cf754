/* The avatar object: a registered body at one of its vertex counts, the colours of those vertices
 * and the network; posing, rendering, the file (smplpix/avatar.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "avatar/avatar_internal.h"
#include "core/internal.h"
#include "smplpix/render.h"
#include "smplpix/safetensors.h"

void spx_avatar_destroy(spx_avatar *a) {
  if (!a) return;
  spx_unet_destroy(a->u);
  spx_body_free(&a->m);
  spx_fit_result_free(&a->r);
  for (int l = 0; l < 2; l++) spx_loop_plan_free(&a->plan[l]);
  free(a->colors), free(a->model_path), free(a->work), free(a->pos), free(a->tmp), free(a->nchw);
  spx_projector_destroy(a->proj);
  spx_device_tensor_free(a->tin);
  free(a);
}

/* The registration parts an avatar keeps (its own copies). */
static spx_status copy_registration(spx_ctx *ctx, const spx_fit_result *src, spx_fit_result *dst) {
  memset(dst, 0, sizeof *dst);
  dst->nv = src->nv, dst->nj = src->nj, dst->nbetas = src->nbetas, dst->nf = src->nf;
  dst->unit_scale = src->unit_scale, dst->sim_scale = src->sim_scale, dst->body_scale = src->body_scale;
  memcpy(dst->sim_R, src->sim_R, sizeof dst->sim_R);
  memcpy(dst->sim_t, src->sim_t, sizeof dst->sim_t);
  memcpy(dst->trans, src->trans, sizeof dst->trans);
  dst->betas = spx_alloc_array(ctx, (size_t)src->nbetas + 1, sizeof(double), "avatar");
  dst->pose = spx_alloc_array(ctx, (size_t)src->nj, 3 * sizeof(double), "avatar");
  dst->template_unposed = spx_alloc_array(ctx, (size_t)src->nv, 3 * sizeof(double), "avatar");
  if (!dst->betas || !dst->pose || !dst->template_unposed) return SPX_E_NOMEM;
  if (src->nbetas) memcpy(dst->betas, src->betas, (size_t)src->nbetas * sizeof(double));
  memcpy(dst->pose, src->pose, (size_t)src->nj * 3 * sizeof(double));
  memcpy(dst->template_unposed, src->template_unposed, (size_t)src->nv * 3 * sizeof(double));
  return SPX_OK;
}

/* The Loop plans of `subdivide` steps, the vertex count, the posing buffers. */
static spx_status prepare(spx_ctx *ctx, spx_avatar *a, int32_t subdivide) {
  if (subdivide < 0 || subdivide > 2) return spx_fail(ctx, SPX_E_ARG, "avatar: %d Loop steps (0, 1 or 2)", subdivide);
  a->subdivide = subdivide, a->nv_in = a->m.nv;
  const int32_t *faces = a->m.faces;
  int32_t nv = a->m.nv, nf = a->m.nf;
  for (int l = 0; l < subdivide; l++) {
    spx_status st = spx_loop_plan_create(ctx, nv, nf, faces, &a->plan[l]);
    if (st) return st;
    nv = a->plan[l].nv_out, nf = a->plan[l].nf_out, faces = a->plan[l].faces_out;
  }
  a->nv_in = nv, a->nf_in = nf, a->faces_in = faces;
  a->work = spx_alloc_array(ctx, (size_t)a->m.nv, 3 * sizeof(double), "avatar");
  a->pos = spx_alloc_array(ctx, (size_t)a->m.nv, 3 * sizeof(float), "avatar");
  a->tmp = spx_alloc_array(ctx, (size_t)(subdivide ? a->plan[0].nv_out : 1), 3 * sizeof(float), "avatar");
  a->colors = spx_alloc_array(ctx, (size_t)a->nv_in, 3 * sizeof(float), "avatar");
  if (!a->work || !a->pos || !a->tmp || !a->colors) return SPX_E_NOMEM;
  return SPX_OK;
}

/* in (the body's vertex count, dim channels) through the avatar's Loop steps into out (nv_in). */
static void subdivide_attr(const spx_avatar *a, const float *in, int dim, float *out) {
  if (a->subdivide == 0) memcpy(out, in, (size_t)a->m.nv * dim * sizeof(float));
  else if (a->subdivide == 1) spx_loop_plan_apply(&a->plan[0], in, dim, out);
  else {
    spx_loop_plan_apply(&a->plan[0], in, dim, a->tmp);
    spx_loop_plan_apply(&a->plan[1], a->tmp, dim, out);
  }
}

spx_status spx_avatar_create(spx_ctx *ctx, const char *model_path, const spx_fit_result *r, int32_t subdivide,
                             spx_avatar **out) {
  *out = NULL;
  if (!model_path || !r || !r->template_unposed || !r->pose)
    return spx_fail(ctx, SPX_E_ARG, "avatar: a body model path and a registration with its template are needed");
  spx_avatar *a = calloc(1, sizeof *a);
  if (!a) return spx_fail(ctx, SPX_E_NOMEM, "avatar: out of memory");
  a->ctx = ctx;
  spx_status st = spx_body_load(ctx, model_path, &a->m);
  if (!st && (r->nv != a->m.nv || r->nj != a->m.nj || r->nbetas > a->m.nbetas))
    st = spx_fail(ctx, SPX_E_ARG, "%s: the registration (%d vertices, %d joints, %d betas) is not of this body model "
                  "(%d, %d, %d)", model_path, r->nv, r->nj, r->nbetas, a->m.nv, a->m.nj, a->m.nbetas);
  size_t len = strlen(model_path) + 1;
  if (!st && !(a->model_path = malloc(len))) st = spx_fail(ctx, SPX_E_NOMEM, "avatar: out of memory");
  if (!st) memcpy(a->model_path, model_path, len);
  a->train_cpu = -1;
  if (!st) st = copy_registration(ctx, r, &a->r);
  if (!st) st = prepare(ctx, a, subdivide);
  if (!st) { /* colours: the registration's through the Loop steps, else grey */
    if (r->colors) subdivide_attr(a, r->colors, 3, a->colors);
    else
      for (size_t i = 0; i < (size_t)a->nv_in * 3; i++) a->colors[i] = 0.5f;
  }
  if (st) {
    spx_avatar_destroy(a);
    return st;
  }
  *out = a;
  return SPX_OK;
}

void spx_avatar_set_colors(spx_avatar *a, const float *colors) {
  memcpy(a->colors, colors, (size_t)a->nv_in * 3 * sizeof(float));
}

void spx_avatar_set_unet(spx_avatar *a, spx_unet *u) {
  if (a->u != u) spx_unet_destroy(a->u);
  a->u = u;
}

void spx_avatar_get_info(const spx_avatar *a, spx_avatar_info *out) {
  memset(out, 0, sizeof *out);
  out->vertices = a->nv_in, out->subdivide = a->subdivide;
  out->image_width = a->img_w, out->image_height = a->img_h;
  out->net_width = a->u ? spx_unet_width(a->u) : 0;
  out->joints = a->m.nj;
  out->train_cpu_seconds = a->train_cpu;
  out->model_path = a->model_path;
}

const spx_body_model *spx_avatar_body(const spx_avatar *a) { return &a->m; }
const spx_fit_result *spx_avatar_registration(const spx_avatar *a) { return &a->r; }
const float *spx_avatar_colors(const spx_avatar *a) { return a->colors; }
spx_unet *spx_avatar_unet(spx_avatar *a) { return a->u; }
const int32_t *spx_avatar_faces(const spx_avatar *a, int32_t *nf) {
  *nf = a->nf_in;
  return a->faces_in;
}

spx_status spx_avatar_pose(spx_avatar *a, const double *pose, const double *trans, float *verts) {
  const spx_fit_result *r = &a->r;
  spx_body_params p = {r->nbetas, r->betas, pose ? pose : r->pose, trans ? trans : r->trans, r->template_unposed};
  spx_status st = spx_body_forward_ref(a->ctx, &a->m, &p, a->work, NULL);
  if (st) return st;
  for (size_t i = 0; i < (size_t)a->m.nv * 3; i++) a->pos[i] = (float)(r->body_scale * a->work[i]);
  subdivide_attr(a, a->pos, 3, verts);
  return SPX_OK;
}

/* The projection's device tensor for a cam-sized image, and the host buffers of one render. */
static spx_status ensure_render(spx_avatar *a, int32_t W, int32_t H) {
  spx_ctx *ctx = a->ctx;
  if (!a->proj) {
    spx_status st = spx_projector_create(ctx, &a->proj);
    if (st) return st;
  }
  if (a->tin && a->tin_w == W && a->tin_h == H) return SPX_OK;
  spx_device_tensor_free(a->tin);
  a->tin = NULL;
  free(a->nchw);
  if (!(a->nchw = spx_alloc_array(ctx, (size_t)W * H, 3 * sizeof(float), "avatar render"))) return SPX_E_NOMEM;
  spx_status st = spx_device_tensor_create(ctx, 1, SPX_UNET_IN_CHANNELS, H, W, &a->tin);
  if (!st) a->tin_w = W, a->tin_h = H;
  return st;
}

spx_status spx_avatar_render(spx_avatar *a, const double *pose, const double *trans, const spx_camera *cam,
                             float *rgb, float *input) {
  spx_ctx *ctx = a->ctx;
  if (!a->u) return spx_fail(ctx, SPX_E_ARG, "avatar render: the avatar has no network");
  if (!cam || !rgb) return spx_fail(ctx, SPX_E_ARG, "avatar render: missing camera or output");
  int32_t W = cam->width, H = cam->height;
  if (W < 16 || H < 16) return spx_fail(ctx, SPX_E_ARG, "avatar render: %dx%d is too small (the UNet needs 16x16)", W, H);
  float *verts = spx_alloc_array(ctx, (size_t)a->nv_in, 3 * sizeof(float), "avatar render");
  if (!verts) return SPX_E_NOMEM;
  spx_status st = spx_avatar_pose(a, pose, trans, verts);
  if (!st) st = ensure_render(a, W, H);
  spx_project_args pa = {1, a->nv_in, verts, a->colors, 1, cam, SPX_LAYOUT_NCHW};
  if (!st) st = spx_project_to_tensor(ctx, a->proj, &pa, a->tin);
  if (!st) st = spx_unet_forward_tensor(a->u, a->tin, a->nchw);
  if (!st && input) {
    pa.layout = SPX_LAYOUT_HWC;
    st = spx_project(ctx, a->proj, &pa, input, NULL);
  }
  if (!st) {
    size_t hw = (size_t)W * H;
    for (size_t p = 0; p < hw; p++)
      for (int c = 0; c < 3; c++) rgb[p * 3 + (size_t)c] = a->nchw[(size_t)c * hw + p];
  }
  free(verts);
  return st;
}
