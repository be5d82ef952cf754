/* The person's own data set of `smplpix avatar` (apps/avatar_app.h): poses, cameras, targets,
 * inputs. Everything is a function of the scan, the registration, the motion and the seed, so a
 * resumed run rebuilds the same images bit for bit. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "avatar_app.h"

#define PI 3.14159265358979323846

void av_set_free(av_set *s) {
  free(s->v), free(s->poses), free(s->in), free(s->tg), free(s->mask);
  memset(s, 0, sizeof *s);
}

static int set_alloc(const char *cmd, av_set *s, const char *name, int n, int nj, int W, int H) {
  memset(s, 0, sizeof *s);
  s->name = name, s->n = n, s->W = W, s->H = H;
  size_t hw = (size_t)W * H;
  s->v = calloc((size_t)n, sizeof *s->v);
  s->poses = calloc((size_t)n * nj * 3, sizeof(double));
  s->in = malloc((size_t)n * SPX_UNET_IN_CHANNELS * hw * sizeof(float));
  s->tg = malloc((size_t)n * SPX_UNET_OUT_CHANNELS * hw * sizeof(float));
  s->mask = malloc((size_t)n * hw);
  if (!s->v || !s->poses || !s->in || !s->tg || !s->mask) {
    av_set_free(s);
    return spx_cli_errorf(cmd, "out of memory for %d images of %dx%d", n, W, H);
  }
  for (int i = 0; i < n; i++) s->v[i].pose = s->poses + (size_t)i * nj * 3;
  return SPX_EXIT_OK;
}

/* Frames [a, b) of the clip spread over n views (jittered within their share when rng). */
static int32_t pick_frame(spx_synth_rng *rng, int i, int n, int32_t a, int32_t b) {
  double u = rng ? spx_synth_rng_uniform(rng, 0, 1) : 0.5;
  int32_t f = a + (int32_t)floor((i + u) * (double)(b - a) / n);
  return f < a ? a : f >= b ? b - 1 : f;
}

/* One view's pose and its camera at azimuth az, elevation el, framed on the posed scan as synth
 * frames its photos (spx_camera_frame: the projected box fills `fill` of the image height, from
 * `dist_scale` x SPX_FRAME_DISTANCE x the box's largest side); posed: scratch of the scan's size. */
static int make_view(const char *cmd, spx_ctx *ctx, spx_avatar *a, const av_subject *sub, const spx_anim_motion *mo,
                     int32_t frame, double az, double el, double dist_scale, double fill, const av_plan *p, av_view *v,
                     float *posed) {
  const spx_body_model *m = spx_avatar_body(a);
  v->frame = frame;
  if (spx_anim_motion_pose(ctx, mo, m, frame, v->pose, v->trans))
    return spx_cli_errorf(cmd, "%s: frame %d: %s", mo->path, frame, spx_ctx_message(ctx));
  if (spx_avatar_pose_scan(ctx, m, spx_avatar_registration(a), &sub->bind, v->pose, v->trans, posed))
    return spx_cli_error(cmd, ctx);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int32_t k = 0; k < sub->bind.nv; k++)
    for (int c = 0; c < 3; c++) lo[c] = fmin(lo[c], posed[k * 3 + c]), hi[c] = fmax(hi[c], posed[k * 3 + c]);
  double extent = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
  if (spx_camera_frame(ctx, sub->bind.nv, posed, p->W, p->H, az, el, extent * SPX_FRAME_DISTANCE * dist_scale, fill,
                       &v->cam))
    return spx_cli_errorf(cmd, "%s view of frame %d: %s", "framing the", frame, spx_ctx_message(ctx));
  return SPX_EXIT_OK;
}

/* The target (the scan, posed in `posed`, photographed) and the input (the avatar's vertices
 * projected) of view i of s; verts: scratch of the avatar's vertex count. */
