/* Mesh rasterizer: device (kernels/raster.cl) vs plain-C reference — pixel-exact coverage and
 * face ids, colors/depth within 1e-5 — plus properties checked independently of both:
 * watertight shared edges (quad, fan, a quad crossing the near plane), degenerate and
 * back-facing triangles, clipping depth against ray casting, texture wrap/clamp against a
 * linear texture, AA 2x = box-filtered 2x render, several cameras, argument errors. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"
#include "smplpix/smplpix.h"
#include "test.h"

static spx_ctx *ctx;
static spx_rasterizer *R;

static spx_camera cam_simple(int w, int h, double f, double cx, double cy) {
  spx_camera c;
  memset(&c, 0, sizeof c);
  c.width = w, c.height = h;
  c.K[0][0] = f, c.K[1][1] = f, c.K[0][2] = cx, c.K[1][2] = cy, c.K[2][2] = 1;
  c.R[0][0] = c.R[1][1] = c.R[2][2] = 1;
  return c;
}

/* a camera looking at the origin from distance dist, rotated about y by ang */
static spx_camera cam_orbit(int w, int h, double f, double ang, double dist) {
  spx_camera c = cam_simple(w, h, f, w * 0.5 + 0.13, h * 0.5 - 0.27);
  double cs = cos(ang), sn = sin(ang);
  c.R[0][0] = cs, c.R[0][2] = -sn, c.R[1][1] = 1, c.R[2][0] = sn, c.R[2][2] = cs;
  c.R[1][0] = c.R[1][2] = c.R[0][1] = c.R[2][1] = 0;
  c.t[0] = 0, c.t[1] = 0, c.t[2] = dist;
  return c;
}

static spx_raster_args base_args(int nv, const float *pos, const float *col, int nf, const int32_t *faces,
                                 const spx_camera *cam) {
  spx_raster_args a;
  memset(&a, 0, sizeof a);
  a.nverts = nv, a.pos = pos, a.col = col, a.nfaces = nf, a.faces = faces;
  a.ncams = 1, a.cams = cam, a.aa = 1, a.layout = SPX_LAYOUT_HWC;
  return a;
}

/* Render with both; compare face ids exactly and values within 1e-5. Returns ids from the ref
 * (caller frees) when ids_out is given. */
static void compare(const spx_raster_args *a, const char *what, float **img_out, int32_t **ids_out) {
  size_t W = (size_t)a->cams[0].width, H = (size_t)a->cams[0].height, n = W * H * 4 * a->ncams;
  float *o1 = malloc(n * 4), *o2 = malloc(n * 4);
  int with_ids = a->aa == 1;
  int32_t *i1 = with_ids ? malloc(n) : NULL, *i2 = with_ids ? malloc(n) : NULL;
  CHECK_OK(ctx, spx_raster_ref(ctx, a, o1, i1));
  CHECK_OK(ctx, spx_raster(ctx, R, a, o2, i2));
  size_t bad_id = 0, bad_val = 0, covered = 0;
  double worst = 0;
  if (with_ids)
    for (size_t i = 0; i < n / 4; i++) {
      bad_id += i1[i] != i2[i];
      covered += i1[i] >= 0;
    }
  for (size_t i = 0; i < n; i++) {
    double d = fabs((double)o1[i] - o2[i]);
    if (!(d <= 1e-5 * (1 + fabs(o1[i])))) bad_val++;
    if (d > worst) worst = d;
  }
  CHECK_MSG(bad_id == 0, "%s: %zu of %zu pixels have a different face", what, bad_id, n / 4);
  CHECK_MSG(bad_val == 0, "%s: %zu values differ (worst %g)", what, bad_val, worst);
  if (with_ids) CHECK_MSG(covered > 0 || a->nfaces == 0, "%s: nothing drawn", what);
  if (img_out) *img_out = o1;
  else free(o1);
  if (ids_out) *ids_out = i1;
  else free(i1);
  free(o2);
  free(i2);
}

