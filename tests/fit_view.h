/* What one depth camera sees, for the registration tests and benchmark: a camera looking at a body
 * from a direction, the body's depth image through it (the rasterizer's depth channel, 0 where no
 * triangle is drawn), a single-view scan (area-uniform surface samples kept where the depth image
 * shows them, with noise), raw depth frames of the body standing in a room (floor, walls, flying
 * pixels at its silhouette, noise, whole millimetres), scans with round holes, and the score
 * against the complete surface (mean distance from noise-free samples of the whole true body to
 * the registered surface).
 * Header-only, deterministic. */
#ifndef SPX_TESTS_FIT_VIEW_H
#define SPX_TESTS_FIT_VIEW_H

#include "fit_synth.h"
#include "smplpix/raster.h"

/* A W x H camera with focal length f (pixels) at `dist` metres from the centre of the body's
 * bounding box, along dir (from the body to the camera, any length), y up. */
static inline int view_camera(spx_ctx *ctx, const double *V, int32_t nv, const double dir[3], double dist, int32_t W,
                              int32_t H, double f, spx_camera *cam) {
  double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30}, c[3], eye[3], up[3] = {0, 1, 0};
  for (int32_t i = 0; i < nv; i++)
    for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], V[i * 3 + d]), hi[d] = fmax(hi[d], V[i * 3 + d]);
  double n = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  for (int d = 0; d < 3; d++) c[d] = 0.5 * (lo[d] + hi[d]), eye[d] = c[d] + dist * dir[d] / n;
  return spx_camera_look_at(ctx, W, H, f, eye, c, up, cam) ? -1 : 0;
}

/* The camera's centre in world coordinates: -R^T t. */
static inline void view_eye(const spx_camera *cam, double eye[3]) {
  for (int d = 0; d < 3; d++) eye[d] = -(cam->R[0][d] * cam->t[0] + cam->R[1][d] * cam->t[1] + cam->R[2][d] * cam->t[2]);
}

/* depth (H*W): the camera depth of the nearest triangle at each pixel centre, 0 where there is none. */
static inline int view_depth(spx_ctx *ctx, const double *V, int32_t nv, const int32_t *F, int32_t nf,
                             const spx_camera *cam, float *depth) {
  size_t npx = (size_t)cam->width * cam->height;
  float *pos = malloc((size_t)nv * 3 * sizeof(float)), *img = malloc(npx * 4 * sizeof(float));
  int32_t *fo = malloc(npx * sizeof(int32_t));
  int rc = -1;
  if (pos && img && fo) {
    for (int32_t i = 0; i < nv * 3; i++) pos[i] = (float)V[i];
    spx_raster_args a = {.nverts = nv, .pos = pos, .nfaces = nf, .faces = F, .ncams = 1, .cams = cam, .aa = 1,
                         .layout = SPX_LAYOUT_HWC};
    if (!spx_raster_ref(ctx, &a, img, fo)) {
      for (size_t p = 0; p < npx; p++) depth[p] = fo[p] >= 0 ? img[p * 4 + 3] : 0.0f;
      rc = 0;
    }
  }
  free(pos), free(img), free(fo);
  return rc;
}

/* A single-view scan: npoints area-uniform samples of the surface, kept where a depth image of
 * twice the camera's resolution shows them (within 1 cm), then Gaussian noise (noise_m). */
