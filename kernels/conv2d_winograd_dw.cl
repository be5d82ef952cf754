/* Winograd F(4x4,3x3) weight gradient for 3x3, stride 1, pad 1 layers (host:
 * lib/nn/conv2d_winograd_dw.c; reference: the direct convolution's weight gradient,
 * lib/nn/conv2d_ref.c; test: tests/test_nn_conv2d_winograd_dw.c).
 *
 * The forward computes every 4x4 output tile as Y = A^T [ U .* V ] A with U = G g G^T and
 * V = B^T d B (kernels/conv2d_winograd.cl). Differentiating, with dY the tile's 4x4 output gradient:
 *   dL/dU = (A dY A^T) .* V,   dL/dg = G^T (dL/dU) G,
 * summed over tiles (and samples). The sum over tiles moves inside the weight transform, so
 *   1. spx_wino_in (conv2d_winograd.cl) on the input:               V[n][ci][e][t]
 *   2. spx_wino_dw_grad:    Q[n][e][co][t] = (A dY A^T)[e]       (e = 0..35, zero outside the image)
 *   3. spx_wino_dw_gemm:    P[co][ci][e] += sum_t Q[n][e][co][t] V[n][ci][e][t]  (36 GEMMs, the
 *                           tile axis is the reduction; one fixed-order sum per sample, added to P
 *                           sample after sample, so P does not depend on how the batch is split)
 *   4. spx_wino_dw_weights: dw[co][ci] += G^T P[.][co][ci] G     (6x6 -> 3x3)
 * The GEMMs do 36 Cout Cin T multiply-adds for the direct path's 9 Cout Cin (16 T): 4x fewer.
 * No atomics; results are bit-identical from run to run. */
/* tunable defaults (CONV_DW_TM/TN/G/QB: the register tile of the direct weight gradient, reused
 * here for the GEMM), the CONV_VW vector type vf, VSUM */
#include "conv2d_common.h"

/* the tile block of the GEMM, a whole number of vectors */
#define WDW_QB ((CONV_DW_QB + CONV_VW - 1) / CONV_VW * CONV_VW)

/* r = A y for one column of 4 (stride s in y, stride rs in r): A is 6x4, A^T as in spx_wino_out. */
#define WINO_A(r, y, s, rs)                                                                   \
  do {                                                                                        \
    vf y0 = y[0], y1 = y[(s)], y2 = y[2 * (s)], y3 = y[3 * (s)];                              \
    vf p02 = y0 + y2, p13 = y1 + y3, q02 = y0 + 4.0f * y2, q13 = 2.0f * y1 + 8.0f * y3;        \
    r[0] = y0;                                                                                \
    r[(rs)] = p02 + p13;                                                                      \
    r[2 * (rs)] = p02 - p13;                                                                  \
    r[3 * (rs)] = q02 + q13;                                                                  \
    r[4 * (rs)] = q02 - q13;                                                                  \
    r[5 * (rs)] = y3;                                                                         \
  } while (0)

/* Output-gradient transform: Q[n][e][co][t] = (A dY A^T)[e] for the CONV_VW tiles t0.. of one tile
 * row (tiles numbered t = ty*TWp + tx as spx_wino_in's). dy [N][Cout][H][W] at dy_off, read with
 * bounds (zero outside the image). Global: (T / CONV_VW, Cout, N). */
