/* 1x1 stride-1 pad-0 forward with at most CONV_THIN_MAXC (<= 8) output channels: the UNet's output
 * layer (64 -> 3). Bandwidth-bound (per pixel Cin loads, Cout stores, Cout*Cin fmas), so one
 * work-item per pixel keeps all Cout sums in registers and reads each input value once, the
 * loads of neighbouring work-items adjacent; the weights are the same for every work-item (one
 * broadcast load each). Host: lib/nn/conv2d_gemm.c (spx_conv2d_thin), tunable CONV_THIN_MAXC;
 * reference: lib/nn/conv2d_ref.c; test: tests/test_nn_conv2d_gemm.c. Sums over ci in order with
 * fma, then the epilogue of kernels/conv2d_common.h's conv_fwd_store. */
#include "conv2d_common.h"

#ifndef CONV_THIN_MAXC
#define CONV_THIN_MAXC 8
#endif
#define THIN_C (CONV_THIN_MAXC > 0 ? CONV_THIN_MAXC : 1)

/* x [N][Cin][hw] from x_off, w [Cout][Cin] from w_off, y [N][Cout][hw] from y_off. Global: (hw, N). */
__kernel void spx_conv2d_thin(const __global float *x, ulong x_off, const __global float *w, ulong w_off,
                              __global float *y, ulong y_off, const __global float *bias, ulong b_off,
                              const __global float *scale, ulong sc_off, const __global float *shift, ulong sh_off,
                              int Cin, int Cout, int hw, int flags) {
  const int p = (int)get_global_id(0), n = (int)get_global_id(1);
  if (p >= hw) return;
  const __global float *xc = x + x_off + (size_t)n * Cin * hw + p;
  const __global float *wc = w + w_off;
  float acc[THIN_C];
#pragma unroll
  for (int c = 0; c < THIN_C; c++) acc[c] = 0.0f;
  for (int ci = 0; ci < Cin; ci++) {
    const float v = xc[(size_t)ci * hw];
#pragma unroll
    for (int c = 0; c < THIN_C; c++) acc[c] = fma(wc[min(c, Cout - 1) * Cin + ci], v, acc[c]);
  }
  __global float *yp = y + y_off + (size_t)n * Cout * hw + p;
#pragma unroll
  for (int c = 0; c < THIN_C; c++) {
    if (c >= Cout) continue;
    float v = acc[c];
    if (flags & FL_ACCUM) v = yp[(size_t)c * hw] + v;
    if (flags & FL_BIAS) v = v + bias[b_off + c];
    if (flags & FL_SCALE) v = v * scale[sc_off + c] + ((flags & FL_SHIFT) ? shift[sh_off + c] : 0.0f);
    if (flags & FL_RELU) v = fmax(v, 0.0f);
    yp[(size_t)c * hw] = v;
  }
}