static inline int view_scan(spx_ctx *ctx, const double *V, int32_t nv, const int32_t *F, int32_t nf,
                            const spx_camera *cam, int32_t npoints, double noise_m, uint64_t seed, spx_mesh *out) {
  spx_camera c2 = *cam;
  c2.width *= 2, c2.height *= 2;
  for (int k = 0; k < 2; k++)
    for (int j = 0; j < 3; j++) c2.K[k][j] *= 2;
  size_t npx = (size_t)c2.width * c2.height;
  float *depth = malloc(npx * sizeof(float));
  synth_opts so = {npoints, 0.0, 0.0, 0, 1.0, 0};
  if (!depth || view_depth(ctx, V, nv, F, nf, &c2, depth) || synth_scan(V, nv, F, nf, &so, seed, out, NULL, NULL)) {
    free(depth);
    return -1;
  }
  uint64_t s = seed * 0x2545F4914F6CDD1DULL + 5;
  int32_t n = 0;
  for (int32_t i = 0; i < out->nv; i++) {
    const float *x = out->pos + i * 3;
    double p[3];
    for (int r = 0; r < 3; r++) p[r] = c2.R[r][0] * x[0] + c2.R[r][1] * x[1] + c2.R[r][2] * x[2] + c2.t[r];
    if (!(p[2] > 0)) continue;
    double u = (c2.K[0][0] * p[0] + c2.K[0][1] * p[1] + c2.K[0][2] * p[2]) / p[2];
    double v = (c2.K[1][1] * p[1] + c2.K[1][2] * p[2]) / p[2];
    if (!(u >= 0 && v >= 0 && u < c2.width && v < c2.height)) continue;
    float d = depth[(size_t)v * c2.width + (size_t)u];
    if (!(d > 0 && p[2] < d + 0.01)) continue;
    for (int k = 0; k < 3; k++) out->pos[n * 3 + k] = (float)(x[k] + noise_m * synth_gauss(&s));
    n++;
  }
  out->nv = n;
  free(depth);
  return 0;
}

/* Camera depth of a room (floor at y0, walls 3.2 m from (cx, cz), ceiling 2.6 m above the floor)
 * along the ray of pixel (i, j): the eye is inside, so the nearest plane ahead is where it leaves. */
static inline double view_room_ray(const spx_camera *cam, const double eye[3], double y0, double cx, double cz,
                                   int32_t i, int32_t j) {
  double yc = (j + 0.5 - cam->K[1][2]) / cam->K[1][1];
  double xc = (i + 0.5 - cam->K[0][2] - cam->K[0][1] * yc) / cam->K[0][0], rc[3] = {xc, yc, 1}, w[3];
  for (int d = 0; d < 3; d++) w[d] = cam->R[0][d] * rc[0] + cam->R[1][d] * rc[1] + cam->R[2][d] * rc[2];
  const double L = 3.2;
  double planes[6][2] = {{1, y0}, {1, y0 + 2.6}, {0, cx - L}, {0, cx + L}, {2, cz - L}, {2, cz + L}}, best = INFINITY;
  for (int k = 0; k < 6; k++) {
    int ax = (int)planes[k][0];
    if (fabs(w[ax]) < 1e-12) continue;
    double t = (planes[k][1] - eye[ax]) / w[ax];
    if (t > 0 && t < best) best = t;
  }
  return best; /* camera depth: rc has z = 1 */
}

/* Flying pixels: half of the pixels on either side of a body / background jump over 5 cm take a
 * random mix of the two depths. */
