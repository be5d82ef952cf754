/* Projection with collision resolution (kernels/project.cl) against the plain-C z-buffer
 * reference, bit for bit: random clouds on every device path (fused sort, radix sort, z-buffer
 * parts, one launch), forced collisions, equal depths, pixel borders, points behind
 * the camera / outside / non-finite, batching, layouts, determinism, winners, the one-launch
 * path's image kept between calls; backward against its reference and finite differences;
 * argument errors. */
#include <float.h>
#include <stdlib.h>

#include "render/project_internal.h"
#include "smplpix/smplpix.h"
#include "test.h"

static spx_ctx *ctx;
static spx_projector *proj;

/* Camera at the origin looking down +z after rotating by small angles (a, b) about x and y. */
static spx_camera make_cam(int w, int h, double f, double a, double b, double tz) {
  spx_camera c;
  memset(&c, 0, sizeof c);
  c.width = w;
  c.height = h;
  c.K[0][0] = f;
  c.K[1][1] = f * 1.01;
  c.K[0][2] = w * 0.5 + 0.3;
  c.K[1][2] = h * 0.5 - 0.2;
  c.K[2][2] = 1;
  double ca = cos(a), sa = sin(a), cb = cos(b), sb = sin(b);
  double Rx[3][3] = {{1, 0, 0}, {0, ca, -sa}, {0, sa, ca}}, Ry[3][3] = {{cb, 0, sb}, {0, 1, 0}, {-sb, 0, cb}};
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      c.R[i][j] = 0;
      for (int k = 0; k < 3; k++) c.R[i][j] += Rx[i][k] * Ry[k][j];
    }
  c.t[0] = 0.01;
  c.t[1] = -0.02;
  c.t[2] = tz;
  return c;
}

/* n points in a box around the optical axis (some fall outside the image or behind). */
static void make_cloud(float *pos, float *col, int n, double spread, unsigned long long seed) {
  for (int i = 0; i < n; i++) {
    pos[i * 3 + 0] = (float)((spx_t_uniform(&seed) - 0.5) * spread);
    pos[i * 3 + 1] = (float)((spx_t_uniform(&seed) - 0.5) * spread);
    pos[i * 3 + 2] = (float)(spx_t_uniform(&seed) * 2.0 - 0.2);
    for (int k = 0; k < 3 && col; k++) col[i * 3 + k] = (float)spx_t_uniform(&seed);
  }
}

/* The device path `force` (SPX_PROJ_PATH_AUTO, or one path; SPX_PROJ_PATH_ONE into a foreign,
 * fully cleared image) on uploaded buffers. */
static void run_dev(const spx_project_args *a, spx_proj_path force, float *out, int32_t *win) {
  size_t npix = (size_t)a->batch * a->ncams * a->cams[0].width * a->cams[0].height;
  size_t vb = (size_t)a->batch * a->nverts * 3 * sizeof(float) + 4;
  cl_mem pos = NULL, col = NULL, img = NULL, w = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, vb, "pos", &pos));
  CHECK_OK(ctx, spx_cl_alloc(ctx, vb, "col", &col));
  CHECK_OK(ctx, spx_cl_alloc(ctx, npix * 16, "img", &img));
  CHECK_OK(ctx, spx_cl_alloc(ctx, npix * 4, "win", &w));
  CHECK_OK(ctx, spx_cl_write(ctx, pos, 0, vb - 4, a->pos));
  if (a->col) CHECK_OK(ctx, spx_cl_write(ctx, col, 0, vb - 4, a->col));
  spx_project_dev_args d = {a->batch, a->nverts, pos, a->col ? col : NULL, a->ncams, a->cams, a->layout};
  CHECK_OK(ctx, spx_project_device(ctx, proj, &d, img, w, force));
  if (force) CHECK(proj->last_path == force || a->nverts == 0);
  CHECK_OK(ctx, spx_cl_read(ctx, img, 0, npix * 16, out));
  CHECK_OK(ctx, spx_cl_read(ctx, w, 0, npix * 4, win));
  spx_cl_free(&pos);
  spx_cl_free(&col);
  spx_cl_free(&img);
  spx_cl_free(&w);
}

