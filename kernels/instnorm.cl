/* Instance norm 2d, affine = False (lib/nn/instnorm.h). One work-group of SPX_BN_WG work-items
 * (a power of two, lib/cl/tuning.c) per (n, c) plane; nothing but that group touches the plane,
 * so there are no atomics and results are bit-identical from run to run. Two-pass statistics
 * (mean, then sum (x - mean)^2: no cancellation); every item sums its strided share with Kahan
 * compensation, and the group combines the items by a pairwise tree in local memory.
 * save: [mean of every plane, then invstd of every plane]. */

#include "norm_reduce.h"

/* range: planes * SPX_BN_WG, groups of SPX_BN_WG */
__kernel __attribute__((reqd_work_group_size(SPX_BN_WG, 1, 1))) void spx_instnorm_fwd(
    __global const float *x, int xo, __global float *save, int so, __global float *y, int yo, int planes, int hw,
    float eps) {
  __local float buf[SPX_BN_WG];
  int p = get_group_id(0), lid = get_local_id(0);
  __global const float *xp = x + xo + p * hw;
  float s = 0.0f, c = 0.0f;
  for (int i = lid; i < hw; i += SPX_BN_WG) SPX_KAHAN_ADD(s, c, xp[i]);
  float mean = spx_bn_group_sum(buf, s - c) / (float)hw;
  s = 0.0f, c = 0.0f;
  for (int i = lid; i < hw; i += SPX_BN_WG) {
    float d = xp[i] - mean;
    SPX_KAHAN_ADD(s, c, d * d);
  }
  float var = spx_bn_group_sum(buf, s - c) / (float)hw;
  float is = 1.0f / sqrt(var + eps);
  if (lid == 0) {
    save[so + p] = mean;
    save[so + planes + p] = is;
  }
  __global float *yp = y + yo + p * hw;
  for (int i = lid; i < hw; i += SPX_BN_WG) yp[i] = (xp[i] - mean) * is;
}

/* dx += invstd * (dy - mean(dy) - xhat * mean(dy * xhat)) */
__kernel __attribute__((reqd_work_group_size(SPX_BN_WG, 1, 1))) void spx_instnorm_bwd(
    __global const float *x, int xo, __global const float *save, int so, __global const float *dy, int go,
    __global float *dx, int dxo, int planes, int hw) {
  __local float buf[SPX_BN_WG];
  int p = get_group_id(0), lid = get_local_id(0);
  __global const float *xp = x + xo + p * hw, *gp = dy + go + p * hw;
  float mean = save[so + p], is = save[so + planes + p];
  float s = 0.0f, c = 0.0f, s2 = 0.0f, c2 = 0.0f;
  for (int i = lid; i < hw; i += SPX_BN_WG) {
    float g = gp[i];
    SPX_KAHAN_ADD(s, c, g);
    SPX_KAHAN_ADD(s2, c2, g * (xp[i] - mean) * is);
  }
  float mg = spx_bn_group_sum(buf, s - c) / (float)hw;
  float mgx = spx_bn_group_sum(buf, s2 - c2) / (float)hw;
  __global float *dp = dx + dxo + p * hw;
  for (int i = lid; i < hw; i += SPX_BN_WG) dp[i] += is * (gp[i] - mg - (xp[i] - mean) * is * mgx);
}
