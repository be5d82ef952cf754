/* Image layout conversions between the file layout (HWC, one image after another) and the
 * network layout (NCHW). One work-item per element of the destination. */

__kernel void spx_hwc_to_nchw(__global const float *src, __global float *dst, int n, int c, int h, int w) {
  int i = SPX_GID0;
  int total = n * c * h * w;
  if (i >= total) return;
  int x = i % w, y = (i / w) % h, ch = (i / (w * h)) % c, b = i / (w * h * c);
  dst[i] = src[((b * h + y) * w + x) * c + ch];
}

__kernel void spx_nchw_to_hwc(__global const float *src, __global float *dst, int n, int c, int h, int w) {
  int i = SPX_GID0;
  int total = n * c * h * w;
  if (i >= total) return;
  int ch = i % c, x = (i / c) % w, y = (i / (c * w)) % h, b = i / (c * w * h);
  dst[i] = src[((b * c + ch) * h + y) * w + x];
}