static void test_random_meshes(void) {
  unsigned long long s = 12345;
  for (int trial = 0; trial < 6; trial++) {
    int nv = 300 + trial * 200, nf = 400 + trial * 300;
    float *pos = malloc(sizeof(float) * nv * 3), *col = malloc(sizeof(float) * nv * 3);
    int32_t *faces = malloc(sizeof(int32_t) * nf * 3);
    double spread = trial == 5 ? 3.0 : 1.0; /* last trial: many triangles cross the near plane */
    for (int i = 0; i < nv * 3; i++) {
      pos[i] = (float)((spx_t_uniform(&s) * 2 - 1) * spread);
      col[i] = (float)spx_t_uniform(&s);
    }
    for (int f = 0; f < nf; f++) {
      int base = (int)(spx_t_uniform(&s) * nv);
      for (int k = 0; k < 3; k++) {
        /* mostly small triangles (nearby indices), some large */
        int off = trial % 2 ? (int)(spx_t_uniform(&s) * nv) : (int)(spx_t_uniform(&s) * 8);
        faces[f * 3 + k] = (base + off) % nv;
      }
    }
    /* make small triangles actually small: pull each face's 2nd/3rd vertex towards the 1st */
    spx_camera cam = cam_orbit(97 + trial * 13, 71 + trial * 7, 60 + trial * 10, 0.3 * trial, trial == 5 ? 2.0 : 3.5);
    spx_raster_args a = base_args(nv, pos, col, nf, faces, &cam);
    a.cull = (spx_cull)(trial % 3);
    a.layout = trial % 2 ? SPX_LAYOUT_NCHW : SPX_LAYOUT_HWC;
    char what[64];
    snprintf(what, sizeof what, "random mesh %d", trial);
    compare(&a, what, NULL, NULL);
    free(pos);
    free(col);
    free(faces);
  }
}

/* UV sphere: (rings+1)*(segs) vertices, poles duplicated per segment for simplicity */
static void make_sphere(int rings, int segs, float r, float **pos, float **col, int32_t **faces, int *nv, int *nf) {
  *nv = (rings + 1) * segs;
  *nf = rings * segs * 2;
  *pos = malloc(sizeof(float) * 3 * *nv);
  *col = malloc(sizeof(float) * 3 * *nv);
  *faces = malloc(sizeof(int32_t) * 3 * *nf);
  for (int i = 0; i <= rings; i++)
    for (int j = 0; j < segs; j++) {
      double th = M_PI * i / rings, ph = 2 * M_PI * j / segs;
      float *p = *pos + 3 * (i * segs + j), *c = *col + 3 * (i * segs + j);
      p[0] = (float)(r * sin(th) * cos(ph)), p[1] = (float)(r * cos(th)), p[2] = (float)(r * sin(th) * sin(ph));
      c[0] = (float)(0.5 + 0.5 * sin(th)), c[1] = (float)(0.5 + 0.5 * cos(ph)), c[2] = (float)i / rings;
    }
  int32_t *f = *faces;
  for (int i = 0; i < rings; i++)
    for (int j = 0; j < segs; j++) {
      int a = i * segs + j, b = i * segs + (j + 1) % segs, c = a + segs, d = b + segs;
      *f++ = a, *f++ = b, *f++ = c; /* counter-clockwise seen from outside: normals point out */
      *f++ = b, *f++ = d, *f++ = c;
    }
}

static void test_sphere(void) {
  float *pos, *col;
  int32_t *faces;
  int nv, nf;
  make_sphere(40, 64, 1.0f, &pos, &col, &faces, &nv, &nf);
  spx_camera cam = cam_orbit(205, 154, 150, 0.4, 3.0);
  spx_raster_args a = base_args(nv, pos, col, nf, faces, &cam);
  float *img;
  int32_t *ids;
  compare(&a, "sphere", &img, &ids);
  /* a closed sphere: the silhouette is a disc; no holes inside it (watertight in a mesh) */
  int W = cam.width, H = cam.height, holes = 0, drawn = 0;
  double cx = cam.K[0][2], cy = cam.K[1][2], rad = 150.0 / sqrt(3.0 * 3.0 - 1.0); /* tangent cone */
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++) {
      double d = hypot(x + 0.5 - cx, y + 0.5 - cy);
      if (d < rad - 2.0 && ids[y * W + x] < 0) holes++;
      if (d > rad + 1.0 && ids[y * W + x] >= 0) holes++;
      drawn += ids[y * W + x] >= 0;
    }
  CHECK_MSG(holes == 0, "sphere: %d pixels inconsistent with the silhouette disc", holes);
  CHECK(drawn > 1000);
  /* depth at the centre pixel ≈ 2 (front surface at distance 3 - 1) */
  int ci = (int)cy * W + (int)cx;
  CHECK_NEAR(img[ci * 4 + 3], 2.0, 0.01, 0);
  free(ids);
  /* back-face culling keeps the front (outer) surface of a closed mesh: identical image */
  a.cull = SPX_CULL_BACK;
  float *img2;
  compare(&a, "sphere culled", &img2, NULL);
  CHECK(memcmp(img, img2, sizeof(float) * W * H * 4) == 0);
  free(img);
  a.cull = SPX_CULL_FRONT; /* the inside (far) surface */
  float *img3;
  compare(&a, "sphere front-culled", &img3, NULL);
  CHECK_NEAR(img3[ci * 4 + 3], 4.0, 0.01, 0);
  free(img2);
  free(img3);
  free(pos);
  free(col);
  free(faces);
}

