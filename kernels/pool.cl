/* Max pool 2x2, stride 2, floor mode (odd sizes drop the last row / column), like
 * F.max_pool2d(x, 2). The argmax is the FIRST maximum in row-major window order, NaN wins
 * (PyTorch's CPU rule `val > max || isnan(val)`). Backward recomputes the argmax from x instead
 * of storing indices; windows do not overlap, so one work-item per window owns its four dx
 * elements: no atomics, deterministic. */

/* 0..3: position of the argmax in the 2x2 window whose top-left is p. */
static inline int spx_pool_argmax(__global const float *p, int w) {
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

/* The value of spx_pool_argmax's element of the window whose top-left is q, branch-free (the
 * same comparisons in the same order: the first maximum, NaN wins). */
static inline float spx_pool_max(__global const float *q, int w) {
  float m = q[0], v = q[1];
  m = (v > m || isnan(v)) ? v : m;
  v = q[w];
  m = (v > m || isnan(v)) ? v : m;
  v = q[w + 1];
  return (v > m || isnan(v)) ? v : m;
}

/* range (ow, oh, planes): one work-item per window. */
__kernel void spx_maxpool_fwd(__global const float *x, int xo, __global float *y, int yo, int h, int w) {
  int oh = h / 2, ow = w / 2;
  int ox = get_global_id(0), oy = get_global_id(1), p = get_global_id(2);
  if (ox >= ow || oy >= oh) return;
  y[yo + (p * oh + oy) * ow + ox] = spx_pool_max(x + xo + (p * h + 2 * oy) * w + 2 * ox, w);
}

/* The same outputs, CPU class (tunable ROW_VEC = 1): 16 windows of one row per work-item from
 * two 16-float loads of each source row, the same comparisons lane by lane (NaN wins, the first
 * maximum). The last chunk of a row when ow is not a multiple of 16 goes window by window.
 * range (ceil(ow / 16), oh, planes). */
__kernel void spx_maxpool_fwd_rows(__global const float *x, int xo, __global float *y, int yo, int h, int w) {
  int oh = h / 2, ow = w / 2;
  int ox0 = get_global_id(0) * 16, oy = get_global_id(1), p = get_global_id(2);
  if (ox0 >= ow || oy >= oh) return;
  __global const float *q = x + xo + (p * h + 2 * oy) * w + 2 * ox0;
  __global float *yr = y + yo + (p * oh + oy) * ow + ox0;
  if (ox0 + 16 > ow) {
    for (int l = 0; l < ow - ox0; l++) yr[l] = spx_pool_max(q + 2 * l, w);
    return;
  }
  const float16 a0 = vload16(0, q), a1 = vload16(0, q + 16), b0 = vload16(0, q + w), b1 = vload16(0, q + w + 16);
  float16 m = (float16)(a0.even, a1.even), v = (float16)(a0.odd, a1.odd);
  m = select(m, v, (v > m) | isnan(v));
  v = (float16)(b0.even, b1.even);
  m = select(m, v, (v > m) | isnan(v));
  v = (float16)(b0.odd, b1.odd);
  m = select(m, v, (v > m) | isnan(v));
  vstore16(m, 0, yr);
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

/* The same gradients, CPU class (tunable ROW_VEC = 1): 16 windows of one row per work-item. The
 * argmax of each lane is found by spx_pool_max's comparisons in its order (the first maximum,
 * NaN wins); each of the window's four dx elements gets dy where it is the argmax and keeps its
 * bits elsewhere (a select, not + 0). The last chunk of a row when ow is not a multiple of 16
 * goes window by window. range (ceil(ow / 16), oh, planes). */
__kernel void spx_maxpool_bwd_rows(__global const float *x, int xo, __global const float *dy, int go,
                                   __global float *dx, int dxo, int h, int w) {
  int oh = h / 2, ow = w / 2;
  int ox0 = get_global_id(0) * 16, oy = get_global_id(1), p = get_global_id(2);
  if (ox0 >= ow || oy >= oh) return;
  const int base = (p * h + 2 * oy) * w + 2 * ox0;
  __global const float *g = dy + go + (p * oh + oy) * ow + ox0;
  if (ox0 + 16 > ow) {
    for (int l = 0; l < ow - ox0; l++) {
      int a = spx_pool_argmax(x + xo + base + 2 * l, w);
      dx[dxo + base + 2 * l + (a >> 1) * w + (a & 1)] += g[l];
    }
    return;
  }
  __global const float *q = x + xo + base;
  const float16 a0 = vload16(0, q), a1 = vload16(0, q + 16), b0 = vload16(0, q + w), b1 = vload16(0, q + w + 16);
  float16 m = (float16)(a0.even, a1.even), v = (float16)(a0.odd, a1.odd);
  int16 k = (int16)0, c = (v > m) | isnan(v);
  m = select(m, v, c), k = select(k, (int16)1, c);
  v = (float16)(b0.even, b1.even);
  c = (v > m) | isnan(v);
  m = select(m, v, c), k = select(k, (int16)2, c);
  v = (float16)(b0.odd, b1.odd);
  c = (v > m) | isnan(v);
  k = select(k, (int16)3, c);
  const float16 gv = vload16(0, g);
  /* window l's elements are lanes 2l (left) and 2l + 1 (right) of the row's 32 floats */
  const int16 par = (int16)(0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1);
  const int16 klo = k.s0011223344556677, khi = k.s8899aabbccddeeff;
  const float16 glo = gv.s0011223344556677, ghi = gv.s8899aabbccddeeff;
  for (int r = 0; r < 2; r++) {
    __global float *d = dx + dxo + base + r * w;
    float16 lo = vload16(0, d), hi = vload16(0, d + 16);
    lo = select(lo, lo + glo, klo == par + 2 * r);
    hi = select(hi, hi + ghi, khi == par + 2 * r);
    vstore16(lo, 0, d);
    vstore16(hi, 0, d + 16);
  }
}

/* Average pool 3x3, stride 2, padding 1, count_include_pad = False (nn.AvgPool2d(3, 2, 1,
 * count_include_pad=False)): output (oy, ox) averages rows 2oy-1..2oy+1 and columns 2ox-1..2ox+1
 * clipped to the image. */
static inline int spx_avg_count(int o, int n) { return min(2 * o + 1, n - 1) - max(2 * o - 1, 0) + 1; }

/* range (ow, oh, planes) */
__kernel void spx_avgpool3_fwd(__global const float *x, int xo, __global float *y, int yo, int h, int w) {
  int oh = (h - 1) / 2 + 1, ow = (w - 1) / 2 + 1;
  int ox = get_global_id(0), oy = get_global_id(1), p = get_global_id(2);
  if (ox >= ow || oy >= oh) return;
  int y0 = max(2 * oy - 1, 0), y1 = min(2 * oy + 1, h - 1), x0 = max(2 * ox - 1, 0), x1 = min(2 * ox + 1, w - 1);
  float s = 0.0f;
  for (int iy = y0; iy <= y1; iy++)
    for (int ix = x0; ix <= x1; ix++) s += x[xo + (p * h + iy) * w + ix];
  y[yo + (p * oh + oy) * ow + ox] = s / (float)((y1 - y0 + 1) * (x1 - x0 + 1));
}

/* range (w, h, planes): one work-item per INPUT element gathers dy / count of the (at most 2x2)
 * outputs whose window holds it, in a fixed order; no atomics. */
__kernel void spx_avgpool3_bwd(__global const float *dy, int go, __global float *dx, int dxo, int h, int w) {
  int oh = (h - 1) / 2 + 1, ow = (w - 1) / 2 + 1;
  int ix = get_global_id(0), iy = get_global_id(1), p = get_global_id(2);
  if (ix >= w || iy >= h) return;
  int oy0 = iy / 2, oy1 = min((iy + 1) / 2, oh - 1), ox0 = ix / 2, ox1 = min((ix + 1) / 2, ow - 1);
  float s = 0.0f;
  for (int oy = oy0; oy <= oy1; oy++)
    for (int ox = ox0; ox <= ox1; ox++)
      s += dy[go + (p * oh + oy) * ow + ox] / (float)(spx_avg_count(oy, h) * spx_avg_count(ox, w));
  dx[dxo + (p * h + iy) * w + ix] += s;
}