/* Device (public API and every forced path) == reference, bit for bit. Returns the reference. */
static void check_vs_ref(const spx_project_args *a, const char *what, float **ref_out, int32_t **ref_win) {
  size_t npix = (size_t)a->batch * a->ncams * a->cams[0].width * a->cams[0].height;
  float *ro = malloc(npix * 16), *o = malloc(npix * 16);
  int32_t *rw = malloc(npix * 4), *w = malloc(npix * 4);
  CHECK_OK(ctx, spx_project_ref(ctx, a, ro, rw));
  for (int force = SPX_PROJ_PATH_AUTO; force < SPX_PROJ_NPATHS; force++) {
    memset(o, 0, npix * 16);
    memset(w, 0, npix * 4);
    if (force == SPX_PROJ_PATH_AUTO) CHECK_OK(ctx, spx_project(ctx, proj, a, o, w));
    else run_dev(a, (spx_proj_path)force, o, w);
    CHECK_MSG(memcmp(o, ro, npix * 16) == 0, "%s: image differs from the reference (path %d)", what, force);
    CHECK_MSG(memcmp(w, rw, npix * 4) == 0, "%s: winners differ from the reference (path %d)", what, force);
  }
  free(o);
  free(w);
  if (ref_out) *ref_out = ro;
  else free(ro);
  if (ref_win) *ref_win = rw;
  else free(rw);
}

static void test_random_clouds(void) {
  static const int ns[] = {1, 100, 6890, 40000};
  for (size_t t = 0; t < sizeof ns / sizeof ns[0]; t++) {
    int n = ns[t];
    float *pos = malloc(sizeof(float) * 3 * n), *col = malloc(sizeof(float) * 3 * n);
    make_cloud(pos, col, n, 1.5, 100 + t);
    spx_camera cam = make_cam(41 + (int)t * 30, 31 + (int)t * 20, 60.0 + 20 * t, 0.1, -0.05, 0.5);
    spx_project_args a = {1, n, pos, col, 1, &cam, SPX_LAYOUT_HWC};
    int32_t *rw;
    char what[64];
    snprintf(what, sizeof what, "cloud n=%d", n);
    check_vs_ref(&a, what, NULL, &rw);
    size_t hit = 0, npix = (size_t)cam.width * cam.height;
    for (size_t i = 0; i < npix; i++) hit += rw[i] >= 0;
    CHECK(hit > 0 || n == 1); /* the test sees something */
    a.col = NULL; /* white */
    check_vs_ref(&a, "white", NULL, NULL);
    free(rw);
    free(pos);
    free(col);
  }
}

/* Many points on the same pixel at various depths, and exact duplicates (equal depths). */
static void test_collisions_and_ties(void) {
  int n = 3000;
  float *pos = malloc(sizeof(float) * 3 * n), *col = malloc(sizeof(float) * 3 * n);
  unsigned long long s = 7;
  spx_camera cam = make_cam(16, 12, 20.0, 0, 0, 0);
  cam.t[0] = cam.t[1] = 0;
  for (int i = 0; i < n; i++) {
    /* 10 rays (pixels), depths from a small set so equal depths happen often */
    int ray = i % 10;
    float z = 0.5f + 0.25f * (float)(spx_t_rng_next(&s) % 5);
    pos[i * 3 + 0] = z * (0.06f * ray - 0.3f);
    pos[i * 3 + 1] = z * 0.013f;
    pos[i * 3 + 2] = z;
    for (int k = 0; k < 3; k++) col[i * 3 + k] = (float)i;
  }
  spx_project_args a = {1, n, pos, col, 1, &cam, SPX_LAYOUT_HWC};
  float *ro;
  int32_t *rw;
  check_vs_ref(&a, "collisions", &ro, &rw);
  /* independent check: each winner is the smallest index among the nearest points of its pixel */
  int checked = 0;
  for (int p = 0; p < cam.width * cam.height; p++) {
    if (rw[p] < 0) continue;
    float best = ro[p * 4 + 3];
    int first = -1;
    for (int i = 0; i < n && first < 0; i++) {
      float o[4];
      int32_t w[16 * 12];
      spx_project_args one = {1, 1, pos + i * 3, NULL, 1, &cam, SPX_LAYOUT_HWC};
      (void)o;
      float img[16 * 12 * 4];
      CHECK_OK(ctx, spx_project_ref(ctx, &one, img, w));
      if (w[p] == 0 && img[p * 4 + 3] == best) first = i;
    }
    CHECK_MSG(rw[p] == first, "pixel %d: winner %d, expected %d", p, rw[p], first);
    CHECK(ro[p * 4] == (float)rw[p]);
    checked++;
  }
  CHECK(checked >= 5);
  free(ro);
  free(rw);
  free(pos);
  free(col);
}