/* Coverage count of each pixel when each face is drawn alone (faces_out != -1). */
static void coverage_counts(int nv, const float *pos, int nf, const int32_t *faces, const spx_camera *cam, int dev,
                            int *count) {
  int W = cam->width, H = cam->height;
  float *img = malloc(sizeof(float) * W * H * 4);
  int32_t *ids = malloc(sizeof(int32_t) * W * H);
  memset(count, 0, sizeof(int) * W * H);
  for (int f = 0; f < nf; f++) {
    spx_raster_args a = base_args(nv, pos, NULL, 1, faces + 3 * f, cam);
    CHECK_OK(ctx, dev ? spx_raster(ctx, R, &a, img, ids) : spx_raster_ref(ctx, &a, img, ids));
    for (int i = 0; i < W * H; i++) count[i] += ids[i] >= 0;
  }
  free(img);
  free(ids);
}

static void test_watertight(void) {
  /* camera: f = 16, principal point 0 → u = 16 x / z; vertices on pixel-centre lines */
  spx_camera cam = cam_simple(32, 32, 16, 0, 0);
  int cnt[32 * 32];
  /* quad [4.5, 20.5]² at z = 1 split along the diagonal through pixel centres */
  float q[] = {4.5f / 16, 4.5f / 16, 1, 20.5f / 16, 4.5f / 16, 1, 20.5f / 16, 20.5f / 16, 1, 4.5f / 16, 20.5f / 16, 1};
  int32_t qf[] = {0, 1, 2, 0, 2, 3};
  for (int dev = 0; dev < 2; dev++) {
    coverage_counts(4, q, 2, qf, &cam, dev, cnt);
    int once = 0, more = 0;
    for (int i = 0; i < 32 * 32; i++) once += cnt[i] == 1, more += cnt[i] > 1;
    CHECK_MSG(once == 256 && more == 0, "quad (%s): %d pixels once, %d more than once (want 256, 0)",
              dev ? "device" : "ref", once, more);
  }
  /* fan around a centre vertex, irregular ring, both windings mixed */
  unsigned long long s = 99;
  enum { N = 13 };
  float fan[3 * (N + 1)];
  int32_t ff[3 * N];
  fan[0] = 16.37f / 16, fan[1] = 15.81f / 16, fan[2] = 1;
  for (int k = 0; k < N; k++) {
    double ang = 2 * M_PI * (k + 0.3 * spx_t_uniform(&s)) / N, r = 9 + 4 * spx_t_uniform(&s);
    fan[3 * (k + 1)] = (float)((16.37 + r * cos(ang)) / 16);
    fan[3 * (k + 1) + 1] = (float)((15.81 + r * sin(ang)) / 16);
    fan[3 * (k + 1) + 2] = 1;
    if (k % 3 == 0) { /* snap some ring vertices to pixel centres / integer positions */
      fan[3 * (k + 1)] = (float)(floor(fan[3 * (k + 1)] * 16) + 0.5) / 16;
      fan[3 * (k + 1) + 1] = (float)floor(fan[3 * (k + 1) + 1] * 16) / 16;
    }
    int a = k + 1, b = (k + 1) % N + 1;
    ff[3 * k] = 0, ff[3 * k + 1] = k % 2 ? a : b, ff[3 * k + 2] = k % 2 ? b : a;
  }
  for (int dev = 0; dev < 2; dev++) {
    coverage_counts(N + 1, fan, N, ff, &cam, dev, cnt);
    int more = 0, gaps = 0, total = 0;
    for (int y = 0; y < 32; y++)
      for (int x = 0; x < 32; x++) {
        int c = cnt[y * 32 + x];
        more += c > 1;
        total += c;
        /* centre strictly inside the ring polygon (by a margin) must be covered */
        double px = x + 0.5, py = y + 0.5;
        int inside = 1;
        for (int k = 0; k < N; k++) {
          double ax = fan[3 * (k + 1)] * 16.0, ay = fan[3 * (k + 1) + 1] * 16.0;
          double bx = fan[3 * ((k + 1) % N + 1)] * 16.0, by = fan[3 * ((k + 1) % N + 1) + 1] * 16.0;
          double cr = (bx - ax) * (py - ay) - (by - ay) * (px - ax), len = hypot(bx - ax, by - ay);
          if (cr / len < 0.01) inside = 0;
        }
        if (inside && c == 0) gaps++;
      }
    CHECK_MSG(more == 0 && gaps == 0 && total > 200, "fan (%s): %d doubly covered, %d gaps, %d total",
              dev ? "device" : "ref", more, gaps, total);
  }
  /* a quad crossing the near plane (z from -1 to 3), split in two: clipped shared edge */
  float nq[] = {-1.0f, -0.3f, -1.0f, 1.0f, -0.3f, -1.0f, 1.0f, 0.4f, 3.0f, -1.0f, 0.4f, 3.0f};
  int32_t nqf[] = {0, 1, 2, 0, 2, 3};
  spx_camera c2 = cam_simple(32, 32, 16, 16, 16);
  int c_ref[32 * 32];
  for (int dev = 0; dev < 2; dev++) {
    int *cc = dev ? cnt : c_ref;
    coverage_counts(4, nq, 2, nqf, &c2, dev, cc);
    int more = 0, total = 0;
    for (int i = 0; i < 32 * 32; i++) more += cc[i] > 1, total += cc[i];
    CHECK_MSG(more == 0 && total > 100, "near-plane quad (%s): %d doubly covered, %d total", dev ? "device" : "ref",
              more, total);
  }
  CHECK(memcmp(cnt, c_ref, sizeof cnt) == 0);
}

