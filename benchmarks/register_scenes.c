/* Bodies and depth frames for bench_register_views (register_scenes.h). */
#include "register_scenes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../tests/fit_view.h"

void rs_body_free(rs_body *b) {
  free(b->V), free(b->F);
  memset(b, 0, sizeof *b);
}

static int body_alloc(spx_ctx *ctx, rs_body *b, const char *name, int32_t nv, int32_t nf) {
  memset(b, 0, sizeof *b);
  snprintf(b->name, sizeof b->name, "%s", name);
  b->nv = nv, b->nf = nf;
  b->V = malloc((size_t)nv * 3 * sizeof(double));
  b->F = malloc((size_t)nf * 3 * sizeof(int32_t));
  if (b->V && b->F) return 0;
  rs_body_free(b);
  spx_fail(ctx, SPX_E_NOMEM, "register scenes: out of memory");
  return -1;
}

static void bbox(const rs_body *b, double lo[3], double hi[3]) {
  for (int d = 0; d < 3; d++) lo[d] = INFINITY, hi[d] = -INFINITY;
  for (int32_t i = 0; i < b->nv; i++)
    for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], b->V[i * 3 + d]), hi[d] = fmax(hi[d], b->V[i * 3 + d]);
}

/* Stretches x and z about the bounding box's centre. */
static void widen(rs_body *b, double sx, double sz) {
  double lo[3], hi[3];
  bbox(b, lo, hi);
  for (int32_t i = 0; i < b->nv; i++) {
    b->V[i * 3] = 0.5 * (lo[0] + hi[0]) + sx * (b->V[i * 3] - 0.5 * (lo[0] + hi[0]));
    b->V[i * 3 + 2] = 0.5 * (lo[2] + hi[2]) + sz * (b->V[i * 3 + 2] - 0.5 * (lo[2] + hi[2]));
  }
}

/* n smooth bulges along the vertex normals: amplitude amp0..amp1 metres, Gaussian of sigma 8-12 cm,
 * centred on random vertices of the trunk (within 18 cm of the vertical axis, between 40% and 75%
 * of the height). */
static int bulge(spx_ctx *ctx, rs_body *b, int n, double amp0, double amp1, uint64_t seed) {
  double *N = malloc((size_t)b->nv * 3 * sizeof(double)), *disp = calloc((size_t)b->nv, sizeof(double));
  if (!N || !disp) {
    free(N), free(disp);
    spx_fail(ctx, SPX_E_NOMEM, "register scenes: out of memory");
    return -1;
  }
  spx_vertex_normals_d(b->V, b->nv, b->F, b->nf, N);
  double lo[3], hi[3];
  bbox(b, lo, hi);
  double cx = 0.5 * (lo[0] + hi[0]), cz = 0.5 * (lo[2] + hi[2]), h = hi[1] - lo[1];
  uint64_t s = seed * 0x9E3779B97F4A7C15ULL + 17;
  for (int k = 0; k < n; k++) {
    const double *c = NULL;
    for (int tries = 0; tries < 100000 && !c; tries++) {
      const double *p = b->V + (synth_next(&s) % (uint64_t)b->nv) * 3;
      double r = hypot(p[0] - cx, p[2] - cz), y = (p[1] - lo[1]) / h;
      if (r < 0.18 && y > 0.40 && y < 0.75) c = p;
    }
    if (!c) continue;
    double amp = amp0 + (amp1 - amp0) * synth_uni(&s), sig = 0.08 + 0.04 * synth_uni(&s);
    for (int32_t i = 0; i < b->nv; i++) {
      const double *p = b->V + i * 3;
      double d2 = (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) + (p[2] - c[2]) * (p[2] - c[2]);
      disp[i] += amp * exp(-0.5 * d2 / (sig * sig));
    }
  }
  for (int32_t i = 0; i < b->nv; i++)
    for (int d = 0; d < 3; d++) b->V[i * 3 + d] += disp[i] * N[i * 3 + d];
  free(N), free(disp);
  return 0;
}

static int from_mesh(spx_ctx *ctx, const spx_mesh *w, const char *name, rs_body *b) {
  if (body_alloc(ctx, b, name, w->nv, w->nf)) return -1;
  for (int32_t i = 0; i < w->nv * 3; i++) b->V[i] = w->pos[i];
  memcpy(b->F, w->faces, (size_t)w->nf * 3 * sizeof(int32_t));
  return 0;
}

/* The shipped body with these betas and synth_body's pose of `seed`. */
static int model_body(spx_ctx *ctx, const spx_body_model *m, const char *name, const double *betas, uint64_t seed,
                      rs_body *b) {
  double *pose = calloc((size_t)m->nj * 3, sizeof(double)), *bt = calloc((size_t)m->nbetas, sizeof(double));
  double trans[3] = {0, 0, 0};
  int rc = -1;
  if (pose && bt && !body_alloc(ctx, b, name, m->nv, m->nf)) {
    synth_body(m, seed, 0.3, pose, bt, trans);
    if (betas) memcpy(bt, betas, (size_t)m->nbetas * sizeof(double));
    spx_body_params p = {m->nbetas, bt, pose, trans, NULL};
    memcpy(b->F, m->faces, (size_t)m->nf * 3 * sizeof(int32_t));
    rc = spx_body_forward_ref(ctx, m, &p, b->V, NULL) ? -1 : 0;
    if (rc) rs_body_free(b);
  } else if (!pose || !bt) {
    spx_fail(ctx, SPX_E_NOMEM, "register scenes: out of memory");
  }
  free(pose), free(bt);
  return rc;
}

