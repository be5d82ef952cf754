/* Reductions and losses. Deterministic two-stage sum: stage 1 runs a FIXED number of groups
 * G (SPX_RED_GROUPS, capped by the size; lib/nn/loss.c) of SPX_RED_WG items (a power of two);
 * item `lid` of group g sums elements g*WG + lid + k*G*WG with Kahan compensation, then the
 * group combines its items by a pairwise tree into partial[g]; stage 2 is one group that does
 * the same over the G partials and writes total / div. The association order depends only on
 * n, G and WG, never on timing, so reruns are bit-identical; the error is O(eps) per item plus
 * O(log2(WG)) tree levels, fine from n = 1 to 10^7 and beyond.
 * SPX_RED_WG == 1 (CPUs): group g instead sums the contiguous chunk [g*ceil(n/G), ...) with
 * eight Kahan lanes in a float8 (vectorised), folded with scalar Kahan.
 * Terms: kind 0 a[i], 1 |a[i] - b[i]| (L1), 2 (a[i] - b[i])^2 (MSE). */

#ifndef SPX_RED_WG
#define SPX_RED_WG 64
#endif

#include "norm_reduce.h"

#define SPX_TERM_VALUE 0
#define SPX_TERM_L1 1
#define SPX_TERM_MSE 2

static inline float spx_red_term(float v, float t, int kind) {
  if (kind == SPX_TERM_L1) return fabs(v - t);
  if (kind == SPX_TERM_MSE) return (v - t) * (v - t);
  return v;
}
static inline float8 spx_red_term8(float8 v, float8 t, int kind) {
  if (kind == SPX_TERM_L1) return fabs(v - t);
  if (kind == SPX_TERM_MSE) return (v - t) * (v - t);
  return v;
}

__kernel __attribute__((reqd_work_group_size(SPX_RED_WG, 1, 1))) void spx_reduce_stage1(
    __global const float *a, int ao, __global const float *b, int bo, int n, int kind, __global float *partial) {
  __local float buf[SPX_RED_WG];
  int lid = get_local_id(0), g = get_group_id(0), ng = get_num_groups(0);
  float s = 0.0f, c = 0.0f;
#if SPX_RED_WG == 1
  int chunk = n / ng + (n % ng != 0);
  int i = min(n, g * chunk), end = min(n, i + chunk);
  __global const float *pa = a + ao, *pb = b + bo;
  float8 s8 = 0.0f, c8 = 0.0f;
  for (; i + 8 <= end; i += 8) SPX_KAHAN8(s8, c8, spx_red_term8(vload8(0, pa + i), vload8(0, pb + i), kind));
  for (; i < end; i++) SPX_KAHAN_ADD(s, c, spx_red_term(pa[i], pb[i], kind));
  spx_fold8(s8, c8, &s, &c);
#else
  for (int i = g * SPX_RED_WG + lid; i < n; i += ng * SPX_RED_WG)
    SPX_KAHAN_ADD(s, c, spx_red_term(a[ao + i], b[bo + i], kind));
#endif
  float total = spx_tree_sum(buf, s - c, SPX_RED_WG);
  if (lid == 0) partial[g] = total;
}

__kernel __attribute__((reqd_work_group_size(SPX_RED_WG, 1, 1))) void spx_reduce_stage2(
    __global const float *partial, int np, __global float *out, int oo, float div) {
  __local float buf[SPX_RED_WG];
  int lid = get_local_id(0);
  float s = 0.0f, c = 0.0f;
  for (int i = lid; i < np; i += SPX_RED_WG) SPX_KAHAN_ADD(s, c, partial[i]);
  float total = spx_tree_sum(buf, s - c, SPX_RED_WG);
  if (lid == 0) out[oo] = total / div;
}

/* Loss gradient, ACCUMULATING, for the prediction (sign = 1) or the target (sign = -1):
 *   L1:  d += sign * sgn(a - b) * (g / div)        (PyTorch: abs().mean() autograd)
 *   MSE: d += sign * ((a - b) * norm * g)          (PyTorch mse_loss_backward, norm = 2/n or 2)
 * g = dout[0], the upstream gradient of the scalar loss. */
__kernel void spx_loss_bwd(__global const float *a, int ao, __global const float *b, int bo, __global const float *dout,
                           int go, __global float *d, int dof, int n, int kind, float div, float norm, float sign) {
  int i = SPX_GID0;
  if (i >= n) return;
  float g = dout[go], diff = a[ao + i] - b[bo + i], v;
  if (kind == SPX_TERM_L1)
    v = (diff > 0.0f ? 1.0f : (diff < 0.0f ? -1.0f : 0.0f)) * (g / div);
  else
    v = diff * norm * g;
  d[dof + i] += sign * v;
}