static void test_degenerate_and_winding(void) {
  spx_camera cam = cam_simple(40, 30, 30, 20, 15);
  float p[] = {-0.3f, -0.2f, 1, 0.3f, -0.2f, 1, 0.0f, 0.3f, 1, /* a triangle */
               -0.3f, 0.0f,  1, 0.0f, 0.0f,  1, 0.3f, 0.0f, 1}; /* collinear */
  float col[18];
  for (int i = 0; i < 18; i++) col[i] = 0.25f;
  int32_t degen[] = {3, 4, 5, 0, 0, 1, 2, 2, 2};
  float img[40 * 30 * 4];
  int32_t ids[40 * 30];
  spx_raster_args a = base_args(6, p, col, 3, degen, &cam);
  for (int dev = 0; dev < 2; dev++) {
    CHECK_OK(ctx, dev ? spx_raster(ctx, R, &a, img, ids) : spx_raster_ref(ctx, &a, img, ids));
    int drawn = 0, bg = 1;
    for (int i = 0; i < 40 * 30; i++) drawn += ids[i] >= 0;
    for (int i = 0; i < 40 * 30 * 4; i++) bg &= img[i] == 1.0f;
    CHECK_MSG(drawn == 0 && bg, "degenerate triangles drew %d pixels (%s)", drawn, dev ? "device" : "ref");
  }
  /* seen from the camera (y down), 0,1,2 is clockwise on screen: its normal (0,0,1) points away
   * → back-facing. Both windings are drawn by default, with identical coverage. */
  int32_t cw[] = {0, 1, 2}, ccw[] = {0, 2, 1};
  int cnt_cw = 0, cnt_ccw = 0;
  for (int dev = 0; dev < 2; dev++) {
    int32_t ids2[40 * 30];
    a = base_args(6, p, col, 1, cw, &cam);
    CHECK_OK(ctx, dev ? spx_raster(ctx, R, &a, img, ids) : spx_raster_ref(ctx, &a, img, ids));
    a.faces = ccw;
    CHECK_OK(ctx, dev ? spx_raster(ctx, R, &a, img, ids2) : spx_raster_ref(ctx, &a, img, ids2));
    cnt_cw = cnt_ccw = 0;
    int same = 1;
    for (int i = 0; i < 40 * 30; i++) cnt_cw += ids[i] >= 0, cnt_ccw += ids2[i] >= 0, same &= ids[i] == ids2[i];
    CHECK(cnt_cw > 50 && same);
    a.cull = SPX_CULL_BACK;
    a.faces = cw;
    CHECK_OK(ctx, dev ? spx_raster(ctx, R, &a, img, ids) : spx_raster_ref(ctx, &a, img, ids));
    int n = 0;
    for (int i = 0; i < 40 * 30; i++) n += ids[i] >= 0;
    CHECK_MSG(n == 0, "back-facing triangle drawn with CULL_BACK (%d px)", n);
    a.faces = ccw;
    CHECK_OK(ctx, dev ? spx_raster(ctx, R, &a, img, ids) : spx_raster_ref(ctx, &a, img, ids));
    n = 0;
    for (int i = 0; i < 40 * 30; i++) n += ids[i] >= 0;
    CHECK_MSG(n == cnt_cw, "front-facing triangle with CULL_BACK: %d px, want %d", n, cnt_cw);
    a.cull = SPX_CULL_FRONT;
    CHECK_OK(ctx, dev ? spx_raster(ctx, R, &a, img, ids) : spx_raster_ref(ctx, &a, img, ids));
    n = 0;
    for (int i = 0; i < 40 * 30; i++) n += ids[i] >= 0;
    CHECK(n == 0);
    /* flat colour 0.25 and depth 1 everywhere drawn */
    a.cull = SPX_CULL_NONE;
    CHECK_OK(ctx, dev ? spx_raster(ctx, R, &a, img, ids) : spx_raster_ref(ctx, &a, img, ids));
    int okc = 1;
    for (int i = 0; i < 40 * 30; i++)
      if (ids[i] >= 0) okc &= fabsf(img[4 * i] - 0.25f) < 1e-6f && fabsf(img[4 * i + 3] - 1.0f) < 1e-6f;
    CHECK(okc);
  }
}

