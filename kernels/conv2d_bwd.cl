/* conv2d gradients (host: lib/nn/conv2d_direct.c direct_weights, lib/nn/conv2d.c backward_bias);
 * backward data runs the forward kernels of conv2d.cl. Layout: see the top of kernels/conv2d.cl. */
#include "conv2d_common.h"

/* Backward weights, partial sums: part[c][co][kk] = sum_n sum_{q in chunk c} dyq[n][co][q] *
 * xp[n][ci][S*q + ky*Wp + kx]. dyq holds dy on the virtual grid (zeros in the padding columns
 * and past the end). A work-item owns DW_TM channels x CONV_DW_G tiles of DW_TN weight columns;
 * it walks its chunk in blocks of CONV_DW_QB q and, per block, updates every tile in turn
 * (accumulators of the other tiles wait in private memory), so the block of dy stays in L1
 * while the tiles stream x. Global: dim0 = ceil(Kdim/(DW_TN*DW_G)), dim1 = ceil(Cout/DW_TM),
 * dim2 = chunks. */
static inline __attribute__((always_inline)) void conv_dw(const __global float *xp, const __global float *dyq,
                                                          __global float *part, int N, int Cin, int Cout, int k,
                                                          int Wp, int plane, int Qd, int qchunk, const int S) {
  const int Kdim = Cin * k * k;
  const int kt0 = (int)get_global_id(0) * CONV_DW_G;
  const int co0 = (int)get_global_id(1) * CONV_DW_TM;
  const int c = (int)get_global_id(2);
  if (kt0 * CONV_DW_TN >= Kdim || co0 >= Cout) return;
  const int qa = c * qchunk, qe = min(qa + qchunk, Qd);
  const int ntiles = min(CONV_DW_G, (Kdim + CONV_DW_TN - 1) / CONV_DW_TN - kt0);

  int xoff[CONV_DW_G][CONV_DW_TN];
  for (int g = 0; g < CONV_DW_G; g++)
#pragma unroll
    for (int j = 0; j < CONV_DW_TN; j++) {
      int kk = min((kt0 + g) * CONV_DW_TN + j, Kdim - 1);
      int ci = kk / (k * k), r = kk - ci * k * k, ky = r / k, kx = r - ky * k;
      xoff[g][j] = ci * plane + ky * Wp + kx;
    }
  int yoff[CONV_DW_TM];
#pragma unroll
  for (int m = 0; m < CONV_DW_TM; m++) yoff[m] = min(co0 + m, Cout - 1) * Qd;

  vf accs[CONV_DW_G][CONV_DW_TM][CONV_DW_TN];
  for (int g = 0; g < CONV_DW_G; g++)
#pragma unroll
    for (int m = 0; m < CONV_DW_TM; m++)
#pragma unroll
      for (int j = 0; j < CONV_DW_TN; j++) accs[g][m][j] = (vf)0.0f;

  for (int n = 0; n < N; n++) {
    const __global float *xn = xp + (size_t)n * Cin * plane;
    const __global float *dn = dyq + (size_t)n * Cout * Qd;
    for (int qb = qa; qb < qe; qb += CONV_DW_QB) {
      const int qbe = min(qb + CONV_DW_QB, qe);
      for (int g = 0; g < ntiles; g++) {
        vf acc[CONV_DW_TM][CONV_DW_TN];
        DW_TILE_COPY(acc, accs[g]);
        for (int q = qb; q < qbe; q += CONV_VW) {
          vf dv[CONV_DW_TM], xv[CONV_DW_TN];
#pragma unroll
          for (int m = 0; m < CONV_DW_TM; m++) dv[m] = VLOAD(dn + yoff[m] + q);
#pragma unroll
          for (int j = 0; j < CONV_DW_TN; j++) xv[j] = vload_s(xn + xoff[g][j] + S * q, S);
          DW_TILE_FMA(acc, dv, xv);
        }
        DW_TILE_COPY(accs[g], acc);
      }
    }
  }
  /* constant trip counts and guards (no break), so the loops unroll and accs stays in registers */
#pragma unroll
  for (int g = 0; g < CONV_DW_G; g++)
#pragma unroll
    for (int m = 0; m < CONV_DW_TM; m++) {
      int co = co0 + m;
      if (g >= ntiles || co >= Cout) continue;
#pragma unroll
      for (int j = 0; j < CONV_DW_TN; j++) {
        int kk = (kt0 + g) * CONV_DW_TN + j;
        if (kk < Kdim) part[((size_t)c * Cout + co) * Kdim + kk] = VSUM(accs[g][m][j]);
      }
    }
}

#define CONV_DW_ARGS                                                                                          \
  const __global float *xp, const __global float *dyq, __global float *part, int N, int Cin, int Cout, int k, \
      int Wp, int plane, int Qd, int qchunk
#define CONV_DW_PASS xp, dyq, part, N, Cin, Cout, k, Wp, plane, Qd, qchunk
__kernel void spx_conv2d_dw_s1(CONV_DW_ARGS) { conv_dw(CONV_DW_PASS, 1); }
__kernel void spx_conv2d_dw_s2(CONV_DW_ARGS) { conv_dw(CONV_DW_PASS, 2); }
__kernel void spx_conv2d_dw_sn(CONV_DW_ARGS, int S) { conv_dw(CONV_DW_PASS, S); }

/* dw[i] += sum over chunks c (in order) of part[c][i]. */
__kernel void spx_conv2d_dw_reduce(const __global float *part, __global float *dw, ulong dw_off, int count,
                                   int nchunks) {
  int i = SPX_GID0;
  if (i >= count) return;
  float s = 0.0f;
  for (int c = 0; c < nchunks; c++) s += part[(size_t)c * count + i];
  dw[dw_off + i] += s;
}

/* db[co] += sum_{n, p} dy[n][co][p]: one work-group of CONV_RED_WG per channel, strided
 * partial sums then a fixed tree in local memory. */
__kernel void spx_conv2d_db(const __global float *dy, ulong dy_off, __global float *db, ulong db_off, int N,
                            int Cout, int hw) {
  __local float red[CONV_RED_WG];
  const int co = (int)get_group_id(0), lid = (int)get_local_id(0);
  float s = 0.0f;
  for (int n = 0; n < N; n++) {
    const __global float *p = dy + dy_off + ((size_t)n * Cout + co) * hw;
    for (int i = lid; i < hw; i += CONV_RED_WG) s += p[i];
  }
  red[lid] = s;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int h = CONV_RED_WG / 2; h > 0; h >>= 1) {
    if (lid < h) red[lid] += red[lid + h];
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (lid == 0) db[db_off + co] += red[0];
}