static int render_view(const char *cmd, spx_ctx *ctx, spx_rasterizer *rast, spx_projector *proj, spx_avatar *a,
                       const av_subject *sub, av_set *s, int i, const float *posed, float *verts, float *rgb) {
  const av_view *v = &s->v[i];
  const spx_mesh *sc = sub->scan;
  size_t hw = (size_t)s->W * s->H;
  spx_synth_surface sf = {sc->nv, posed, sub->tex ? NULL : sc->col, sc->nf, sc->faces, 0, NULL, NULL, 0, 0, 0, NULL};
  if (sub->tex) {
    sf.nuv = sc->nuv, sf.uv = sc->uv, sf.face_uv = sc->face_uv;
    sf.tex_width = sub->tex->width, sf.tex_height = sub->tex->height, sf.tex_channels = sub->tex->channels;
    sf.tex = sub->tex->data;
  }
  spx_project_args pa = {1, 0, verts, spx_avatar_colors(a), 1, &v->cam, SPX_LAYOUT_NCHW};
  spx_avatar_info info;
  spx_avatar_get_info(a, &info);
  pa.nverts = info.vertices;
  if (spx_synth_photo_surface(ctx, rast, &sf, &v->cam, &sub->light, 1, rgb, s->mask + (size_t)i * hw) ||
      spx_avatar_pose(a, v->pose, v->trans, verts) ||
      spx_project(ctx, proj, &pa, s->in + (size_t)i * SPX_UNET_IN_CHANNELS * hw, NULL))
    return spx_cli_errorf(cmd, "%s view %d: %s", s->name, i, spx_ctx_message(ctx));
  float *tg = s->tg + (size_t)i * SPX_UNET_OUT_CHANNELS * hw;
  for (size_t q = 0; q < hw; q++)
    for (int c = 0; c < 3; c++) tg[(size_t)c * hw + q] = rgb[q * 3 + (size_t)c];
  return SPX_EXIT_OK;
}

/* Scratch and device state of the views' rendering. */
typedef struct av_scratch {
  float *posed, *verts, *rgb;
  spx_rasterizer *rast;
  spx_projector *proj;
} av_scratch;

/* The views of one split: n frames of [f0, f1), azimuths az0 + 2 pi (i + shift + jitter) / n;
 * each view's target and input. */
static int make_split(const char *cmd, spx_ctx *ctx, spx_avatar *a, const av_subject *sub, const spx_anim_motion *mo,
                      const av_plan *p, spx_synth_rng *rng, int32_t f0, int32_t f1, double shift, av_set *s,
                      av_scratch *w) {
  double az0 = spx_synth_rng_uniform(rng, 0, 2 * PI);
  for (int i = 0; i < s->n; i++) {
    int32_t frame = pick_frame(rng, i, s->n, f0, f1);
    double az = az0 + 2 * PI * (i + shift + spx_synth_rng_uniform(rng, -0.25, 0.25)) / s->n;
    double el = spx_synth_rng_uniform(rng, -10, 35) * PI / 180;
    double dist = spx_synth_rng_uniform(rng, 0.8, 1.3), fill = spx_synth_rng_uniform(rng, SPX_FRAME_FILL_MIN, SPX_FRAME_FILL_MAX);
    int rc = make_view(cmd, ctx, a, sub, mo, frame, az, el, dist, fill, p, &s->v[i], w->posed);
    if (!rc) rc = render_view(cmd, ctx, w->rast, w->proj, a, sub, s, i, w->posed, w->verts, w->rgb);
    if (rc) return rc;
  }
  return SPX_EXIT_OK;
}

int av_make_sets(const char *cmd, spx_ctx *ctx, spx_avatar *a, const av_subject *sub, const spx_anim_motion *mo,
                 const av_plan *p, av_set *train, av_set *val, av_set *held) {
  int nj = spx_avatar_body(a)->nj, rc;
  spx_avatar_info info;
  spx_avatar_get_info(a, &info);
  if ((rc = set_alloc(cmd, train, "train", p->ntrain, nj, p->W, p->H)) ||
      (rc = set_alloc(cmd, val, "validation", p->nval, nj, p->W, p->H)) ||
      (rc = set_alloc(cmd, held, "held-out", p->nheld, nj, p->W, p->H)))
    return rc;
  av_scratch w = {malloc((size_t)sub->bind.nv * 3 * sizeof(float)), malloc((size_t)info.vertices * 3 * sizeof(float)),
                  malloc((size_t)p->W * p->H * 3 * sizeof(float)), NULL, NULL};
  if (!w.posed || !w.verts || !w.rgb) rc = spx_cli_errorf(cmd, "out of memory");
  else if (spx_rasterizer_create(ctx, &w.rast) || spx_projector_create(ctx, &w.proj)) rc = spx_cli_error(cmd, ctx);
  /* training poses from the first 3/4 of the clip, validation and held-out ones from its last fifth */
  int32_t F = mo->nframes, train_end = F * 3 / 4, eval_start = (F * 4 + 4) / 5;
  spx_synth_rng rt = {spx_cli_mix64(p->seed * 2 + 1)}, re = {spx_cli_mix64(p->seed * 2 + 2)};
  if (!rc) rc = make_split(cmd, ctx, a, sub, mo, p, &rt, 0, train_end, 0, train, &w);
  if (!rc) rc = make_split(cmd, ctx, a, sub, mo, p, &re, eval_start, F, 0.5, held, &w);
  if (!rc) rc = make_split(cmd, ctx, a, sub, mo, p, &re, eval_start, F, 0.25, val, &w);
  spx_rasterizer_destroy(w.rast);
  spx_projector_destroy(w.proj);
  free(w.posed), free(w.verts), free(w.rgb);
  return rc;
}