/* Clipping: triangle crossing the near plane; depth of every drawn pixel = ray-plane distance,
 * and pixels whose ray hits well inside the triangle (in front of znear) are drawn. */
static void test_near_clip(void) {
  spx_camera cam = cam_simple(64, 48, 40, 32, 24);
  float p[] = {-0.5f, -0.4f, 2.0f, 0.6f, -0.3f, 1.5f, 0.1f, 0.5f, -0.5f};
  float col[] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  int32_t f[] = {0, 1, 2};
  spx_raster_args a = base_args(3, p, col, 1, f, &cam);
  a.znear = 0.05f;
  float *img;
  int32_t *ids;
  compare(&a, "near clip", &img, &ids);
  double e1[3], e2[3], n[3];
  for (int i = 0; i < 3; i++) e1[i] = p[3 + i] - p[i], e2[i] = p[6 + i] - p[i];
  n[0] = e1[1] * e2[2] - e1[2] * e2[1], n[1] = e1[2] * e2[0] - e1[0] * e2[2], n[2] = e1[0] * e2[1] - e1[1] * e2[0];
  int bad_depth = 0, missed = 0, drawn = 0;
  for (int y = 0; y < 48; y++)
    for (int x = 0; x < 64; x++) {
      double r[3] = {(x + 0.5 - 32) / 40, (y + 0.5 - 24) / 40, 1};
      double den = n[0] * r[0] + n[1] * r[1] + n[2] * r[2];
      double t = (n[0] * p[0] + n[1] * p[1] + n[2] * p[2]) / den; /* depth along z */
      double q[3] = {r[0] * t, r[1] * t, t};
      /* barycentric inside test with margin */
      double b[3];
      for (int k = 0; k < 3; k++) {
        const float *A = p + 3 * ((k + 1) % 3), *B = p + 3 * ((k + 2) % 3);
        double u[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]}, w[3] = {q[0] - A[0], q[1] - A[1], q[2] - A[2]};
        double c[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        b[k] = (c[0] * n[0] + c[1] * n[1] + c[2] * n[2]) / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      }
      int in = b[0] > 0.02 && b[1] > 0.02 && b[2] > 0.02 && t > 0.06;
      int i = y * 64 + x;
      if (ids[i] >= 0) {
        drawn++;
        if (!(fabs(img[4 * i + 3] - t) < 1e-3 * t) || !(img[4 * i + 3] >= 0.05f * 0.999f)) bad_depth++;
        /* colour = barycentrics of the 3-D hit point (perspective-correct) */
        if (fabs(img[4 * i] - b[0]) > 2e-3 || fabs(img[4 * i + 2] - b[2]) > 2e-3) bad_depth++;
      } else if (in) {
        missed++;
      }
    }
  CHECK_MSG(bad_depth == 0 && missed == 0 && drawn > 100, "near clip: %d bad, %d missed, %d drawn", bad_depth,
            missed, drawn);
  free(img);
  free(ids);
}

/* Many faces crossing the near plane: each yields two sub-triangles, more than the records the
 * device reserves at first, so the setup pass must grow its buffers and run again. */
