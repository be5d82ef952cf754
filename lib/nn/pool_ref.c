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

/* rows/cols [lo, hi] of output o's window, clipped to [0, n) */
static void win(int o, int n, int *lo, int *hi) {
  *lo = 2 * o - 1 < 0 ? 0 : 2 * o - 1;
  *hi = 2 * o + 1 > n - 1 ? n - 1 : 2 * o + 1;
}

/* forward: y = the window's mean of x; backward: each dy / window size added to the window of dx */
static void avgpool3(const double *in, int n, int c, int h, int w, int backward, double *out) {
  int oh = spx_avgpool3_out(h), ow = spx_avgpool3_out(w);
  for (int p = 0; p < n * c; p++)
    for (int oy = 0; oy < oh; oy++)
      for (int ox = 0; ox < ow; ox++) {
        int y0, y1, x0, x1;
        win(oy, h, &y0, &y1), win(ox, w, &x0, &x1);
        size_t o = ((size_t)p * oh + oy) * ow + ox;
        double s = 0, g = backward ? in[o] / ((y1 - y0 + 1) * (x1 - x0 + 1)) : 0;
        for (int iy = y0; iy <= y1; iy++)
          for (int ix = x0; ix <= x1; ix++) {
            size_t i = ((size_t)p * h + iy) * w + ix;
            if (backward) out[i] += g;
            else s += in[i];
          }
        if (!backward) out[o] = s / ((y1 - y0 + 1) * (x1 - x0 + 1));
      }
}

void spx_ref_avgpool3_forward(const double *x, int n, int c, int h, int w, double *y) { avgpool3(x, n, c, h, w, 0, y); }

void spx_ref_avgpool3_backward(const double *dy, int n, int c, int h, int w, double *dx) {
  avgpool3(dy, n, c, h, w, 1, dx);
}