/* A `smplpix synth` subject of seed `seed`, posed by synth_body's pose of pose_seed. */
static int clothed(spx_ctx *ctx, const spx_body_model *m, const spx_image *parts, const char *name, uint64_t seed,
                   uint64_t pose_seed, rs_body *b) {
  spx_synth_subject s;
  if (spx_synth_subject_create(ctx, m, parts, seed, SPX_SYNTH_TEX_MIN, &s)) return -1;
  double *pose = calloc((size_t)m->nj * 3, sizeof(double)), *bt = calloc((size_t)m->nbetas, sizeof(double));
  float *Vf = malloc((size_t)s.nv * 3 * sizeof(float));
  double trans[3];
  int rc = -1;
  if (pose && bt && Vf && !body_alloc(ctx, b, name, s.nv, s.nf)) {
    synth_body(m, pose_seed, 0.3, pose, bt, trans);
    memset(trans, 0, sizeof trans);
    if (!spx_synth_pose(ctx, m, &s, pose, trans, Vf)) {
      for (int32_t i = 0; i < s.nv * 3; i++) b->V[i] = Vf[i];
      memcpy(b->F, s.faces, (size_t)s.nf * 3 * sizeof(int32_t));
      rc = 0;
    } else {
      rs_body_free(b);
    }
  } else if (!pose || !bt || !Vf) {
    spx_fail(ctx, SPX_E_NOMEM, "register scenes: out of memory");
  }
  free(pose), free(bt), free(Vf);
  spx_synth_subject_free(&s);
  return rc;
}

int rs_body_outside(spx_ctx *ctx, const spx_body_model *m, const spx_mesh *woman, const spx_image *parts, int k,
                    rs_body *out) {
  memset(out, 0, sizeof *out);
  switch (k) {
  case 0: return from_mesh(ctx, woman, "woman", out);
  case 1:
    if (from_mesh(ctx, woman, "woman-large", out)) return -1;
    widen(out, 1.12, 1.18);
    return bulge(ctx, out, 4, 0.015, 0.03, 5);
  case 2: return clothed(ctx, m, parts, "clothed-a", 1001, 61, out);
  case 3: return clothed(ctx, m, parts, "clothed-b", 1002, 62, out);
  case 4: {
    double *bt = calloc((size_t)m->nbetas, sizeof(double));
    if (!bt) return spx_fail(ctx, SPX_E_NOMEM, "register scenes: out of memory"), -1;
    /* beta 0 is the shipped model's overall size: +0.5 (1.81 m); every other one at +-4 */
    for (int32_t i = 0; i < m->nbetas; i++) bt[i] = i == 0 ? 0.5 : i % 2 ? 4.0 : -4.0;
    int rc = model_body(ctx, m, "betas-x2", bt, 63, out);
    free(bt);
    return rc;
  }
  case 5:
    if (model_body(ctx, m, "displaced", NULL, 64, out)) return -1;
    widen(out, 1.1, 1.0);
    return bulge(ctx, out, 6, 0.02, 0.04, 6);
  default: spx_fail(ctx, SPX_E_ARG, "register scenes: no outside body %d", k); return -1;
  }
}

int rs_body_inside(spx_ctx *ctx, const spx_body_model *m, int b, rs_body *out) {
  if (b > 0) return model_body(ctx, m, "inside", NULL, 40 + (uint64_t)b, out);
  double *bt = calloc((size_t)m->nbetas, sizeof(double)), *pose = calloc((size_t)m->nj * 3, sizeof(double));
  int rc = -1;
  if (bt && pose && !body_alloc(ctx, out, "rest", m->nv, m->nf)) {
    spx_body_params p = {m->nbetas, bt, pose, NULL, NULL};
    memcpy(out->F, m->faces, (size_t)m->nf * 3 * sizeof(int32_t));
    rc = spx_body_forward_ref(ctx, m, &p, out->V, NULL) ? -1 : 0;
    if (rc) rs_body_free(out);
  }
  free(bt), free(pose);
  return rc;
}

int rs_camera(spx_ctx *ctx, const rs_body *b, double az, double up, double dist, int32_t W, int32_t H,
              spx_camera *cam) {
  double lo[3], hi[3], c[3], eye[3], upv[3] = {0, 1, 0};
  bbox(b, lo, hi);
  for (int d = 0; d < 3; d++) c[d] = 0.5 * (lo[d] + hi[d]);
  eye[0] = c[0] + dist * sin(az), eye[1] = c[1] + up, eye[2] = c[2] + dist * cos(az);
  double f = 525.0 * W / 640.0;
  if (spx_camera_look_at(ctx, W, H, f, eye, c, upv, cam)) return -1;
  cam->K[0][2] = 319.5 * W / 640.0, cam->K[1][2] = 239.5 * H / 480.0;
  return 0;
}

int rs_depth_frame(spx_ctx *ctx, const rs_body *b, const spx_camera *cam, int room, uint64_t seed, float *depth) {
  return view_room_depth(ctx, b->V, b->nv, b->F, b->nf, cam, room, 0.001, seed, depth);
}
