/* conv2d forwards other than the stride-1 3x3 / 1x1 ones of kernels/conv2d.cl: generic kernel
 * size at stride 1, stride 2, any stride (same implicit GEMM, kernels/conv2d_common.h). */
#include "conv2d_common.h"

__kernel void spx_conv2d_fwd_s1(CONV_FWD_ARGS) { conv_fwd(CONV_FWD_PASS, 1, 0); }
__kernel void spx_conv2d_fwd_s2(CONV_FWD_ARGS) { conv_fwd(CONV_FWD_PASS, 2, 0); }
__kernel void spx_conv2d_fwd_sn(CONV_FWD_ARGS, int S) { conv_fwd(CONV_FWD_PASS, S, 0); }
