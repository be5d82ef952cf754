/* Max pool 2x2, stride 2, floor mode (odd sizes drop the last row / column), like
 * F.max_pool2d(x, 2). The argmax is the FIRST maximum in row-major window order, NaN wins
 * (PyTorch's CPU rule `val > max || isnan(val)`). Backward recomputes the argmax from x instead
 * of storing indices and gathers: each input element adds dout of its window if it is the argmax,
 * so there are no atomics and results are deterministic. */

/* 0..3: position of the argmax in the 2x2 window whose top-left is p. */
inline int spx_pool_argmax(__global const float *p, int w) {
  float v[4] = {p[0], p[1], p[w], p[w + 1]};
  float m = -INFINITY;
  int a = 0;
  for (int k = 0; k < 4; k++)
    if (v[k] > m || isnan(v[k])) {
      m = v[k];
      a = k;
    }
  return a;
}

__kernel void spx_maxpool_fwd(__global const float *x, int xo, __global float *y, int yo, int nc, int h, int w) {
  int oh = h / 2, ow = w / 2;
  int i = SPX_GID0;
  if (i >= nc * oh * ow) return;
  int ox = i % ow, oy = (i / ow) % oh, p = i / (ow * oh);
  __global const float *q = x + xo + (p * h + 2 * oy) * w + 2 * ox;
  int a = spx_pool_argmax(q, w);
  y[yo + i] = q[(a >> 1) * w + (a & 1)];
}

/* one work-item per dx element */
__kernel void spx_maxpool_bwd(__global const float *x, int xo, __global const float *dy, int go, __global float *dx,
                              int dxo, int nc, int h, int w) {
  int oh = h / 2, ow = w / 2;
  int i = SPX_GID0;
  if (i >= nc * h * w) return;
  int ix = i % w, iy = (i / w) % h, p = i / (w * h);
  int oy = iy >> 1, ox = ix >> 1;
  if (oy >= oh || ox >= ow) return; /* dropped by floor mode */
  int a = spx_pool_argmax(x + xo + (p * h + 2 * oy) * w + 2 * ox, w);
  if (a == ((iy & 1) << 1 | (ix & 1))) dx[dxo + i] += dy[go + (p * oh + oy) * ow + ox];
}
