/* Bilinear x2 upsampling, PyTorch's F.interpolate(scale_factor=2, mode="bilinear") formulas for
 * align_corners true and false (CPU, float):
 *   align_corners:  src = scale * dst,                scale = (in - 1) / (out - 1)  (0 if out == 1)
 *   otherwise:      src = max(scale * (dst + 0.5) - 0.5, 0),  scale = 1 / 2
 *   i0 = min((int)src, in - 1), i1 = i0 + (i0 < in - 1), l1 = clamp(src - i0, 0, 1), l0 = 1 - l1
 *   y = l0h * (l0w * x[h0,w0] + l1w * x[h0,w1]) + l1h * (l0w * x[h1,w0] + l1w * x[h1,w1])
 * The scales are computed on the host (float) and passed in. Backward is a gather: each input
 * pixel sums the weighted dy of the output pixels that read it (rows 2i-4 .. 2i+5 cover every
 * reader for both modes, see lib/nn/upsample.c), so no atomics and deterministic results. */

inline void spx_up_src(int d, int in, float scale, int align, int *i0, int *i1, float *l0, float *l1) {
  float s = align ? scale * (float)d : scale * ((float)d + 0.5f) - 0.5f;
  if (s < 0.0f) s = 0.0f;
  int a = (int)s;
  if (a > in - 1) a = in - 1;
  *i0 = a;
  *i1 = a + (a < in - 1 ? 1 : 0);
  float l = s - (float)a;
  l = l < 0.0f ? 0.0f : (l > 1.0f ? 1.0f : l);
  *l1 = l;
  *l0 = 1.0f - l;
}

__kernel void spx_upsample2x_fwd(__global const float *x, int xo, __global float *y, int yo, int nc, int h, int w,
                                 float sh, float sw, int align) {
  int oh = 2 * h, ow = 2 * w;
  int i = SPX_GID0;
  if (i >= nc * oh * ow) return;
  int ox = i % ow, oy = (i / ow) % oh, p = i / (ow * oh);
  int h0, h1, w0, w1;
  float lh0, lh1, lw0, lw1;
  spx_up_src(oy, h, sh, align, &h0, &h1, &lh0, &lh1);
  spx_up_src(ox, w, sw, align, &w0, &w1, &lw0, &lw1);
  __global const float *q = x + xo + p * h * w;
  y[yo + i] = lh0 * (lw0 * q[h0 * w + w0] + lw1 * q[h0 * w + w1]) + lh1 * (lw0 * q[h1 * w + w0] + lw1 * q[h1 * w + w1]);
}

/* weight with which output coordinate d reads input coordinate i */
inline float spx_up_weight(int d, int i, int in, float scale, int align) {
  int i0, i1;
  float l0, l1;
  spx_up_src(d, in, scale, align, &i0, &i1, &l0, &l1);
  return (i0 == i ? l0 : 0.0f) + (i1 == i ? l1 : 0.0f);
}

__kernel void spx_upsample2x_bwd(__global const float *dy, int go, __global float *dx, int xo, int nc, int h, int w,
                                 float sh, float sw, int align) {
  int oh = 2 * h, ow = 2 * w;
  int i = SPX_GID0;
  if (i >= nc * h * w) return;
  int ix = i % w, iy = (i / w) % h, p = i / (w * h);
  int ya = max(0, 2 * iy - 4), yb = min(oh - 1, 2 * iy + 5);
  int xa = max(0, 2 * ix - 4), xb = min(ow - 1, 2 * ix + 5);
  float wx[10];
  for (int ox = xa; ox <= xb; ox++) wx[ox - xa] = spx_up_weight(ox, ix, w, sw, align);
  __global const float *g = dy + go + p * oh * ow;
  float acc = 0.0f;
  for (int oy = ya; oy <= yb; oy++) {
    float wy = spx_up_weight(oy, iy, h, sh, align);
    if (wy == 0.0f) continue;
    float row = 0.0f;
    for (int ox = xa; ox <= xb; ox++)
      if (wx[ox - xa] != 0.0f) row += wx[ox - xa] * g[oy * ow + ox];
    acc += wy * row;
  }
  dx[xo + i] += acc;
}