/* u'/d exactly integral lands in that column; u == W is outside; d <= 0, NaN, Inf dropped. */
static void test_borders_and_drops(void) {
  spx_camera cam;
  memset(&cam, 0, sizeof cam);
  cam.width = 8;
  cam.height = 4;
  cam.K[0][0] = cam.K[1][1] = cam.K[2][2] = 1;
  cam.R[0][0] = cam.R[1][1] = cam.R[2][2] = 1;
  float inf = INFINITY, nan = NAN;
  float pos[][3] = {
      {6, 2, 2},                          /* u = 3, v = 1 exactly: column 3, row 1 */
      {nextafterf(6, 0), 2.5f, 2},        /* u just below 3: column 2, row 1 */
      {16, 2, 2},                         /* u = 8 = W: outside */
      {nextafterf(16, 0), 0, 2},          /* u just below W: column 7, row 0 */
      {0, 0, 1},                          /* u = v = 0: pixel 0 */
      {-1e-7f, 0, 1},                     /* u < 0: outside */
      {1, 1, 0},                          /* d == 0 */
      {1, 1, -1},                         /* d < 0 */
      {nan, 1, 1}, {1, inf, 1}, {1, 1, inf}, {-inf, 0, 1}, {1, 1, nan},
      {0, 8, 2},                          /* v = 4 = H: outside */
  };
  int n = (int)(sizeof pos / sizeof pos[0]);
  spx_project_args a = {1, n, &pos[0][0], NULL, 1, &cam, SPX_LAYOUT_HWC};
  float *ro;
  int32_t *rw;
  check_vs_ref(&a, "borders", &ro, &rw);
  int expect[32];
  for (int i = 0; i < 32; i++) expect[i] = -1;
  expect[1 * 8 + 3] = 0;
  expect[1 * 8 + 2] = 1;
  expect[0 * 8 + 7] = 3;
  expect[0] = 4;
  for (int i = 0; i < 32; i++) CHECK_MSG(rw[i] == expect[i], "pixel %d: winner %d, expected %d", i, rw[i], expect[i]);
  CHECK(ro[(1 * 8 + 3) * 4 + 3] == 2.0f && ro[1 * 4 + 3] == 1.0f && ro[5 * 4] == 1.0f);
  free(ro);
  free(rw);
}

