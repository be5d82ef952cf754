/* Free space (lib/fit/stage.h): where a camera saw past the person, no part of the body can be. A
 * camera's silhouette is the pixels of a depth grid of its points (the free stage's larger scan
 * sample, so that thin parts such as fingers hold points) that hold scan points, closed (dilated and
 * eroded by FS_CLOSE pixels, so the gaps between samples count as body while the outline stays);
 * every model vertex that no camera saw and that projects more than a pixel outside it (or outside
 * the grid) gets a target: the same depth on the ray of the nearest silhouette pixel (breadth-first over the
 * grid). The pose and free stages pull such vertices towards their targets along the line between:
 * a model whose unseen side is wider than what the camera saw of it, or that bulges out past the
 * outline, is drawn back in. Only with cameras given (not one inferred from the scan's shape). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/stage.h"

#define FS_CLOSE 2

/* m = mask grown (grow = 1) or shrunk (0) by r pixels (square); out of the grid counts as empty. */
static void morph(const unsigned char *in, int32_t W, int32_t H, int r, int grow, unsigned char *out) {
  for (int32_t j = 0; j < H; j++)
    for (int32_t i = 0; i < W; i++) {
      int any = 0, all = 1;
      for (int32_t b = j - r; b <= j + r; b++)
        for (int32_t a = i - r; a <= i + r; a++) {
          int v = a >= 0 && b >= 0 && a < W && b < H && in[(size_t)b * W + a];
          any |= v, all &= v;
        }
      out[(size_t)j * W + i] = (unsigned char)(grow ? any : all);
    }
}

spx_status spx_fit_zgrid_silhouette(spx_ctx *ctx, spx_fit_zgrid *g) {
  size_t n = (size_t)g->W * g->H;
  unsigned char *m = spx_alloc_array(ctx, n, 2, "free space");
  free(g->near);
  g->near = spx_alloc_array(ctx, n, sizeof(int32_t), "free space");
  int32_t *queue = spx_alloc_array(ctx, n, sizeof(int32_t), "free space");
  if (!m || !g->near || !queue) {
    free(m), free(queue);
    return SPX_E_NOMEM;
  }
  for (size_t p = 0; p < n; p++) m[p] = isfinite(g->z[p]);
  morph(m, g->W, g->H, FS_CLOSE, 1, m + n);
  morph(m + n, g->W, g->H, FS_CLOSE, 0, m);
  /* nearest silhouette pixel of every pixel: breadth-first from all of them at once */
  size_t head = 0, tail = 0;
  for (size_t p = 0; p < n; p++) {
    g->near[p] = m[p] ? (int32_t)p : -1;
    if (m[p]) queue[tail++] = (int32_t)p;
  }
  while (head < tail) {
    int32_t p = queue[head++], i = p % g->W, j = p / g->W;
    for (int32_t b = j - 1; b <= j + 1; b++)
      for (int32_t a = i - 1; a <= i + 1; a++) {
        if (a < 0 || b < 0 || a >= g->W || b >= g->H) continue;
        size_t q = (size_t)b * g->W + a;
        if (g->near[q] >= 0) continue;
        g->near[q] = g->near[p];
        queue[tail++] = (int32_t)q;
      }
  }
  free(m), free(queue);
  return SPX_OK;
}

int spx_fit_outside_silhouette(const spx_fit_zgrid *g, const double x[3], double q[3]) {
  double e[3] = {x[0] - g->eye[0], x[1] - g->eye[1], x[2] - g->eye[2]}, c[3];
  for (int r = 0; r < 3; r++) c[r] = g->R[r * 3] * e[0] + g->R[r * 3 + 1] * e[1] + g->R[r * 3 + 2] * e[2];
  if (!(c[2] > 0) || !g->near) return 0;
  double a = (c[0] / c[2] - g->a0) / g->px, b = (c[1] / c[2] - g->b0) / g->px;
  int inside = a >= 0 && b >= 0 && a < g->W && b < g->H;
  int32_t ia = (int32_t)fmin(fmax(floor(a), 0), g->W - 1), ib = (int32_t)fmin(fmax(floor(b), 0), g->H - 1);
  int32_t p = ib * g->W + ia, t = g->near[p];
  /* within a pixel of the outline is within the grid's own quantisation: no evidence */
  int32_t di = abs(t % g->W - ia), dj = abs(t / g->W - ib);
  if (t < 0 || (inside && (di > dj ? di : dj) <= 1)) return 0;
  /* the target pixel's centre on the image plane, at the vertex's depth, back in the model frame */
  double u = g->a0 + ((t % g->W) + 0.5) * g->px, v = g->b0 + ((t / g->W) + 0.5) * g->px;
  double cq[3] = {u * c[2], v * c[2], c[2]};
  for (int d = 0; d < 3; d++) q[d] = g->eye[d] + g->R[d] * cq[0] + g->R[3 + d] * cq[1] + g->R[6 + d] * cq[2];
  return 1;
}

int32_t spx_fit_free_space_pairs(const spx_fit_work *w, const float *V, int32_t nv, int32_t *idx, double *q,
                                 double *n) {
  int32_t np = 0;
  for (int32_t j = 0; w->free_space && j < nv; j++) {
    if (w->seen[j]) continue; /* what a camera saw meets the data terms instead */
    double x[3] = {V[j * 3], V[j * 3 + 1], V[j * 3 + 2]}, t[3], best = 0;
    for (int32_t k = 0; k < w->neye; k++) {
      if (!spx_fit_outside_silhouette(&w->zg[k], x, t)) continue;
      double dv[3] = {t[0] - x[0], t[1] - x[1], t[2] - x[2]}, l = sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]);
      if (!(l > best)) continue; /* the camera it is farthest outside of */
      best = l, idx[np] = j;
      for (int d = 0; d < 3; d++) q[np * 3 + d] = t[d], n[np * 3 + d] = dv[d] / l;
    }
    if (best > 1e-3) np++;
  }
  return np;
}
