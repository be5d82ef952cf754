/* Plain-C double-precision reference of the 2-D convolution (lib/nn/conv2d.h). Direct loops,
 * written for clarity; the device kernels in kernels/conv2d.cl are tested against these. */
#include "nn/conv2d.h"

/* One pass over every output pixel (n, co, oy, ox) and its taps (ci, ky, kx) inside the image, in
 * that order. Forward (dy NULL): y = act(scale * (bias + sum w * x) + shift). Backward: db, dw and
 * dx (each optional) accumulate dy's share. */
static void ref_conv2d(const spx_conv2d_shape *s, const double *x, const double *w, const double *bias,
                       const double *scale, const double *shift, int relu, double *y, const double *dy, double *dx,
                       double *dw, double *db) {
  int ho = spx_conv2d_out_size(s->h, s->k, s->stride, s->pad);
  int wo = spx_conv2d_out_size(s->w, s->k, s->stride, s->pad);
  int k = s->k;
  for (int n = 0; n < s->n; n++)
    for (int co = 0; co < s->cout; co++)
      for (int oy = 0; oy < ho; oy++)
        for (int ox = 0; ox < wo; ox++) {
          size_t yi = (((size_t)n * s->cout + co) * ho + oy) * wo + ox;
          double acc = bias ? bias[co] : 0.0, g = dy ? dy[yi] : 0.0;
          if (dy && db) db[co] += g;
          for (int ci = 0; ci < s->cin; ci++)
            for (int ky = 0; ky < k; ky++) {
              int iy = oy * s->stride + ky - s->pad;
              if (iy < 0 || iy >= s->h) continue;
              for (int kx = 0; kx < k; kx++) {
                int ix = ox * s->stride + kx - s->pad;
                if (ix < 0 || ix >= s->w) continue;
                size_t wi = ((size_t)(co * s->cin + ci) * k + ky) * k + kx;
                size_t xi = (((size_t)n * s->cin + ci) * s->h + iy) * s->w + ix;
                if (!dy) acc += w[wi] * x[xi];
                if (dy && dw) dw[wi] += g * x[xi];
                if (dy && dx) dx[xi] += g * w[wi];
              }
            }
          if (dy) continue;
          if (scale) acc = acc * scale[co] + (shift ? shift[co] : 0.0);
          if (relu && acc < 0) acc = 0;
          y[yi] = acc;
        }
}

void spx_ref_conv2d_forward(const spx_conv2d_shape *s, const double *x, const double *w, const double *bias,
                            const double *scale, const double *shift, int relu, double *y) {
  ref_conv2d(s, x, w, bias, scale, shift, relu, y, NULL, NULL, NULL, NULL);
}

void spx_ref_conv2d_backward(const spx_conv2d_shape *s, const double *x, const double *w, const double *dy,
                             double *dx, double *dw, double *db) {
  ref_conv2d(s, x, w, NULL, NULL, NULL, 0, NULL, dy, dx, dw, db);
}
