/* Plain-C double references for kernels/tensor_ops.cl (pad/crop, concat). */
#include "nn/tensor_ops.h"

/* forward: out = x padded with zeros; backward: dx += the interior of dout (in = dout, out = dx) */
static void pad(const double *in, int n, int c, int h, int w, int left, int right, int top, int bottom, int backward,
                double *out) {
  int oh = h + top + bottom, ow = w + left + right;
  for (int p = 0; p < n * c; p++)
    for (int oy = 0; oy < oh; oy++)
      for (int ox = 0; ox < ow; ox++) {
        int iy = oy - top, ix = ox - left, inside = iy >= 0 && iy < h && ix >= 0 && ix < w;
        size_t i = ((size_t)p * h + iy) * w + ix, o = ((size_t)p * oh + oy) * ow + ox;
        if (!backward) out[o] = inside ? in[i] : 0.0;
        else if (inside) out[i] += in[o];
      }
}

void spx_ref_pad_forward(const double *x, int n, int c, int h, int w, int left, int right, int top, int bottom,
                         double *out) {
  pad(x, n, c, h, w, left, right, top, bottom, 0, out);
}

void spx_ref_pad_backward(const double *dout, int n, int c, int h, int w, int left, int right, int top, int bottom,
                          double *dx) {
  pad(dout, n, c, h, w, left, right, top, bottom, 1, dx);
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