/* one call with B=3 sets x C=4 cameras == 12 single calls; NCHW == transposed HWC; repeatable */
static void test_batched_layouts_determinism(void) {
  int B = 3, C = 4, n = 2000, W = 37, H = 29;
  float *pos = malloc(sizeof(float) * 3 * n * B), *col = malloc(sizeof(float) * 3 * n * B);
  make_cloud(pos, col, n * B, 1.2, 55);
  spx_camera cams[4];
  for (int c = 0; c < C; c++) cams[c] = make_cam(W, H, 30.0 + c, 0.05 * c, -0.03 * c, 0.4 + 0.1 * c);
  size_t hw = (size_t)W * H, img4 = hw * 4;
  float *o = malloc(sizeof(float) * img4 * B * C), *o2 = malloc(sizeof(float) * img4 * B * C),
        *one = malloc(sizeof(float) * img4);
  int32_t *w = malloc(sizeof(int32_t) * hw * B * C), *w2 = malloc(sizeof(int32_t) * hw * B * C),
          *w1 = malloc(sizeof(int32_t) * hw);
  spx_project_args a = {B, n, pos, col, C, cams, SPX_LAYOUT_HWC};
  check_vs_ref(&a, "batched", NULL, NULL);
  CHECK_OK(ctx, spx_project(ctx, proj, &a, o, w));
  for (int b = 0; b < B; b++)
    for (int c = 0; c < C; c++) {
      spx_project_args s1 = {1, n, pos + (size_t)b * n * 3, col + (size_t)b * n * 3, 1, &cams[c], SPX_LAYOUT_HWC};
      CHECK_OK(ctx, spx_project(ctx, proj, &s1, one, w1));
      size_t img = (size_t)b * C + c;
      CHECK_MSG(memcmp(one, o + img * img4, img4 * sizeof(float)) == 0, "image %zu differs from its single call", img);
      CHECK(memcmp(w1, w + img * hw, hw * sizeof(int32_t)) == 0);
    }
  a.layout = SPX_LAYOUT_NCHW;
  check_vs_ref(&a, "batched nchw", NULL, NULL);
  CHECK_OK(ctx, spx_project(ctx, proj, &a, o2, w2));
  size_t bad = 0;
  for (size_t img = 0; img < (size_t)B * C; img++)
    for (size_t p = 0; p < hw; p++)
      for (int k = 0; k < 4; k++) bad += o2[img * img4 + k * hw + p] != o[img * img4 + p * 4 + k];
  CHECK_MSG(bad == 0, "%zu NCHW values differ from HWC", bad);
  CHECK(memcmp(w, w2, sizeof(int32_t) * hw * B * C) == 0);
  for (int r = 0; r < 3; r++) {
    CHECK_OK(ctx, spx_project(ctx, proj, &a, o, w));
    CHECK(memcmp(o, o2, sizeof(float) * img4 * B * C) == 0 && memcmp(w, w2, sizeof(int32_t) * hw * B * C) == 0);
  }
  free(pos);
  free(col);
  free(o);
  free(o2);
  free(one);
  free(w);
  free(w2);
  free(w1);
}

