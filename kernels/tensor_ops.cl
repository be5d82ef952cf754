/* Elementwise helpers, zero pad / crop (F.pad with per-side amounts, negative = crop) and
 * channel concat / split. One work-item per destination element; no atomics anywhere.
 * Host side: lib/nn/tensor_ops.c; reference: lib/nn/tensor_ops_ref.c. */

__kernel void spx_copy(__global const float *x, int xo, __global float *y, int yo, int n) {
  int i = SPX_GID0;
  if (i < n) y[yo + i] = x[xo + i];
}

/* y += alpha * x */
__kernel void spx_axpy(__global const float *x, int xo, __global float *y, int yo, float alpha, int n) {
  int i = SPX_GID0;
  if (i < n) y[yo + i] += alpha * x[xo + i];
}

/* x *= alpha */
__kernel void spx_scale(__global float *x, int xo, float alpha, int n) {
  int i = SPX_GID0;
  if (i < n) x[xo + i] *= alpha;
}

/* out = a + b */
__kernel void spx_add(__global const float *a, int ao, __global const float *b, int bo, __global float *out, int oo,
                      int n) {
  int i = SPX_GID0;
  if (i < n) out[oo + i] = a[ao + i] + b[bo + i];
}

/* out[nc, oy, ox] = x[nc, oy - top, ox - left] or 0 outside x; out is nc x oh x ow. */
__kernel void spx_pad_fwd(__global const float *x, int xo, __global float *out, int oo, int nc, int h, int w, int oh,
                          int ow, int left, int top) {
  int i = SPX_GID0;
  if (i >= nc * oh * ow) return;
  int ox = i % ow, oy = (i / ow) % oh, p = i / (ow * oh);
  int iy = oy - top, ix = ox - left;
  out[oo + i] = (iy >= 0 && iy < h && ix >= 0 && ix < w) ? x[xo + (p * h + iy) * w + ix] : 0.0f;
}

/* dx[nc, iy, ix] += dout[nc, iy + top, ix + left] where that is inside dout (gather: one
 * work-item per dx element). */
__kernel void spx_pad_bwd(__global const float *dout, int go, __global float *dx, int xo, int nc, int h, int w, int oh,
                          int ow, int left, int top) {
  int i = SPX_GID0;
  if (i >= nc * h * w) return;
  int ix = i % w, iy = (i / w) % h, p = i / (w * h);
  int oy = iy + top, ox = ix + left;
  if (oy >= 0 && oy < oh && ox >= 0 && ox < ow) dx[xo + i] += dout[go + (p * oh + oy) * ow + ox];
}

/* out = [a, b] along channels: a is n x ca x hw, b is n x cb x hw. */
__kernel void spx_concat_fwd(__global const float *a, int ao, __global const float *b, int bo, __global float *out,
                             int oo, int n, int ca, int cb, int hw) {
  int i = SPX_GID0;
  int c = ca + cb;
  if (i >= n * c * hw) return;
  int s = i % hw, ch = (i / hw) % c, k = i / (hw * c);
  out[oo + i] = ch < ca ? a[ao + (k * ca + ch) * hw + s] : b[bo + (k * cb + ch - ca) * hw + s];
}

/* dst (n x cd x hw) += channels [c0, c0 + cd) of src (n x cs x hw): the backward of concat. */
__kernel void spx_channel_slice_acc(__global const float *src, int so, __global float *dst, int dsto, int n, int cs,
                                    int c0, int cd, int hw) {
  int i = SPX_GID0;
  if (i >= n * cd * hw) return;
  int s = i % hw, ch = (i / hw) % cd, k = i / (hw * cd);
  dst[dsto + i] += src[so + (k * cs + c0 + ch) * hw + s];
}
