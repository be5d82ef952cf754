/* What one camera saw (lib/fit/stage.h): a coarse depth image of the scan from the camera's
 * centre, and from it which model vertices the camera would have seen. A vertex hidden behind
 * scanned surface, or facing away from the camera, is no evidence either way: the data terms
 * that pull the model towards the scan leave it alone and the free stage keeps its model shape. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "body/rot3.h"
#include "fit/stage.h"

/* Camera-space coordinates of p: c = R (p - eye). */
static void cam_coords(const spx_fit_zgrid *g, const double p[3], double c[3]) {
  double e[3] = {p[0] - g->eye[0], p[1] - g->eye[1], p[2] - g->eye[2]};
  for (int r = 0; r < 3; r++) c[r] = g->R[r * 3] * e[0] + g->R[r * 3 + 1] * e[1] + g->R[r * 3 + 2] * e[2];
}

/* Pixel of camera-space point c, or -1 outside the grid. */
static int64_t pixel_of(const spx_fit_zgrid *g, const double c[3]) {
  if (!(c[2] > 0)) return -1;
  double a = (c[0] / c[2] - g->a0) / g->px, b = (c[1] / c[2] - g->b0) / g->px;
  if (!(a >= 0 && b >= 0 && a < g->W && b < g->H)) return -1;
  return (int64_t)b * g->W + (int64_t)a;
}

spx_status spx_fit_zgrid_build(spx_ctx *ctx, const double eye[3], const float *Q, int32_t nq, const int32_t *qv,
                               int32_t cam, spx_fit_zgrid *g) {
  free(g->z), free(g->near);
  memset(g, 0, sizeof *g);
  memcpy(g->eye, eye, sizeof g->eye);
  /* optical axis: from the eye to the centroid of its points; x, y any orthonormal completion */
  double c[3] = {0, 0, 0}, z[3], x[3], y[3];
  int32_t nmine = 0;
  for (int32_t i = 0; i < nq; i++)
    if (!qv || qv[i] == cam) {
      nmine++;
      for (int d = 0; d < 3; d++) c[d] += Q[i * 3 + d];
    }
  if (!nmine) return spx_fail(ctx, SPX_E_ARG, "registration: camera %d of the scan saw none of its points", (int)cam);
  for (int d = 0; d < 3; d++) c[d] /= nmine;
  for (int d = 0; d < 3; d++) z[d] = c[d] - eye[d];
  double nz = sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
  if (!(nz > 0)) return spx_fail(ctx, SPX_E_ARG, "registration: the camera of the view is at the scan's centre");
  for (int d = 0; d < 3; d++) z[d] /= nz;
  double h[3] = {fabs(z[0]) < 0.9 ? 1.0 : 0.0, fabs(z[0]) < 0.9 ? 0.0 : 1.0, 0.0};
  spx_rot3_cross(z, h, x);
  double nx = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  for (int d = 0; d < 3; d++) x[d] /= nx;
  spx_rot3_cross(z, x, y);
  for (int d = 0; d < 3; d++) g->R[d] = x[d], g->R[3 + d] = y[d], g->R[6 + d] = z[d];
  /* the grid spans the scan's image; about nq/2 pixels, so that most seen pixels hold a point */
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  int32_t nin = 0;
  for (int32_t i = 0; i < nq; i++) {
    if (qv && qv[i] != cam) continue;
    double p[3] = {Q[i * 3], Q[i * 3 + 1], Q[i * 3 + 2]}, q[3];
    cam_coords(g, p, q);
    if (!(q[2] > 0)) continue;
    double a = q[0] / q[2], b = q[1] / q[2];
    lo[0] = fmin(lo[0], a), hi[0] = fmax(hi[0], a), lo[1] = fmin(lo[1], b), hi[1] = fmax(hi[1], b);
    nin++;
  }
  if (nin < 10) return spx_fail(ctx, SPX_E_ARG, "registration: the scan is not in front of the camera of the view");
  double area = fmax(hi[0] - lo[0], 1e-6) * fmax(hi[1] - lo[1], 1e-6);
  g->px = sqrt(area / (0.5 * nin));
  g->a0 = lo[0], g->b0 = lo[1];
  g->W = (int32_t)fmin(4096, (hi[0] - lo[0]) / g->px + 1), g->H = (int32_t)fmin(4096, (hi[1] - lo[1]) / g->px + 1);
  g->px = fmax(g->px, fmax((hi[0] - lo[0]) / (g->W - 0.5), (hi[1] - lo[1]) / (g->H - 0.5)));
  g->z = spx_alloc_array(ctx, (size_t)g->W * g->H, sizeof(float), "registration view");
  if (!g->z) return SPX_E_NOMEM;
  for (size_t p = 0; p < (size_t)g->W * g->H; p++) g->z[p] = INFINITY;
  for (int32_t i = 0; i < nq; i++) {
    if (qv && qv[i] != cam) continue;
    double p[3] = {Q[i * 3], Q[i * 3 + 1], Q[i * 3 + 2]}, q[3];
    cam_coords(g, p, q);
    int64_t k = pixel_of(g, q);
    if (k >= 0 && q[2] < g->z[k]) g->z[k] = (float)q[2];
  }
  return SPX_OK;
}

void spx_fit_zgrid_free(spx_fit_zgrid *g) {
  free(g->z), free(g->near);
  memset(g, 0, sizeof *g);
}

void spx_fit_visibility(const spx_fit_zgrid *g, const float *V, const double *N, int32_t nv, double tol,
                        unsigned char *seen) {
  for (int32_t j = 0; j < nv; j++) {
    double p[3] = {V[j * 3], V[j * 3 + 1], V[j * 3 + 2]}, c[3];
    const double *n = N + (size_t)j * 3;
    if (seen[j] || n[0] * (g->eye[0] - p[0]) + n[1] * (g->eye[1] - p[1]) + n[2] * (g->eye[2] - p[2]) <= 0) continue;
    cam_coords(g, p, c);
    int64_t k = pixel_of(g, c);
    if (k < 0) {
      seen[j] = 1;
      continue;
    }
    /* nearest scanned depth around the pixel (3x3: the grid has gaps between points) */
    int32_t a = (int32_t)(k % g->W), b = (int32_t)(k / g->W);
    float zmin = INFINITY;
    for (int32_t bb = b - 1; bb <= b + 1; bb++)
      for (int32_t aa = a - 1; aa <= a + 1; aa++)
        if (aa >= 0 && bb >= 0 && aa < g->W && bb < g->H) zmin = fminf(zmin, g->z[(size_t)bb * g->W + aa]);
    seen[j] = c[2] <= zmin + tol; /* not behind scanned surface */
  }
}
