/* Bilinear x2 upsampling, PyTorch's F.interpolate(scale_factor=2, mode="bilinear") formulas for
 * align_corners true and false (CPU, float):
 *   align_corners:  src = scale * dst,                scale = (in - 1) / (out - 1)  (0 if out == 1)
 *   otherwise:      src = max(scale * (dst + 0.5) - 0.5, 0),  scale = 1 / 2
 *   i0 = min((int)src, in - 1), i1 = i0 + (i0 < in - 1), l1 = clamp(src - i0, 0, 1), l0 = 1 - l1
 *   y = l0h * (l0w * x[h0,w0] + l1w * x[h0,w1]) + l1h * (l0w * x[h1,w0] + l1w * x[h1,w1])
 * The scales are computed on the host (float) and passed in. Backward is a gather: each input
 * pixel sums the weighted dy of the output pixels that read it (rows 2i-1 .. 2i+3 cover every
 * reader for both modes, see lib/nn/upsample.c), so no atomics and deterministic results. */

static inline void spx_up_src(int d, int in, float scale, int align, int *i0, int *i1, float *l0, float *l1) {
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

/* Output (oy, ox) of the x2 upsampling of the h x w plane q: the one expression both forward
 * kernels use, so the fused spx_upcat_fwd is bit-identical to upsample -> pad -> concat. */
static inline float spx_up_at(__global const float *q, int h, int w, int oy, int ox, float sh, float sw, int align) {
  int h0, h1, w0, w1;
  float lh0, lh1, lw0, lw1;
  spx_up_src(oy, h, sh, align, &h0, &h1, &lh0, &lh1);
  spx_up_src(ox, w, sw, align, &w0, &w1, &lw0, &lw1);
  return lh0 * (lw0 * q[h0 * w + w0] + lw1 * q[h0 * w + w1]) + lh1 * (lw0 * q[h1 * w + w0] + lw1 * q[h1 * w + w1]);
}

/* range (ow, oh, planes) of the 2h x 2w output; output planes start ps apart at yo, rows rs
 * apart (the plain upsampling: ps = oh * ow, rs = ow; the fused up block writes its channels of
 * the concatenation in place, at the pad offset). */
__kernel void spx_upsample2x_fwd(__global const float *x, int xo, __global float *y, int yo, int h, int w, float sh,
                                 float sw, int align, int ps, int rs) {
  int oh = 2 * h, ow = 2 * w;
  int ox = get_global_id(0), oy = get_global_id(1), p = get_global_id(2);
  if (ox >= ow || oy >= oh) return;
  y[yo + p * ps + oy * rs + ox] = spx_up_at(x + xo + p * h * w, h, w, oy, ox, sh, sw, align);
}

/* The same outputs, CPU class (tunable ROW_VEC = 1): one work-item writes UP_V = 16 consecutive
 * columns of one output row for a block of `pb` planes. The row's and the 16 columns' source
 * indices and weights come from spx_up_src once per work-item, not once per output. Away from
 * the left and right edges, output column 2j reads input columns j-1, j and column 2j+1 reads
 * j, j+1 (both align_corners modes); where the computed indices follow that pattern, each plane
 * reads the 10 input floats of each source row once and the lanes take their columns by two
 * constant swizzles. Elsewhere (the first chunk of a row, the last, images narrower than 16
 * columns) each lane reads its own. Every lane evaluates spx_up_at's expression on the same
 * operands: bit-identical to spx_upsample2x_fwd. range (ceil(ow / UP_V), oh, ceil(planes / pb)). */
#define UP_V 16
__kernel void spx_upsample2x_fwd_rows(__global const float *x, int xo, __global float *y, int yo, int h, int w,
                                      float sh, float sw, int align, int ps, int rs, int planes, int pb) {
  const int oh = 2 * h, ow = 2 * w;
  const int ox0 = get_global_id(0) * UP_V, oy = get_global_id(1), p0 = get_global_id(2) * pb;
  if (ox0 >= ow || oy >= oh || p0 >= planes) return;
  const int p1 = min(p0 + pb, planes), n = min(UP_V, ow - ox0), hw = h * w;
  int h0, h1;
  float lh0, lh1;
  spx_up_src(oy, h, sh, align, &h0, &h1, &lh0, &lh1);
  int c0[UP_V], c1[UP_V];
  float a0[UP_V], a1[UP_V];
  const int s = ox0 / 2 - 1; /* the pattern's first input column */
  int fast = n == UP_V && s >= 0;
  for (int l = 0; l < n; l++) {
    spx_up_src(ox0 + l, w, sw, align, &c0[l], &c1[l], &a0[l], &a1[l]);
    fast &= c0[l] == s + (l + 1) / 2 && c1[l] == c0[l] + 1;
  }
  __global float *yr = y + yo + oy * rs + ox0;
  if (fast) {
    const float16 lw0 = vload16(0, a0), lw1 = vload16(0, a1);
    for (int p = p0; p < p1; p++) {
      __global const float *q0 = x + xo + p * hw + h0 * w + s, *q1 = x + xo + p * hw + h1 * w + s;
      const float16 r0 = (float16)(vload8(0, q0), vload2(0, q0 + 8), (float2)(0.0f), (float4)(0.0f));
      const float16 r1 = (float16)(vload8(0, q1), vload2(0, q1 + 8), (float2)(0.0f), (float4)(0.0f));
      const float16 v = lh0 * (lw0 * r0.s0112233445566778 + lw1 * r0.s1223344556677889) +
                        lh1 * (lw0 * r1.s0112233445566778 + lw1 * r1.s1223344556677889);
      vstore16(v, 0, yr + p * ps);
    }
  } else {
    for (int p = p0; p < p1; p++) {
      __global const float *q0 = x + xo + p * hw + h0 * w, *q1 = x + xo + p * hw + h1 * w;
      for (int l = 0; l < n; l++)
        yr[p * ps + l] = lh0 * (a0[l] * q0[c0[l]] + a1[l] * q0[c1[l]]) + lh1 * (a0[l] * q1[c0[l]] + a1[l] * q1[c1[l]]);
    }
  }
}

/* The zero border around the upsampled planes of the fused up block (pad > 0 only): the rows
 * outside [top, top + uh) (rows = 1, range (ow, oh - uh, planes)) or the columns outside
 * [left, left + uw) of the rows inside (rows = 0, range (ow - uw, uh, planes)) of the oh x ow
 * planes starting at oo. */
__kernel void spx_upcat_border(__global float *out, int oo, int oh, int ow, int top, int left, int uh, int uw,
                               int rows) {
  int i = get_global_id(0), j = get_global_id(1), p = get_global_id(2);
  int oy, ox;
  if (rows) {
    if (i >= ow || j >= oh - uh) return;
    oy = j < top ? j : j + uh, ox = i;
  } else {
    if (i >= ow - uw || j >= uh) return;
    oy = top + j, ox = i < left ? i : i + uw;
  }
  out[oo + (p * oh + oy) * ow + ox] = 0.0f;
}

/* weight with which output coordinate d reads input coordinate i */
static inline float spx_up_weight(int d, int i, int in, float scale, int align) {
  int i0, i1;
  float l0, l1;
  spx_up_src(d, in, scale, align, &i0, &i1, &l0, &l1);
  return (i0 == i ? l0 : 0.0f) + (i1 == i ? l1 : 0.0f);
}

/* The (at most 5) output coordinates 2i-1 .. 2i+3 that can read input coordinate i, with their
 * weights (0 for those that do not read it or lie outside): first one in *d0, weights in wt. */
static inline void spx_up_readers(int i, int in, int out, float scale, int align, int *d0, float *wt) {
  int a = 2 * i - 1;
  *d0 = a;
#pragma unroll
  for (int k = 0; k < 5; k++) {
    int d = a + k;
    wt[k] = (d >= 0 && d < out) ? spx_up_weight(d, i, in, scale, align) : 0.0f;
  }
}

/* Backward in two separable passes (the same sums, in the same order, as a fused 2-D gather:
 * each input pixel gets sum_a wy[a] * (sum_b wx[b] * dy[y0+a, x0+b])). Readers of input
 * coordinate i are output coordinates 2i-1 .. 2i+3 (lib/nn/upsample.c); their weights come from
 * per-axis tables tab[k * in + i] (k = 0..4) built once per call by spx_upsample2x_weights.
 * Branch-free: loads are at clamped (valid) indices and terms whose weight is 0 are replaced by 0
 * with a select (never 0 * dy, so an inf/NaN elsewhere cannot leak in). */

/* range (in): the reader weights of every input coordinate along one axis */
__kernel void spx_upsample2x_weights(__global float *tab, int to, int in, float scale, int align) {
  int i = SPX_GID0;
  if (i >= in) return;
  int d0;
  float wt[5];
  spx_up_readers(i, in, 2 * in, scale, align, &d0, wt);
  for (int k = 0; k < 5; k++) tab[to + k * in + i] = wt[k];
}

/* Pass 1, range (w, oh, planes): t[to + p, oy, ix] = sum_b wx[b] * dy[p, oy, 2ix - 1 + b]. dy's
 * planes start ps apart at go, rows rs apart (the plain upsampling: ps = oh * ow, rs = ow, all
 * samples in one launch; the fused up block reads its slice of the concatenated gradient in
 * place, one launch per sample). */
/* t's element of input column ix in dy row g (the work of one work-item of the pass). */
static inline float spx_up_bwd_row1(__global const float *g, __global const float *tab, int wxo, int w, int ix) {
  float row = 0.0f;
#pragma unroll
  for (int b = 0; b < 5; b++) {
    float wb = tab[wxo + b * w + ix], v = g[clamp(2 * ix - 1 + b, 0, 2 * w - 1)];
    row += wb != 0.0f ? wb * v : 0.0f;
  }
  return row;
}
/* dx's increment at (iy, ix) of plane p from the row-pass result t. */
static inline float spx_up_bwd_col1(__global const float *t, __global const float *tab, int wyo, int h, int w, int p, int iy,
                             int ix) {
  int oh = 2 * h;
  __global const float *q = t + p * oh * w + ix;
  float acc = 0.0f;
#pragma unroll
  for (int a = 0; a < 5; a++) {
    float wa = tab[wyo + a * h + iy], v = q[clamp(2 * iy - 1 + a, 0, oh - 1) * w];
    acc += wa != 0.0f ? wa * v : 0.0f;
  }
  return acc;
}

__kernel void spx_upsample2x_bwd_rows(__global const float *dy, int go, __global float *t, int to,
                                      __global const float *tab, int wxo, int h, int w, int ps, int rs) {
  int oh = 2 * h;
  int ix = get_global_id(0), oy = get_global_id(1), p = get_global_id(2);
  if (ix >= w || oy >= oh) return;
  t[to + (p * oh + oy) * w + ix] = spx_up_bwd_row1(dy + go + p * ps + oy * rs, tab, wxo, w, ix);
}

/* Pass 2, range (w, h, planes): dx[p, iy, ix] += sum_a wy[a] * t[p, 2iy - 1 + a, ix]. */
__kernel void spx_upsample2x_bwd_cols(__global const float *t, __global const float *tab, int wyo,
                                      __global float *dx, int xo, int h, int w) {
  int ix = get_global_id(0), iy = get_global_id(1), p = get_global_id(2);
  if (ix >= w || iy >= h) return;
  dx[xo + (p * h + iy) * w + ix] += spx_up_bwd_col1(t, tab, wyo, h, w, p, iy, ix);
}

/* The two passes, CPU class (tunable ROW_VEC = 1): 16 consecutive input columns per work-item,
 * the same terms in the same order lane by lane (same bits). Pass 1 reads the 36 dy elements
 * 2ix0-2 .. 2ix0+33 as six vectors and takes tap b of lane l (element 2(ix0+l)-1+b) by .odd /
 * .even; a chunk whose taps would be clamped (the first one, and those ending within 17 columns
 * of the right edge) goes lane by lane. Pass 2 loads its rows of t as vectors (the weights are
 * per row). Ranges (ceil(w / 16), oh or h, planes). */
__kernel void spx_upsample2x_bwd_rows_v(__global const float *dy, int go, __global float *t, int to,
                                        __global const float *tab, int wxo, int h, int w, int ps, int rs) {
  int oh = 2 * h;
  int ix0 = get_global_id(0) * 16, oy = get_global_id(1), p = get_global_id(2);
  if (ix0 >= w || oy >= oh) return;
  __global const float *g = dy + go + p * ps + oy * rs;
  __global float *tr = t + to + (p * oh + oy) * w;
  if (ix0 < 1 || ix0 + 17 > w) {
    for (int ix = ix0; ix < min(ix0 + 16, w); ix++) tr[ix] = spx_up_bwd_row1(g, tab, wxo, w, ix);
    return;
  }
  __global const float *b0 = g + 2 * ix0 - 2;
  const float16 l0 = vload16(0, b0), l1 = vload16(0, b0 + 16), m0 = vload16(0, b0 + 2), m1 = vload16(0, b0 + 18);
  const float16 n0 = vload16(0, b0 + 4), n1 = vload16(0, b0 + 20);
  const float16 v[5] = {(float16)(l0.odd, l1.odd), (float16)(m0.even, m1.even), (float16)(m0.odd, m1.odd),
                        (float16)(n0.even, n1.even), (float16)(n0.odd, n1.odd)};
  float16 row = (float16)0.0f;
#pragma unroll
  for (int b = 0; b < 5; b++) {
    const float16 wb = vload16(0, tab + wxo + b * w + ix0);
    row += select((float16)0.0f, wb * v[b], wb != 0.0f);
  }
  vstore16(row, 0, tr + ix0);
}

__kernel void spx_upsample2x_bwd_cols_v(__global const float *t, __global const float *tab, int wyo,
                                        __global float *dx, int xo, int h, int w) {
  int oh = 2 * h;
  int ix0 = get_global_id(0) * 16, iy = get_global_id(1), p = get_global_id(2);
  if (ix0 >= w || iy >= h) return;
  __global float *d = dx + xo + (p * h + iy) * w;
  if (ix0 + 16 > w) {
    for (int ix = ix0; ix < w; ix++) d[ix] += spx_up_bwd_col1(t, tab, wyo, h, w, p, iy, ix);
    return;
  }
  __global const float *q = t + p * oh * w + ix0;
  float16 acc = (float16)0.0f;
#pragma unroll
  for (int a = 0; a < 5; a++) {
    const float wa = tab[wyo + a * h + iy];
    const float16 v = vload16(0, q + clamp(2 * iy - 1 + a, 0, oh - 1) * w);
    acc += wa != 0.0f ? wa * v : (float16)0.0f;
  }
  vstore16(vload16(0, d + ix0) + acc, 0, d + ix0);
}
