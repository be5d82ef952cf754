/* Kernels of lib/metrics (LPIPS's AlexNet): max pooling 3x3, stride 2, no padding, floor mode, like
 * torch.nn.MaxPool2d(kernel_size=3, stride=2). Windows overlap, so this is forward only (LPIPS
 * needs no gradients). NaN wins, as in PyTorch. Reference: lib/metrics/lpips_ref.c. */

/* range (ow, oh, planes) */
__kernel void spx_metrics_maxpool3s2(__global const float *x, int xo, __global float *y, int yo, int h, int w, int oh,
                                     int ow) {
  int ox = get_global_id(0), oy = get_global_id(1), p = get_global_id(2);
  if (ox >= ow || oy >= oh) return;
  __global const float *q = x + xo + (p * h + 2 * oy) * w + 2 * ox;
  float m = -INFINITY;
  for (int ky = 0; ky < 3; ky++)
    for (int kx = 0; kx < 3; kx++) {
      float v = q[ky * w + kx];
      if (v > m || isnan(v)) m = v;
    }
  y[yo + (p * oh + oy) * ow + ox] = m;
}
