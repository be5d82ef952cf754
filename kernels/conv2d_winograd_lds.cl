/* Winograd F(4x4, 3x3) for GPU-class devices: the three stages of conv2d_winograd.cl's CPU
 * variant (input transform, 36 GEMMs over the input channels, output transform) fused into one
 * kernel that stages everything through local memory (tunable CONV_WINO_LDS; host:
 * lib/nn/conv2d_winograd_lds.c, dispatched from lib/nn/conv2d_winograd.c; reference: the direct
 * convolution's, lib/nn/conv2d_ref.c; test: tests/test_nn_conv2d_winograd_lds.c).
 *
 * A work-group owns BM = CONV_WLDS_WM*CONV_WLDS_TM output channels x BN = CONV_WLDS_WN*CONV_WLDS_TN
 * consecutive 4x4 tiles of one tile row of one image, for all 36 transform positions e: it has
 * 36*CONV_WLDS_WM*CONV_WLDS_WN work-items, work-item (e, wm, wn) holding a register tile of
 * CONV_WLDS_TM channels (wm + i*WM) x CONV_WLDS_TN tiles (wn + j*WN) of position e's GEMM
 * (interleaved, so neighbouring work-items read neighbouring local words). Per block of
 * CONV_WLDS_KB input channels the group
 *   1. copies the block's input rows (6 rows x 4*BN+2 columns per channel, zero outside the
 *      image: no padded copy of the input) and the block's transformed weights (one contiguous
 *      run of U[cb][ci][e][BM]) into local memory,
 *   2. transforms the input in local memory, V[ci][e][BN] = B^T d B (one work-item per channel
 *      and tile),
 *   3. accumulates M[e][co][t] += U[e][ci][co] V[ci][e][t] in registers;
 * then the products go through local memory once more for the output transform and the
 * epilogue (y = A^T M A, accumulate / bias / affine / ReLU) by one work-item per (channel, tile).
 * Nothing but the input, U (spx_wino_lds_weights, once per call) and y touches global memory:
 * the CPU variant's V and M round trips (2.25x and 2.25x the input / output size) are gone.
 * The transforms are conv2d_winograd.cl's (winograd_tf.h) and the GEMM sums over ci in the same
 * order with fma from zero, so results are bit-identical to the CPU variant's and to reruns. */
#include "conv2d_common.h"
#include "winograd_tf.h"

#ifndef CONV_WLDS_TM
#define CONV_WLDS_TM 4
#endif
#ifndef CONV_WLDS_TN
#define CONV_WLDS_TN 4
#endif
#ifndef CONV_WLDS_WM
#define CONV_WLDS_WM 2
#endif
#ifndef CONV_WLDS_WN
#define CONV_WLDS_WN 2
#endif
#ifndef CONV_WLDS_KB
#define CONV_WLDS_KB 8
#endif
#define WL_TM CONV_WLDS_TM
#define WL_TN CONV_WLDS_TN
#define WL_WM CONV_WLDS_WM
#define WL_WN CONV_WLDS_WN
#define WL_KB CONV_WLDS_KB
#define WL_BM (WL_WM * WL_TM)  /* output channels of a group */
#define WL_BN (WL_WN * WL_TN)  /* tiles of a group */
#define WL_L (36 * WL_WM * WL_WN) /* work-items of a group */
#define WL_XW (4 * WL_BN + 2)  /* input columns of a group */
/* local memory: the block stage (input rows, V, U), later reused for the products M */
#define WL_XS (WL_KB * 6 * WL_XW)
#define WL_VS (WL_KB * 36 * WL_BN)
#define WL_US (WL_KB * 36 * WL_BM)
#define WL_MS (36 * WL_BM * WL_BN)
#define WL_POOL (WL_XS + WL_VS + WL_US > WL_MS ? WL_XS + WL_VS + WL_US : WL_MS)

/* U[cb][r][e][m] = (G g G^T)[e] for GEMM column c = cb*WL_BM + m (cols: the row count rounded up
 * to WL_BM, extra columns zero) and reduction index r; flip as in winograd_tf.h's wino_filter_of.
 * A group's block of KB reduction indices is then one contiguous run of KB*36*WL_BM floats, in the
 * order of its local copy (coalesced loads). One work-item per (r, c), c fastest. Global: red * cols. */
__kernel void spx_wino_lds_weights(const __global float *w, ulong w_off, __global float *U, int Cout, int Cin,
                                   int cols, int flip) {
  const int i = SPX_GID0, red = flip ? Cout : Cin;
  if (i >= red * cols) return;
  const int r = i / cols, c = i - r * cols;
  float u[36];
  wino_u_of(w + w_off, Cin, flip ? Cin : Cout, c, r, flip, u);
  __global float *ub = U + (((size_t)(c / WL_BM) * red + r) * 36) * WL_BM + c % WL_BM;
  for (int e = 0; e < 36; e++) ub[e * WL_BM] = u[e];
}

/* x [N][Cin][H][W] (the layer's input at its offset), U from spx_wino_lds_weights (CoutP columns),
 * TWp = tiles per row rounded up to WL_BN. Global: dim0 = CoutP/WL_BM * TH * TWp/WL_BN groups of
 * WL_L (channel block fastest: consecutive groups read the same input rows), dim1 = N. */
