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

/* The indexed kernels below run on a 3-D range (x, y, plane) (lib/nn/nn_internal.h
 * spx_nn_run3d), so no work-item divides. */

/* out[p, oy, ox] = x[p, oy - top, ox - left] or 0 outside x; one work-item per out element. */
__kernel void spx_pad_fwd(__global const float *x, int xo, __global float *out, int oo, int h, int w, int oh, int ow,
                          int left, int top) {
  int ox = get_global_id(0), oy = get_global_id(1), p = get_global_id(2);
  if (ox >= ow || oy >= oh) return;
  int iy = oy - top, ix = ox - left;
  out[oo + (p * oh + oy) * ow + ox] = (iy >= 0 && iy < h && ix >= 0 && ix < w) ? x[xo + (p * h + iy) * w + ix] : 0.0f;
}

/* dx[p, iy, ix] += dout[p, iy + top, ix + left] where that is inside dout (gather: one
 * work-item per dx element). */
__kernel void spx_pad_bwd(__global const float *dout, int go, __global float *dx, int xo, int h, int w, int oh, int ow,
                          int left, int top) {
  int ix = get_global_id(0), iy = get_global_id(1), p = get_global_id(2);
  if (ix >= w || iy >= h) return;
  int oy = iy + top, ox = ix + left;
  if (oy >= 0 && oy < oh && ox >= 0 && ox < ow) dx[xo + (p * h + iy) * w + ix] += dout[go + (p * oh + oy) * ow + ox];
}

/* dst (n x cd x hw) += channels [c0, c0 + cd) of src (n x cs x hw): the backward of concat. */
__kernel void spx_channel_slice_acc(__global const float *src, int so, __global float *dst, int dsto, int cs, int c0,
                                    int cd, int hw) {
  int s = get_global_id(0), ch = get_global_id(1), k = get_global_id(2);
  if (s >= hw || ch >= cd) return;
  dst[dsto + (k * cd + ch) * hw + s] += src[so + (k * cs + c0 + ch) * hw + s];
}

/* dst (n x cd x hw) channels [c0, c0 + cs) = src (n x cs x hw): one half of concat forward. */
__kernel void spx_channel_place(__global const float *src, int so, __global float *dst, int dsto, int cs, int c0,
                                int cd, int hw) {
  int s = get_global_id(0), ch = get_global_id(1), k = get_global_id(2);
  if (s >= hw || ch >= cs) return;
  dst[dsto + (k * cd + c0 + ch) * hw + s] = src[so + (k * cs + ch) * hw + s];
}