static void test_clip_overflow(void) {
  spx_rasterizer *r2;
  CHECK_OK(ctx, spx_rasterizer_create(ctx, &r2));
  unsigned long long s = 777;
  enum { NF = 3000 };
  float *pos = malloc(sizeof(float) * 9 * NF), *col = malloc(sizeof(float) * 9 * NF);
  int32_t *faces = malloc(sizeof(int32_t) * 3 * NF);
  for (int f = 0; f < NF; f++)
    for (int k = 0; k < 3; k++) {
      float *p = pos + 9 * f + 3 * k;
      p[0] = (float)(spx_t_uniform(&s) * 2 - 1), p[1] = (float)(spx_t_uniform(&s) * 2 - 1);
      p[2] = k == 0 ? -1.0f : (float)(1 + spx_t_uniform(&s));
      for (int c = 0; c < 3; c++) col[9 * f + 3 * k + c] = (float)spx_t_uniform(&s);
      faces[3 * f + k] = 3 * f + k;
    }
  spx_camera cam = cam_simple(64, 48, 30, 32, 24);
  spx_raster_args a = base_args(3 * NF, pos, col, NF, faces, &cam);
  spx_rasterizer *keep = R;
  R = r2;
  compare(&a, "clip overflow", NULL, NULL);
  compare(&a, "clip overflow again", NULL, NULL);
  R = keep;
  spx_rasterizer_destroy(r2);
  free(pos);
  free(col);
  free(faces);
}

static void test_texture(void) {
  /* texture with R = column index, G = row index (linear: bilinear reproduces it exactly) */
  enum { TW = 8, TH = 4 };
  float tex[TW * TH * 4];
  for (int y = 0; y < TH; y++)
    for (int x = 0; x < TW; x++) {
      float *t = tex + 4 * (y * TW + x);
      t[0] = (float)x, t[1] = (float)y, t[2] = 0.5f, t[3] = 9;
    }
  spx_camera cam = cam_simple(40, 40, 20, 20, 20);
  /* screen-aligned quad at z = 2 covering pixels 5..34; uv from -0.5 to 1.5 */
  float p[] = {-1.5f, -1.5f, 2, 1.5f, -1.5f, 2, 1.5f, 1.5f, 2, -1.5f, 1.5f, 2};
  float uv[] = {-0.5f, 1.5f, 1.5f, 1.5f, 1.5f, -0.5f, -0.5f, -0.5f};
  int32_t f[] = {0, 1, 2, 0, 2, 3};
  spx_raster_args a = base_args(4, p, NULL, 2, f, &cam);
  a.nuv = 4, a.uv = uv, a.face_uv = f, a.tex = tex, a.tex_width = TW, a.tex_height = TH, a.tex_channels = 4;
  for (int wrap = 0; wrap < 2; wrap++) {
    a.wrap = (spx_wrap)wrap;
    float *img;
    compare(&a, wrap ? "texture clamp" : "texture wrap", &img, NULL);
    int bad = 0, n = 0;
    for (int y = 5; y < 35; y++)
      for (int x = 5; x < 35; x++) {
        double u = -0.5 + 2.0 * (x + 0.5 - 5) / 30, v = 1.5 - 2.0 * (y + 0.5 - 5) / 30;
        double tx = u * TW - 0.5, ty = (1 - v) * TH - 0.5;
        const float *o = img + 4 * (y * 40 + x);
        if (wrap) {
          double ex = tx < 0 ? 0 : tx > TW - 1 ? TW - 1 : tx, ey = ty < 0 ? 0 : ty > TH - 1 ? TH - 1 : ty;
          bad += fabs(o[0] - ex) > 1e-3 || fabs(o[1] - ey) > 1e-3;
          n++;
        } else if (tx > 0.01 && tx < TW - 1.01 && ty > 0.01 && ty < TH - 1.01) {
          bad += fabs(o[0] - tx) > 1e-3 || fabs(o[1] - ty) > 1e-3;
          n++;
        }
        bad += fabs(o[2] - 0.5) > 1e-6 || fabs(o[3] - 2.0) > 1e-5;
      }
    CHECK_MSG(bad == 0 && n > 100, "texture %s: %d bad of %d", wrap ? "clamp" : "wrap", bad, n);
    free(img);
  }
  /* wrap: shifting all uv by whole numbers changes nothing */
  float uv2[8];
  for (int i = 0; i < 8; i++) uv2[i] = uv[i] + (i % 2 ? -3.0f : 2.0f);
  a.wrap = SPX_WRAP_REPEAT;
  float *i1 = malloc(sizeof(float) * 40 * 40 * 4), *i2 = malloc(sizeof(float) * 40 * 40 * 4);
  CHECK_OK(ctx, spx_raster(ctx, R, &a, i1, NULL));
  a.uv = uv2;
  CHECK_OK(ctx, spx_raster(ctx, R, &a, i2, NULL));
  double worst = 0;
  for (int i = 0; i < 40 * 40 * 4; i++) worst = fmax(worst, fabs(i1[i] - i2[i]));
  CHECK_MSG(worst < 1e-4, "wrap not periodic: %g", worst);
  /* textured sphere with vertex colours (modulated), vs reference */
  float *pos, *col;
  int32_t *faces;
  int nv, nf;
  make_sphere(20, 24, 1.0f, &pos, &col, &faces, &nv, &nf);
  float *suv = malloc(sizeof(float) * 2 * nv);
  for (int i = 0; i < nv; i++) suv[2 * i] = (float)(i % 24) / 6.0f, suv[2 * i + 1] = (float)(i / 24) / 5.0f;
  spx_camera c2 = cam_orbit(120, 90, 90, 1.0, 3.0);
  spx_raster_args b = base_args(nv, pos, col, nf, faces, &c2);
  b.nuv = nv, b.uv = suv, b.face_uv = faces, b.tex = tex, b.tex_width = TW, b.tex_height = TH, b.tex_channels = 4;
  b.wrap = SPX_WRAP_REPEAT;
  compare(&b, "textured sphere wrap", NULL, NULL);
  b.wrap = SPX_WRAP_CLAMP;
  b.layout = SPX_LAYOUT_NCHW;
  compare(&b, "textured sphere clamp", NULL, NULL);
  /* static_id: topology and texture stay resident; a second call (moved vertices) still matches */
  b.static_id = 42;
  compare(&b, "textured sphere resident 1", NULL, NULL);
  for (int i = 0; i < nv * 3; i++) pos[i] *= 0.9f;
  compare(&b, "textured sphere resident 2", NULL, NULL);
  b.static_id = 0;
  free(suv);
  free(pos);
  free(col);
  free(faces);
  free(i1);
  free(i2);
}