static inline void view_flying(const float *in, const unsigned char *body, int32_t W, int32_t H, uint64_t *s,
                               float *out) {
  memcpy(out, in, (size_t)W * H * sizeof(float));
  static const int nb[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  for (int32_t j = 0; j < H; j++)
    for (int32_t i = 0; i < W; i++) {
      size_t p = (size_t)j * W + i;
      for (int k = 0; k < 4; k++) {
        int32_t a = i + nb[k][0], bb = j + nb[k][1];
        if (a < 0 || bb < 0 || a >= W || bb >= H) continue;
        size_t q = (size_t)bb * W + a;
        if (body[p] == body[q] || !(in[q] > 0) || fabsf(in[p] - in[q]) < 0.05f) continue;
        if (synth_uni(s) < 0.5) {
          double t = 0.2 + 0.6 * synth_uni(s);
          out[p] = (float)(t * in[p] + (1 - t) * in[q]);
        }
        break;
      }
    }
}

/* A raw depth frame (cam->height*cam->width metres, 0 = no data) of the body (V, F): with room,
 * standing in a room (view_room_ray: floor at the body's lowest point, walls 3.2 m from its box's
 * centre) with flying pixels at its silhouette (view_flying); then Gaussian noise (noise_m) and
 * whole millimetres, as a 16-bit PNG holds them. Returns 0 or -1. */
static inline int view_room_depth(spx_ctx *ctx, const double *V, int32_t nv, const int32_t *F, int32_t nf,
                                  const spx_camera *cam, int room, double noise_m, uint64_t seed, float *depth) {
  int32_t W = cam->width, H = cam->height;
  size_t npx = (size_t)W * H;
  float *tmp = malloc(npx * sizeof(float));
  unsigned char *body = malloc(npx);
  int rc = !tmp || !body ? -1 : view_depth(ctx, V, nv, F, nf, cam, tmp);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, eye[3];
  for (int32_t i = 0; i < nv; i++)
    for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], V[i * 3 + d]), hi[d] = fmax(hi[d], V[i * 3 + d]);
  view_eye(cam, eye);
  uint64_t s = seed * 0xD1B54A32D192ED03ULL + 29;
  for (size_t p = 0; !rc && p < npx; p++) {
    double r = room ? view_room_ray(cam, eye, lo[1], 0.5 * (lo[0] + hi[0]), 0.5 * (lo[2] + hi[2]), (int32_t)(p % W),
                                    (int32_t)(p / W))
                    : INFINITY;
    body[p] = tmp[p] > 0 && tmp[p] <= r;
    tmp[p] = body[p] ? tmp[p] : isfinite(r) ? (float)r : 0.0f;
  }
  if (!rc && room) view_flying(tmp, body, W, H, &s, depth);
  else if (!rc) memcpy(depth, tmp, npx * sizeof(float));
  for (size_t p = 0; !rc && p < npx; p++)
    if (depth[p] > 0) depth[p] = roundf((float)(depth[p] + noise_m * synth_gauss(&s)) * 1000.0f) / 1000.0f;
  free(tmp), free(body);
  return rc;
}

/* Removes from a point cloud every point within radius r of `count` random points of it. */
static inline void view_holes(spx_mesh *scan, int count, double r, uint64_t seed) {
  uint64_t s = seed * 0x9E3779B97F4A7C15ULL + 11;
  for (int h = 0; h < count && scan->nv > 0; h++) {
    float c[3];
    memcpy(c, scan->pos + (synth_next(&s) % (uint64_t)scan->nv) * 3, sizeof c);
    int32_t n = 0;
    for (int32_t i = 0; i < scan->nv; i++) {
      const float *x = scan->pos + i * 3;
      double dx = x[0] - c[0], dy = x[1] - c[1], dz = x[2] - c[2];
      if (dx * dx + dy * dy + dz * dz < r * r) continue;
      memmove(scan->pos + n * 3, x, 3 * sizeof(float));
      if (scan->col) memmove(scan->col + n * 3, scan->col + i * 3, 3 * sizeof(float));
      n++;
    }
    scan->nv = n;
  }
}

/* Mean distance (metres) from 30,000 noise-free samples of the whole true surface (V, F) to the
 * registered surface (reg: nv*3 floats, faces rf); -1 on failure. */
static inline double view_complete_error(spx_ctx *ctx, const double *V, int32_t nv, const int32_t *F, int32_t nf,
                                         const float *reg, int32_t rnv, const int32_t *rf, int32_t rnf) {
  spx_mesh truth;
  synth_opts so = {30000, 0.0, 0.0, 0, 1.0, 0};
  if (synth_scan(V, nv, F, nf, &so, 99, &truth, NULL, NULL)) return -1;
  double mean = -1;
  if (spx_fit_surface_distance(ctx, truth.pos, truth.nv, reg, rnv, rf, rnf, NULL, &mean, NULL, NULL)) mean = -1;
  spx_mesh_free(&truth);
  return mean;
}

#endif