/* loss = sum(G * image): backward == reference bit for bit, == finite differences */
static void test_backward(void) {
  int B = 2, C = 3, n = 500, W = 40, H = 30;
  float *pos = malloc(sizeof(float) * 3 * n * B), *col = malloc(sizeof(float) * 3 * n * B);
  make_cloud(pos, col, n * B, 1.0, 77);
  spx_camera cams[3];
  for (int c = 0; c < C; c++) cams[c] = make_cam(W, H, 30.0 + 3 * c, 0.1 * c, 0.07 * c, 0.5);
  size_t npix = (size_t)B * C * W * H, nv3 = (size_t)B * n * 3;
  float *o = malloc(sizeof(float) * npix * 4), *G = malloc(sizeof(float) * npix * 4);
  int32_t *w = malloc(sizeof(int32_t) * npix), *w2 = malloc(sizeof(int32_t) * npix);
  float *gc = malloc(sizeof(float) * nv3), *gp = malloc(sizeof(float) * nv3), *rc = malloc(sizeof(float) * nv3),
        *rp = malloc(sizeof(float) * nv3);
  unsigned long long s = 3;
  for (size_t i = 0; i < npix * 4; i++) G[i] = (float)(spx_t_uniform(&s) - 0.5);
  for (int layout = 0; layout < 2; layout++) {
    spx_project_args a = {B, n, pos, col, C, cams, (spx_layout)layout};
    CHECK_OK(ctx, spx_project(ctx, proj, &a, o, w));
    for (size_t i = 0; i < nv3; i++) gc[i] = rc[i] = gp[i] = rp[i] = (float)i * 0.001f; /* += semantics */
    CHECK_OK(ctx, spx_project_backward(ctx, proj, &a, w, G, gc, gp));
    spx_project_backward_ref(&a, w, G, rc, rp);
    CHECK(memcmp(gc, rc, sizeof(float) * nv3) == 0);
    CHECK(memcmp(gp, rp, sizeof(float) * nv3) == 0);
    CHECK_OK(ctx, spx_project_backward(ctx, proj, &a, w, G, NULL, gp)); /* either may be NULL */
  }
  /* finite differences on the HWC forward (double sums of the float images) */
  spx_project_args a = {B, n, pos, col, C, cams, SPX_LAYOUT_HWC};
  CHECK_OK(ctx, spx_project(ctx, proj, &a, o, w));
  memset(gc, 0, sizeof(float) * nv3);
  memset(gp, 0, sizeof(float) * nv3);
  CHECK_OK(ctx, spx_project_backward(ctx, proj, &a, w, G, gc, gp));
  int tested_pos = 0, tested_col = 0, nonzero = 0;
  for (int t = 0; t < 60; t++) {
    size_t v = (size_t)(spx_t_rng_next(&s) % (unsigned long long)(B * n)), j = (size_t)(spx_t_rng_next(&s) % 3);
    for (int which = 0; which < 2; which++) {
      float *x = which ? &pos[v * 3 + j] : &col[v * 3 + j];
      float x0 = *x, h = which ? 2e-4f : 0.25f;
      double L[2];
      int same = 1;
      for (int sgn = 0; sgn < 2; sgn++) {
        *x = x0 + (sgn ? h : -h);
        CHECK_OK(ctx, spx_project(ctx, proj, &a, o, w2));
        same &= memcmp(w, w2, sizeof(int32_t) * npix) == 0;
        L[sgn] = 0;
        for (size_t i = 0; i < npix * 4; i++) L[sgn] += (double)G[i] * o[i];
      }
      double hh = (double)(x0 + h) - (double)(x0 - h);
      *x = x0;
      if (!same) continue; /* the step moved a point across a pixel: no gradient to compare */
      double fd = (L[1] - L[0]) / hh, an = which ? gp[v * 3 + j] : gc[v * 3 + j];
      nonzero += an != 0;
      if (which) {
        CHECK_NEAR(an, fd, 2e-3, 2e-2);
        tested_pos++;
      } else {
        CHECK_NEAR(an, fd, 1e-5, 1e-5); /* colors enter linearly */
        tested_col++;
      }
    }
  }
  CHECK(tested_pos >= 30 && tested_col >= 50 && nonzero >= 10);
  /* bad winners are argument errors */
  w[0] = n;
  CHECK(spx_project_backward(ctx, proj, &a, w, G, gc, gp) == SPX_E_ARG);
  w[0] = 5;
  w[1] = 5;
  CHECK(spx_project_backward(ctx, proj, &a, w, G, gc, gp) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "wins two pixels") != NULL);
  free(pos);
  free(col);
  free(o);
  free(G);
  free(w);
  free(w2);
  free(gc);
  free(gp);
  free(rc);
  free(rp);
}