__kernel void spx_wino_dw_grad(const __global float *dy, ulong dy_off, __global float *Q, int Cout, int H, int W,
                               int TWp, int T) {
  const int t0 = (int)get_global_id(0) * CONV_VW, co = (int)get_global_id(1), n = (int)get_global_id(2);
  if (t0 >= T) return;
  const int ty = t0 / TWp, tx0 = t0 - ty * TWp, ox0 = 4 * tx0;
  const __global float *dc = dy + dy_off + ((size_t)n * Cout + co) * H * W;
  vf d[16], r[24], q[36];
  for (int i = 0; i < 4; i++) {
    const int oy = 4 * ty + i;
    const __global float *p = dc + (size_t)oy * W + ox0;
#if CONV_VW == 16
    if (oy < H && ox0 + 64 <= W) {
      /* lane l needs p[4l + j], j = 0..3: four 16-float loads, de-interleaved by 4 */
      float16 a0 = vload16(0, p), a1 = vload16(0, p + 16), a2 = vload16(0, p + 32), a3 = vload16(0, p + 48);
      d[4 * i + 0] = (float16)(a0.s048c, a1.s048c, a2.s048c, a3.s048c);
      d[4 * i + 1] = (float16)(a0.s159d, a1.s159d, a2.s159d, a3.s159d);
      d[4 * i + 2] = (float16)(a0.s26ae, a1.s26ae, a2.s26ae, a3.s26ae);
      d[4 * i + 3] = (float16)(a0.s37bf, a1.s37bf, a2.s37bf, a3.s37bf);
      continue;
    }
#endif
    for (int j = 0; j < 4; j++) {
      float lanes[CONV_VW];
      for (int l = 0; l < CONV_VW; l++) lanes[l] = oy < H && ox0 + 4 * l + j < W ? p[4 * l + j] : 0.0f;
      d[4 * i + j] = VLOAD(lanes);
    }
  }
  for (int j = 0; j < 4; j++) WINO_A((r + j), (d + j), 4, 4); /* columns: r (6x4) = A dY */
  for (int a = 0; a < 6; a++) WINO_A((q + 6 * a), (r + 4 * a), 1, 1); /* rows: q (6x6) = r A^T */
  __global float *qo = Q + ((size_t)n * 36 * Cout + co) * T + t0;
  const size_t es = (size_t)Cout * T;
  for (int e = 0; e < 36; e++) VSTORE(q[e], qo + e * es);
}

/* The 36 GEMMs over the tiles of NS samples: P[co][ci][e] = (accum ? P : 0) + s_0 + s_1 + ...,
 * s_n = sum_t Q[n][e][co][t] V[n][ci][e][t] (CONV_VW lanes of partial sums, then VSUM). A
 * work-item owns CONV_DW_TM out channels x CONV_DW_G tiles of CONV_DW_TN in channels; it walks
 * the tiles in blocks of CONV_DW_QB and updates every channel tile per block, so the block of Q
 * stays in L1 while V streams. (P's 36 entries of one weight pair are adjacent, so that
 * spx_wino_dw_weights reads them in one line.) Global: (ceil(Cin / (TN*G)), ceil(Cout / TM), 36). */
