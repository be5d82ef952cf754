/* Plain-C double references for kernels/tensor_ops.cl (pad/crop, concat). */
#include "nn/tensor_ops.h"

void spx_ref_pad_forward(const double *x, int n, int c, int h, int w, int left, int right, int top, int bottom,
                         double *out) {
  int oh = h + top + bottom, ow = w + left + right;
  for (int p = 0; p < n * c; p++)
    for (int oy = 0; oy < oh; oy++)
      for (int ox = 0; ox < ow; ox++) {
        int iy = oy - top, ix = ox - left;
        out[((size_t)p * oh + oy) * ow + ox] =
            (iy >= 0 && iy < h && ix >= 0 && ix < w) ? x[((size_t)p * h + iy) * w + ix] : 0.0;
      }
}

void spx_ref_pad_backward(const double *dout, int n, int c, int h, int w, int left, int right, int top, int bottom,
                          double *dx) {
  int oh = h + top + bottom, ow = w + left + right;
  for (int p = 0; p < n * c; p++)
    for (int oy = 0; oy < oh; oy++)
      for (int ox = 0; ox < ow; ox++) {
        int iy = oy - top, ix = ox - left;
        if (iy >= 0 && iy < h && ix >= 0 && ix < w) dx[((size_t)p * h + iy) * w + ix] += dout[((size_t)p * oh + oy) * ow + ox];
      }
}

void spx_ref_concat_forward(const double *a, const double *b, int n, int ca, int cb, int hw, double *out) {
  for (int k = 0; k < n; k++) {
    for (int ch = 0; ch < ca; ch++)
      for (int s = 0; s < hw; s++) out[((size_t)k * (ca + cb) + ch) * hw + s] = a[((size_t)k * ca + ch) * hw + s];
    for (int ch = 0; ch < cb; ch++)
      for (int s = 0; s < hw; s++) out[((size_t)k * (ca + cb) + ca + ch) * hw + s] = b[((size_t)k * cb + ch) * hw + s];
  }
}

void spx_ref_concat_backward(const double *dout, int n, int ca, int cb, int hw, double *da, double *db) {
  for (int k = 0; k < n; k++) {
    if (da)
      for (int ch = 0; ch < ca; ch++)
        for (int s = 0; s < hw; s++) da[((size_t)k * ca + ch) * hw + s] += dout[((size_t)k * (ca + cb) + ch) * hw + s];
    if (db)
      for (int ch = 0; ch < cb; ch++)
        for (int s = 0; s < hw; s++)
          db[((size_t)k * cb + ch) * hw + s] += dout[((size_t)k * (ca + cb) + ca + ch) * hw + s];
  }
}