static void test_errors_and_empty(void) {
  spx_camera cams[2] = {make_cam(20, 10, 10, 0, 0, 1), make_cam(21, 10, 10, 0, 0, 1)};
  float pos[3] = {0, 0, 1}, out[21 * 10 * 4 * 2];
  int32_t win[21 * 10 * 2];
  spx_project_args a = {1, 1, pos, NULL, 2, cams, SPX_LAYOUT_HWC};
  CHECK(spx_project(ctx, proj, &a, out, win) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "camera 1") != NULL);
  CHECK(spx_project_ref(ctx, &a, out, win) == SPX_E_ARG);
  a.ncams = 1;
  cams[0].K[0][0] = 0;
  CHECK(spx_project(ctx, proj, &a, out, win) == SPX_E_CAMERA);
  cams[0].K[0][0] = 10;
  cams[0].R[1][1] = NAN;
  CHECK(spx_project(ctx, proj, &a, out, win) == SPX_E_NUMERIC);
  cams[0].R[1][1] = 1;
  cams[0].t[2] = 1e300; /* finite in double, not in float */
  CHECK(spx_project(ctx, proj, &a, out, win) == SPX_E_NUMERIC);
  cams[0].t[2] = 1;
  cams[0].R[1][1] = 2;
  CHECK(spx_project(ctx, proj, &a, out, win) == SPX_E_CAMERA);
  CHECK(strstr(spx_ctx_message(ctx), "orthonormal") != NULL);
  cams[0] = make_cam(20, 10, 10, 0, 0, 1);
  cams[0].width = 0;
  CHECK(spx_project(ctx, proj, &a, out, win) == SPX_E_CAMERA);
  cams[0].width = 20;
  a.batch = 0;
  CHECK(spx_project(ctx, proj, &a, out, win) == SPX_E_ARG);
  a.batch = 1;
  a.layout = (spx_layout)7;
  CHECK(spx_project(ctx, proj, &a, out, win) == SPX_E_ARG);
  /* N = 0 is valid: all background */
  a.layout = SPX_LAYOUT_NCHW;
  a.nverts = 0;
  a.pos = NULL;
  a.batch = 2;
  memset(out, 0, sizeof out);
  CHECK_OK(ctx, spx_project(ctx, proj, &a, out, win));
  int ok = 1;
  for (int i = 0; i < 20 * 10 * 4 * 2; i++) ok &= out[i] == 1.0f;
  for (int i = 0; i < 20 * 10 * 2; i++) ok &= win[i] == -1;
  CHECK(ok);
}

/* a larger cloud (general path with the multi-work-group sort) and the integer-division path
 * (kernels/exact.h) that devices without correctly rounded division take */
static void test_large_and_fallback_division(void) {
  int n = 120000;
  float *pos = malloc(sizeof(float) * 3 * n), *col = malloc(sizeof(float) * 3 * n);
  make_cloud(pos, col, n, 1.0, 9);
  spx_camera cam = make_cam(410, 308, 300.0, 0.02, 0.01, 0.6);
  spx_project_args a = {1, n, pos, col, 1, &cam, SPX_LAYOUT_HWC};
  check_vs_ref(&a, "large", NULL, NULL);
  spx_ctx *main_ctx = ctx;
  spx_projector *main_proj = proj;
  spx_ctx *c2 = NULL;
  CHECK(spx_ctx_create(&c2) == SPX_OK);
  spx_ctx_set_profile(c2, SPX_DEBUG_DIV_FALLBACK);
  CHECK_OK(c2, spx_device_open(c2, NULL));
  if (c2 && c2->dev) {
    ctx = c2;
    CHECK(!c2->dev->cr_div);
    CHECK_OK(c2, spx_projector_create(c2, &proj));
    a.nverts = 20000;
    check_vs_ref(&a, "integer division", NULL, NULL);
    spx_projector_destroy(proj);
  }
  spx_ctx_destroy(c2);
  ctx = main_ctx;
  proj = main_proj;
  free(pos);
  free(col);
}

/* The one-launch path keeps the projector's image between calls and clears only what its last call wrote:
 * a long sequence of spx_project calls on one projector — moving point sets, winners asked for or
 * not, layouts, sizes and batches changing, the multi-launch path, a backward (which writes the
 * winners buffer) and a device-tensor call in between — each equal to the reference. */