__kernel void spx_wino_dw_gemm(const __global float *Q, const __global float *V, __global float *P, int Cin,
                               int Cout, int T, int NS, int accum) {
  const int ct0 = (int)get_global_id(0) * CONV_DW_G, co0 = (int)get_global_id(1) * CONV_DW_TM;
  const int e = (int)get_global_id(2);
  const int nct = (Cin + CONV_DW_TN - 1) / CONV_DW_TN;
  if (ct0 >= nct || co0 >= Cout) return;
  const int ng = min(CONV_DW_G, nct - ct0);
  int qrow[CONV_DW_TM], vrow[CONV_DW_G][CONV_DW_TN];
#pragma unroll
  for (int m = 0; m < CONV_DW_TM; m++) qrow[m] = min(co0 + m, Cout - 1);
  for (int g = 0; g < CONV_DW_G; g++)
#pragma unroll
    for (int j = 0; j < CONV_DW_TN; j++) vrow[g][j] = min((ct0 + g) * CONV_DW_TN + j, Cin - 1);
  vf sums[CONV_DW_G][CONV_DW_TM][CONV_DW_TN];
  for (int n = 0; n < NS; n++) {
    const __global float *qn = Q + ((size_t)n * 36 + e) * Cout * T;
    const __global float *vn = V + ((size_t)n * Cin * 36 + e) * T;
    for (int g = 0; g < CONV_DW_G; g++)
#pragma unroll
      for (int m = 0; m < CONV_DW_TM; m++)
#pragma unroll
        for (int j = 0; j < CONV_DW_TN; j++) sums[g][m][j] = (vf)0.0f;
    for (int tb = 0; tb < T; tb += WDW_QB) {
      const int te = min(tb + WDW_QB, T);
      for (int g = 0; g < ng; g++) {
        vf a[CONV_DW_TM][CONV_DW_TN];
        DW_TILE_COPY(a, sums[g]);
        for (int t = tb; t < te; t += CONV_VW) {
          vf qv[CONV_DW_TM], vv[CONV_DW_TN];
#pragma unroll
          for (int m = 0; m < CONV_DW_TM; m++) qv[m] = VLOAD(qn + (size_t)qrow[m] * T + t);
#pragma unroll
          for (int j = 0; j < CONV_DW_TN; j++) vv[j] = VLOAD(vn + (size_t)vrow[g][j] * 36 * T + t);
          DW_TILE_FMA(a, qv, vv);
        }
        DW_TILE_COPY(sums[g], a);
      }
    }
    /* one sum per sample, added in sample order */
    /* constant trip counts and guards (no break), so the loops unroll and sums stays in registers */
#pragma unroll
    for (int g = 0; g < CONV_DW_G; g++)
#pragma unroll
      for (int m = 0; m < CONV_DW_TM; m++) {
        const int co = co0 + m;
        if (g >= ng || co >= Cout) continue;
#pragma unroll
        for (int j = 0; j < CONV_DW_TN; j++) {
          const int ci = (ct0 + g) * CONV_DW_TN + j;
          if (ci >= Cin) continue;
          __global float *pp = P + ((size_t)co * Cin + ci) * 36 + e;
          *pp = (accum || n > 0 ? *pp : 0.0f) + VSUM(sums[g][m][j]);
        }
      }
  }
}

/* dw[co][ci] += G^T P[.][co][ci] G (the 6x6 gradient of U back to the 3x3 filter; G as in
 * spx_wino_weights). Global: Cout * Cin. */
#define R6 0.16666667f /* 1/6, 1/12, 1/24 rounded to float */
#define R12 0.083333336f
#define R24 0.041666668f
/* o = G^T p for one column of 6 (stride s in p, stride os in o) */
#define WINO_GT(o, p, s, os)                                                                  \
  do {                                                                                        \
    float p0 = p[0], p1 = p[(s)], p2 = p[2 * (s)], p3 = p[3 * (s)], p4 = p[4 * (s)], p5 = p[5 * (s)]; \
    float s12 = p1 + p2, s34 = p3 + p4;                                                        \
    o[0] = p0 * 0.25f - s12 * R6 + s34 * R24;                                                   \
    o[(os)] = (p2 - p1) * R6 + (p3 - p4) * R12;                                                 \
    o[2 * (os)] = (s34 - s12) * R6 + p5;                                                        \
  } while (0)
__kernel void spx_wino_dw_weights(const __global float *P, __global float *dw, ulong dw_off, int Cout, int Cin) {
  const int i = SPX_GID0; /* co * Cin + ci */
  if (i >= Cout * Cin) return;
  float p[36], h[18], o[9];
  for (int e = 0; e < 36; e++) p[e] = P[(size_t)i * 36 + e];
  for (int b = 0; b < 6; b++) WINO_GT((h + b), (p + b), 6, 6); /* columns: h (3x6) = G^T p */
  for (int a = 0; a < 3; a++) WINO_GT((o + 3 * a), (h + 6 * a), 1, 1); /* rows: o (3x3) = h G */
  __global float *dp = dw + dw_off + (size_t)i * 9;
  for (int k = 0; k < 9; k++) dp[k] += o[k];
}
