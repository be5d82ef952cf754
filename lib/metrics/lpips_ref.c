/* Plain-C double reference of kernels/metrics.cl (lib/metrics/metrics_internal.h). */
#include <math.h>

#include "metrics/metrics_internal.h"

void spx_ref_maxpool3s2_forward(const double *x, int planes, int h, int w, double *y) {
  int oh = spx_maxpool3s2_out(h), ow = spx_maxpool3s2_out(w);
  for (int p = 0; p < planes; p++)
    for (int oy = 0; oy < oh; oy++)
      for (int ox = 0; ox < ow; ox++) {
        const double *q = x + ((size_t)p * (size_t)h + (size_t)(2 * oy)) * (size_t)w + (size_t)(2 * ox);
        double m = -INFINITY;
        for (int ky = 0; ky < 3; ky++)
          for (int kx = 0; kx < 3; kx++) {
            double v = q[ky * w + kx];
            if (v > m || isnan(v)) m = v;
          }
        y[((size_t)p * (size_t)oh + (size_t)oy) * (size_t)ow + (size_t)ox] = m;
      }
}