static void test_one_launch_sequence(void) {
  int nmax = 140000; /* step 13: above the CPU default SPX_PROJ_ONE_MAX (the parts + merge path) */
  float *pos = malloc(sizeof(float) * 3 * nmax), *col = malloc(sizeof(float) * 3 * nmax);
  spx_camera cams[2] = {make_cam(61, 47, 50.0, 0.05, -0.02, 0.5), make_cam(61, 47, 45.0, -0.03, 0.04, 0.45)};
  spx_camera big = make_cam(70, 50, 50.0, 0.05, -0.02, 0.5);
  size_t npmax = (size_t)2 * 2 * 70 * 50;
  float *o = malloc(npmax * 16), *ro = malloc(npmax * 16), *G = calloc(npmax * 4, sizeof(float));
  float *gc = calloc((size_t)nmax * 3, sizeof(float));
  int32_t *w = malloc(npmax * 4), *rw = malloc(npmax * 4);
  int saw_one = 0, saw_zbuf = 0;
  for (int step = 0; step < 24; step++) {
    /* six phases of four calls with one geometry each; within a phase winners are asked for in
     * calls 0, 1 and 3 (so both the kept and the stale winners buffer are exercised) */
    int ph = step / 4, B = ph == 2 || ph == 4 ? 2 : 1, C = ph == 2 ? 2 : 1, want_w = step % 4 != 2;
    int n = step == 13 ? nmax : step == 21 ? 0 : 200 + 300 * (step % 4);
    make_cloud(pos, col, n * B, 1.0 + 0.1 * (step % 3), 1000 + (unsigned long long)step);
    spx_project_args a = {B, n, n ? pos : NULL, step % 7 == 6 ? NULL : col, C, ph == 3 ? &big : cams,
                          ph == 1 || ph == 4 ? SPX_LAYOUT_NCHW : SPX_LAYOUT_HWC};
    size_t np = (size_t)B * C * a.cams[0].width * a.cams[0].height;
    memset(o, 0, np * 16);
    memset(w, 0, np * 4);
    CHECK_OK(ctx, spx_project(ctx, proj, &a, o, want_w ? w : NULL));
    saw_one += proj->last_path == SPX_PROJ_PATH_ONE;
    saw_zbuf += proj->last_path == SPX_PROJ_PATH_ZBUF;
    CHECK_OK(ctx, spx_project_ref(ctx, &a, ro, rw));
    CHECK_MSG(memcmp(o, ro, np * 16) == 0, "step %d (n=%d, B=%d, C=%d): image differs", step, n, B, C);
    CHECK_MSG(!want_w || memcmp(w, rw, np * 4) == 0, "step %d: winners differ", step);
    if (step == 17) CHECK_OK(ctx, spx_project_backward(ctx, proj, &a, rw, G, gc, NULL));
    if (step == 18) {
      spx_device_tensor *t = NULL;
      spx_project_args nchw = a;
      nchw.layout = SPX_LAYOUT_NCHW;
      CHECK_OK(ctx, spx_device_tensor_create(ctx, B * C, 4, a.cams[0].height, a.cams[0].width, &t));
      CHECK_OK(ctx, spx_project_to_tensor(ctx, proj, &nchw, t));
      spx_device_tensor_free(t);
    }
  }
  if (ctx->dev->tune.proj_zbuf && ctx->dev->tune.proj_one_max >= 2200) CHECK(saw_one >= 20);
  if (ctx->dev->tune.proj_zbuf && ctx->dev->tune.proj_one_max < nmax) CHECK(saw_zbuf >= 1);
  free(pos);
  free(col);
  free(o);
  free(ro);
  free(G);
  free(gc);
  free(w);
  free(rw);
}

int main(void) {
  if (spx_t_open_device(&ctx) || spx_t_no_device(ctx, spx_projector_create(ctx, &proj))) return 1;
  SPX_RUN(test_random_clouds);
  SPX_RUN(test_collisions_and_ties);
  SPX_RUN(test_borders_and_drops);
  SPX_RUN(test_batched_layouts_determinism);
  SPX_RUN(test_backward);
  SPX_RUN(test_one_launch_sequence);
  SPX_RUN(test_errors_and_empty);
  SPX_RUN(test_large_and_fallback_division);
  spx_projector_destroy(proj);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