static void test_aa(void) {
  float *pos, *col;
  int32_t *faces;
  int nv, nf;
  make_sphere(16, 20, 1.0f, &pos, &col, &faces, &nv, &nf);
  spx_camera cam = cam_orbit(61, 47, 40, 0.7, 3.0);
  spx_camera big = cam;
  big.width *= 2, big.height *= 2;
  for (int i = 0; i < 2; i++)
    for (int j = 0; j < 3; j++) big.K[i][j] *= 2;
  int W = cam.width, H = cam.height;
  float *hi = malloc(sizeof(float) * 4 * W * H * 4), *exp = malloc(sizeof(float) * W * H * 4);
  spx_raster_args a = base_args(nv, pos, col, nf, faces, &big);
  CHECK_OK(ctx, spx_raster_ref(ctx, &a, hi, NULL));
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++)
      for (int c = 0; c < 4; c++) {
        const float *r0 = hi + ((2 * y) * 2 * W + 2 * x) * 4, *r1 = r0 + 2 * W * 4;
        exp[(y * W + x) * 4 + c] = (((r0[c] + r0[4 + c]) + r1[c]) + r1[4 + c]) * 0.25f;
      }
  a = base_args(nv, pos, col, nf, faces, &cam);
  a.aa = 2;
  float *got;
  compare(&a, "aa2", &got, NULL);
  int bad = 0, partial = 0;
  for (int i = 0; i < W * H * 4; i++) {
    bad += got[i] != exp[i]; /* the reference: bit for bit */
    partial += i % 4 == 3 && got[i] > 1.0f && got[i] < 2.0f;
  }
  CHECK_MSG(bad == 0, "aa2 differs from the box-filtered 2x render in %d values", bad);
  CHECK(partial > 0); /* some edge pixels mix background and surface */
  free(got);
  /* NCHW output of the device path */
  a.layout = SPX_LAYOUT_NCHW;
  compare(&a, "aa2 nchw", NULL, NULL);
  free(hi);
  free(exp);
  free(pos);
  free(col);
  free(faces);
}

