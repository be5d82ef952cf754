/* Plain-C double references for kernels/pool.cl. */
#include <math.h>

#include "nn/pool.h"

/* flat index (into x) of the argmax of the window at output (p, oy, ox) */
static size_t argmax(const double *x, int p, int h, int w, int oy, int ox) {
  size_t best = ((size_t)p * h + 2 * oy) * w + 2 * ox;
  double m = -INFINITY;
  for (int dy = 0; dy < 2; dy++)
    for (int dx = 0; dx < 2; dx++) {
      size_t k = ((size_t)p * h + 2 * oy + dy) * w + 2 * ox + dx;
      if (x[k] > m || isnan(x[k])) {
        m = x[k];
        best = k;
      }
    }
  return best;
}

void spx_ref_maxpool_forward(const double *x, int n, int c, int h, int w, double *y) {
  int oh = h / 2, ow = w / 2;
  for (int p = 0; p < n * c; p++)
    for (int oy = 0; oy < oh; oy++)
      for (int ox = 0; ox < ow; ox++) y[((size_t)p * oh + oy) * ow + ox] = x[argmax(x, p, h, w, oy, ox)];
}

void spx_ref_maxpool_backward(const double *x, const double *dy, int n, int c, int h, int w, double *dx) {
  int oh = h / 2, ow = w / 2;
  for (int p = 0; p < n * c; p++)
    for (int oy = 0; oy < oh; oy++)
      for (int ox = 0; ox < ow; ox++) dx[argmax(x, p, h, w, oy, ox)] += dy[((size_t)p * oh + oy) * ow + ox];
}