__kernel __attribute__((reqd_work_group_size(WL_L, 1, 1))) void spx_wino_lds(
    const __global float *x, ulong x_off, const __global float *U, __global float *y, ulong y_off,
    const __global float *bias, ulong b_off, const __global float *scale, ulong sc_off, const __global float *shift,
    ulong sh_off, int Cin, int Cout, int CoutP, int H, int W, int TWp, int flags) {
  __local float pool[WL_POOL];
  __local float *xs = pool, *vs = pool + WL_XS, *us = pool + WL_XS + WL_VS, *ms = pool;
  const int ncb = CoutP / WL_BM, grp = (int)get_group_id(0), cb = grp % ncb, tb = grp / ncb;
  const int nbx = TWp / WL_BN, ty = tb / nbx, tx0 = (tb - ty * nbx) * WL_BN;
  const int lid = (int)get_local_id(0), e = lid / (WL_WM * WL_WN), wm = lid / WL_WN % WL_WM, wn = lid % WL_WN;
  const int n = (int)get_global_id(1), hw = H * W;
  const __global float *xn = x + x_off + (size_t)n * Cin * hw;
  const int gy0 = 4 * ty - 1, gx0 = 4 * tx0 - 1; /* image position of the group's first input */
  float acc[WL_TM][WL_TN];
#pragma unroll
  for (int m = 0; m < WL_TM; m++)
#pragma unroll
    for (int j = 0; j < WL_TN; j++) acc[m][j] = 0.0f;

  for (int c0 = 0; c0 < Cin; c0 += WL_KB) {
    const int nc = min(WL_KB, Cin - c0);
    barrier(CLK_LOCAL_MEM_FENCE); /* the previous block is consumed */
    for (int i = lid; i < nc * 6 * WL_XW; i += WL_L) {
      int c = i / (6 * WL_XW), r = i - c * (6 * WL_XW), row = r / WL_XW, col = r - row * WL_XW;
      int gy = gy0 + row, gx = gx0 + col;
      xs[i] = gy >= 0 && gy < H && gx >= 0 && gx < W ? xn[(size_t)(c0 + c) * hw + gy * W + gx] : 0.0f;
    }
    const __global float *ub = U + ((size_t)cb * Cin + c0) * 36 * WL_BM; /* [c][e][m] of this block */
    for (int i = lid; i < nc * 36 * WL_BM; i += WL_L) us[i] = ub[i];
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int i = lid; i < nc * WL_BN; i += WL_L) { /* V = B^T d B, as spx_wino_in */
      int c = i / WL_BN, t = i - c * WL_BN;
      const __local float *p = xs + c * (6 * WL_XW) + 4 * t;
      /* fully unrolled, so d and r live in registers (rolled, GPU compilers put them on the stack) */
      float d[36], r[36];
#pragma unroll
      for (int a = 0; a < 6; a++)
#pragma unroll
        for (int b = 0; b < 6; b++) d[a * 6 + b] = p[a * WL_XW + b];
#pragma unroll
      for (int j = 0; j < 6; j++) WINO_BT(float, (r + j), (d + j), 6);
#pragma unroll
      for (int a = 0; a < 6; a++) WINO_BT(float, (d + 6 * a), (r + 6 * a), 1);
      __local float *v = vs + c * (36 * WL_BN) + t;
#pragma unroll
      for (int ee = 0; ee < 36; ee++) v[ee * WL_BN] = d[ee];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int c = 0; c < nc; c++) {
      const __local float *ur = us + (c * 36 + e) * WL_BM + wm, *vr = vs + (c * 36 + e) * WL_BN + wn;
      float uv[WL_TM], vv[WL_TN];
#pragma unroll
      for (int m = 0; m < WL_TM; m++) uv[m] = ur[m * WL_WM];
#pragma unroll
      for (int j = 0; j < WL_TN; j++) vv[j] = vr[j * WL_WN];
#pragma unroll
      for (int m = 0; m < WL_TM; m++)
#pragma unroll
        for (int j = 0; j < WL_TN; j++) acc[m][j] = fma(uv[m], vv[j], acc[m][j]);
    }
  }

  barrier(CLK_LOCAL_MEM_FENCE);
#pragma unroll
  for (int m = 0; m < WL_TM; m++)
#pragma unroll
    for (int j = 0; j < WL_TN; j++) ms[(e * WL_BM + wm + m * WL_WM) * WL_BN + wn + j * WL_WN] = acc[m][j];
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int i = lid; i < WL_BM * WL_BN; i += WL_L) { /* y = A^T M A + epilogue, as spx_wino_out */
    const int cl = i / WL_BN, t = i - cl * WL_BN, co = cb * WL_BM + cl, ox0 = 4 * (tx0 + t);
    if (co >= Cout || ox0 >= W) continue;
    float mm[36], r[24];
#pragma unroll
    for (int ee = 0; ee < 36; ee++) mm[ee] = ms[(ee * WL_BM + cl) * WL_BN + t];
    WINO_AT_COLS(float, r, mm);
    float bv, sc, sh;
    wino_epi_consts(flags, bias, b_off, scale, sc_off, shift, sh_off, co, &bv, &sc, &sh);
    __global float *yc = y + y_off + ((size_t)n * Cout + co) * hw;
#pragma unroll
    for (int a = 0; a < 4; a++) {
      const int oy = 4 * ty + a;
      if (oy >= H) continue;
      WINO_AT(float, o0, o1, o2, o3, (r + 6 * a), 1);
      const float o[4] = {o0, o1, o2, o3};
#pragma unroll
      for (int b = 0; b < 4; b++)
        if (ox0 + b < W) wino_epi1(o[b], yc + (size_t)oy * W + ox0 + b, flags, bv, sc, sh);
    }
  }
}
