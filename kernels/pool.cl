/* Max pool 2x2, stride 2, floor mode (odd sizes drop the last row / column), like
 * F.max_pool2d(x, 2). The argmax is the FIRST maximum in row-major window order, NaN wins
 * (PyTorch's CPU rule `val > max || isnan(val)`). Backward recomputes the argmax from x instead
 * of storing indices; windows do not overlap, so one work-item per window owns its four dx
 * elements: no atomics, deterministic. */

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

/* range (ow, oh, planes) */
__kernel void spx_maxpool_fwd(__global const float *x, int xo, __global float *y, int yo, int h, int w) {
  int oh = h / 2, ow = w / 2;
  int ox = get_global_id(0), oy = get_global_id(1), p = get_global_id(2);
  if (ox >= ow || oy >= oh) return;
  __global const float *q = x + xo + (p * h + 2 * oy) * w + 2 * ox;
  int a = spx_pool_argmax(q, w);
  y[yo + (p * oh + oy) * ow + ox] = q[(a >> 1) * w + (a & 1)];
}

/* range (ow, oh, planes): one work-item per window adds dy to the argmax element of its window.
 * Windows do not overlap (stride 2), so every dx element has at most one writer: no atomics. */
__kernel void spx_maxpool_bwd(__global const float *x, int xo, __global const float *dy, int go, __global float *dx,
                              int dxo, int h, int w) {
  int oh = h / 2, ow = w / 2;
  int ox = get_global_id(0), oy = get_global_id(1), p = get_global_id(2);
  if (ox >= ow || oy >= oh) return;
  int base = (p * h + 2 * oy) * w + 2 * ox;
  int a = spx_pool_argmax(x + xo + base, w);
  dx[dxo + base + (a >> 1) * w + (a & 1)] += dy[go + (p * oh + oy) * ow + ox];
}
