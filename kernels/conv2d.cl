/* 2-D convolution as an implicit GEMM (host side: lib/nn/conv2d_direct.c; reference: lib/nn/conv2d_ref.c).
 *
 * Programs (split so that a command compiles only what it runs; each forward variant costs ~0.5 s
 * of PoCL compile, the backward kernels ~2 s): this file holds the stride-1 3x3 and 1x1 forwards
 * (every convolution of the UNet, and its backward data) and the pad / pack helpers;
 * conv2d_strided.cl the other forwards (generic k, stride 2, any stride); conv2d_bwd.cl the
 * weight and bias gradients; conv2d_common.h the code they share.
 *
 * The input is first copied into a zero-padded scratch `xp` ([N][C][Hp][Wp] plus a guard of
 * zeros). Outputs are computed on a "virtual grid": q = oy*Wp + ox with ox running over the
 * whole padded width, so that for every (ci, ky, kx) the input of output q sits at
 *     xp[ci*plane + S*q + ky*Wp + kx]
 * i.e. consecutive q read consecutive (S = 1) or evenly strided (S = 2) floats: no bounds tests
 * in the inner loop, contiguous vector loads. Columns ox >= Wo are computed and dropped.
 *
 * Register tiling: a work-item owns CONV_TM output channels x CONV_TN vectors of CONV_VW
 * pixels (CPU: explicit float16 vectors = one AVX-512 register each; GPU: CONV_VW = 1 and the
 * CONV_LWS work-items of a group take interleaved pixels so loads coalesce), for CONV_CT such
 * channel tiles walked in blocks of CONV_CB input channels (cache blocking). Weights are
 * pre-packed per channel tile as wpk[tile][kk][TM] (kk = (ci*k+ky)*k+kx): the TM weights of one
 * step are adjacent and a work-item's panel is contiguous. Tunables: lib/cl/tuning.c.
 *
 * Backward data = this same forward kernel on dy dilated by the stride and padded by k-1-pad,
 * with weights flipped and transposed (spx_conv2d_pack flip=1), accumulating into dx.
 * Backward weights = GEMM over (n, q) with the reduction split into fixed chunks (partials,
 * then a fixed-order sum): no atomics, bit-identical every run.
 *
 * Winograd F(4x4,3x3) for 3x3 stride-1 layers: kernels/conv2d_winograd.cl (inference by default).
 * GPU-class devices (CONV_LDS) run the 3x3 stride-1 forward from local-memory tiles instead:
 * kernels/conv2d_lds.cl (same arguments, same summation order, bit-identical results).
 * Layers with few output channels (CONV_NARROW_MAXC) take the same kernels compiled with a
 * narrower, longer register tile: kernels/conv2d_narrow.cl (bit-identical results).
 * With CONV_NOPAD (CPU class) the stride-1 3x3 pad-1 and 1x1 pad-0 forwards and their data
 * gradients skip the padded copy and read the input itself: kernels/conv2d_nopad.h (same bits). */
#include "conv2d_common.h"

__kernel void spx_conv2d_fwd_k3s1(CONV_FWD_ARGS) { conv_fwd(CONV_FWD_PASS, 1, 3); }
__kernel void spx_conv2d_fwd_k1s1(CONV_FWD_ARGS) { conv_fwd(CONV_FWD_PASS, 1, 1); }

/* Copy src [NC][H][W] into dst planes of `plane` floats laid out as rows of Wp: element
 * (sy, sx) goes to row top + sy*d, column left + sx*d; everything else in the plane (padding,
 * dilation holes, plane tail) is zero. Global: (Wp, ceil(plane/Wp), NC). The guard after the
 * last plane is filled separately. */
__kernel void spx_conv2d_pad(const __global float *src, ulong src_off, __global float *dst, int H, int W, int Hp,
                             int Wp, int plane, int top, int left, int d) {
  const int xx = (int)get_global_id(0), yy = (int)get_global_id(1), nc = (int)get_global_id(2);
  const int r = yy * Wp + xx;
  if (xx >= Wp || r >= plane) return;
  float v = 0.0f;
  int sy = yy - top, sx = xx - left;
  int ok = yy < Hp && sy >= 0 && sx >= 0;
  if (ok && d != 1) {
    ok = sy % d == 0 && sx % d == 0;
    sy /= d;
    sx /= d;
  }
  if (ok && sy < H && sx < W) v = src[src_off + ((size_t)nc * H + sy) * W + sx];
  dst[(size_t)nc * plane + r] = v;
}

/* Weight panels of CONV_TM columns (conv_pack in conv2d_common.h). */
__kernel void spx_conv2d_pack(CONV_PACK_ARGS) { conv_pack(w, w_off, wpk, Cout, Cin, k, cols, flip); }

/* The same forwards read from the unpadded input (kernels/conv2d_nopad.h; CONV_NOPAD). */
#include "conv2d_nopad.h"
__kernel void spx_conv2d_fwd_k3s1_np(CONV_NP_ARGS) { conv_fwd_np(CONV_NP_PASS(3)); }
__kernel void spx_conv2d_fwd_k1s1_np(CONV_NP_ARGS) { conv_fwd_np(CONV_NP_PASS(1)); }