static void test_multi_camera(void) {
  float *pos, *col;
  int32_t *faces;
  int nv, nf;
  make_sphere(12, 16, 1.0f, &pos, &col, &faces, &nv, &nf);
  spx_camera cams[3] = {cam_orbit(50, 40, 30, 0.0, 3.0), cam_orbit(50, 40, 30, 2.0, 2.5),
                        cam_orbit(50, 40, 30, 4.0, 1.0)}; /* the last one inside the sphere */
  spx_raster_args a = base_args(nv, pos, col, nf, faces, cams);
  a.ncams = 3;
  float *all;
  compare(&a, "3 cameras", &all, NULL);
  float one[50 * 40 * 4];
  for (int c = 0; c < 3; c++) {
    spx_raster_args b = base_args(nv, pos, col, nf, faces, &cams[c]);
    CHECK_OK(ctx, spx_raster(ctx, R, &b, one, NULL));
    double worst = 0;
    for (int i = 0; i < 50 * 40 * 4; i++) worst = fmax(worst, fabs(one[i] - all[c * 50 * 40 * 4 + i]));
    CHECK(worst < 1e-5);
  }
  free(all);
  free(pos);
  free(col);
  free(faces);
}

static void test_errors(void) {
  spx_camera cam = cam_simple(8, 8, 8, 4, 4);
  float p[] = {0, 0, 1, 1, 0, 1, 0, 1, 1};
  int32_t f[] = {0, 1, 3};
  float img[8 * 8 * 4];
  spx_raster_args a = base_args(3, p, NULL, 1, f, &cam);
  CHECK(spx_raster(ctx, R, &a, img, NULL) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "face 0") != NULL);
  CHECK(spx_raster_ref(ctx, &a, img, NULL) == SPX_E_ARG);
  f[2] = 2;
  p[4] = NAN;
  CHECK(spx_raster(ctx, R, &a, img, NULL) == SPX_E_NUMERIC);
  p[4] = 0;
  a.aa = 3;
  CHECK(spx_raster(ctx, R, &a, img, NULL) == SPX_E_ARG);
  a.aa = 2;
  int32_t ids[64];
  CHECK(spx_raster(ctx, R, &a, img, ids) == SPX_E_ARG); /* faces_out needs aa 1 */
  a.aa = 1;
  a.uv = p; /* texture args incomplete */
  CHECK(spx_raster(ctx, R, &a, img, NULL) == SPX_E_ARG);
  a.uv = NULL;
  spx_camera bad = cam;
  bad.K[0][0] = -1;
  a.cams = &bad;
  CHECK(spx_raster(ctx, R, &a, img, NULL) == SPX_E_CAMERA);
  a.cams = &cam;
  a.nfaces = 0; /* empty mesh: background */
  CHECK_OK(ctx, spx_raster(ctx, R, &a, img, ids));
  int bg = 1;
  for (int i = 0; i < 64 * 4; i++) bg &= img[i] == 1.0f;
  for (int i = 0; i < 64; i++) bg &= ids[i] == -1;
  CHECK(bg);
}

int main(void) {
  if (spx_t_open_device(&ctx) || spx_t_no_device(ctx, spx_rasterizer_create(ctx, &R))) return 1;
  SPX_RUN(test_random_meshes);
  SPX_RUN(test_sphere);
  SPX_RUN(test_watertight);
  SPX_RUN(test_degenerate_and_winding);
  SPX_RUN(test_near_clip);
  SPX_RUN(test_clip_overflow);
  SPX_RUN(test_texture);
  SPX_RUN(test_aa);
  SPX_RUN(test_multi_camera);
  SPX_RUN(test_errors);
  /* the other device's forms: per-pixel tile kernel (GPU) and one face per setup work-item */
  const char *forms[][2] = {{"0", "1"}};
  for (int i = 0; i < 1; i++) {
    /* tunables are resolved when the device opens: reopen it (and the rasterizer's buffers) */
    setenv("SPX_TUNE_RASTER_SERIAL", forms[i][0], 1);
    setenv("SPX_TUNE_RASTER_CHUNK", forms[i][1], 1);
    fprintf(stderr, "SPX_TUNE_RASTER_SERIAL=%s SPX_TUNE_RASTER_CHUNK=%s\n", forms[i][0], forms[i][1]);
    spx_rasterizer_destroy(R);
    R = NULL;
    CHECK_OK(ctx, spx_device_open(ctx, NULL));
    CHECK(ctx->dev->tune.raster_serial == atoi(forms[i][0]) && ctx->dev->tune.raster_chunk == atoi(forms[i][1]));
    CHECK_OK(ctx, spx_rasterizer_create(ctx, &R));
    SPX_RUN(test_random_meshes);
    SPX_RUN(test_watertight);
    SPX_RUN(test_clip_overflow);
    SPX_RUN(test_aa);
  }
  spx_rasterizer_destroy(R);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
