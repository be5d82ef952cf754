/* The stride-1 3x3 / 1x1 forwards and the weight packing of kernels/conv2d.cl, compiled with the
 * narrow register tile: CONV_NARROW_TM output channels x CONV_NARROW_TN vectors of CONV_VW pixels
 * per work-item instead of CONV_TM x CONV_TN. Host: lib/nn/conv2d_direct.c picks these for runs with at
 * most CONV_NARROW_MAXC output channels (lib/cl/tuning.c). Same arguments and the same summation
 * order per output (input channel, then ky, kx, one fma each) as conv2d.cl: bit-identical
 * results, only the work split differs. On 2-core PoCL the full-resolution 16/32-channel layers
 * of the width-16 UNet run ~25-30% less CPU time with a 4 x 6 tile than with 8 x 3 (more pixels
 * per work-item, half the weight broadcasts per input vector; benchmarks/RESULTS.md); on Zen 5,
 * 4 x 5 (the CPU default, lib/cl/tuning.c). */
#ifndef CONV_NARROW_TM
#define CONV_NARROW_TM 4
#endif
#ifndef CONV_NARROW_TN
#define CONV_NARROW_TN 5
#endif
#undef CONV_TM
#undef CONV_TN
#define CONV_TM CONV_NARROW_TM
#define CONV_TN CONV_NARROW_TN
#include "conv2d_common.h"

__kernel void spx_conv2d_fwd_k3s1_narrow(CONV_FWD_ARGS) { conv_fwd(CONV_FWD_PASS, 1, 3); }
__kernel void spx_conv2d_fwd_k1s1_narrow(CONV_FWD_ARGS) { conv_fwd(CONV_FWD_PASS, 1, 1); }
__kernel void spx_conv2d_pack_narrow(CONV_PACK_ARGS) { conv_pack(w, w_off, wpk, Cout, Cin, k, cols, flip); }
#include "conv2d_nopad.h"
__kernel void spx_conv2d_fwd_k3s1_narrow_np(CONV_NP_ARGS) { conv_fwd_np(CONV_NP_PASS(3)); }
__kernel void spx_conv2d_fwd_k1s1_narrow_np(CONV_NP_ARGS) { conv_fwd_np(CONV_NP_PASS(1)); }
