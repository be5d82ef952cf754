/* 3x3 stride-1 convolution forward with local-memory tiles, for GPU-class devices (tunable
 * CONV_LDS; host: lib/nn/conv2d_lds.c, called from lib/nn/conv2d_direct.c for every 3x3 stride-1
 * forward and backward-data convolution that is not on the Winograd path; reference:
 * lib/nn/conv2d_ref.c; test: tests/test_nn_conv2d_lds.c).
 *
 * Same inputs as conv2d.cl's spx_conv2d_fwd_k3s1 (xp zero-padded by spx_conv2d_pad into planes of
 * Hp x Wp, output (oy, ox) reading xp[ci][oy+ky][ox+kx]; weights packed per channel tile as
 * wpk[cot][ci*9 + ky*3 + kx][CONV_TM]), but the outputs are cut into 2-D tiles of
 * LDS_TX columns x LDS_TY rows, one work-group of CONV_LWS work-items per (tile, channel tile of
 * CONV_TM outputs, image). Work-item (lx, ly) owns column lx and rows ly + j*(CONV_LWS/LDS_TX),
 * j < CONV_TN, for CONV_TM output channels. Per block of CONV_LDS_CB input channels the group
 * copies the (LDS_TY+2) x (LDS_TX+2) input halo and the block's 9*CONV_TM weights into local
 * memory once; every input value is then read from local memory by up to 9 outputs and every
 * weight by all CONV_LWS work-items (the direct GPU kernel reads both from global memory /
 * caches). Sums run over (ci, ky, kx) in order with fma: fixed order, bit-identical reruns.
 *
 * CONV_LDS = 2 runs spx_conv2d_fwd_k3s1_lds2 instead, whose register tile reuses what it reads
 * from local memory: a work-item owns CONV_TM output channels x CONV_TN adjacent columns of one
 * row, loads the CONV_TN + 2 inputs of a (channel, ky) row once for its 3 taps kx, and its TM
 * weights of a tap as float4s; a work-group of CONV_LWS is CONV_LDS_CG channel groups x pixel
 * work-items, so one staged halo serves CONV_LDS_CG * CONV_TM output channels. Per output the
 * same (ci, ky, kx) fma chain, so both kernels give the same bits as the direct one. */
#include "conv2d_common.h"

#ifndef CONV_LDS_TX
#define CONV_LDS_TX 16
#endif
#ifndef CONV_LDS_CB
#define CONV_LDS_CB 8
#endif
#define LDS_TX CONV_LDS_TX
#define LDS_WY (CONV_LWS / CONV_LDS_TX) /* work-item rows of a group */
#define LDS_TY (LDS_WY * CONV_TN)       /* output rows of a tile */
#define LDS_HX (LDS_TX + 2)             /* halo width */
#define LDS_HY (LDS_TY + 2)

/* Stage the input halo of nc channels from channel cb: hy x hx values from (oy0, ox0) of each
 * padded plane into xs (zeros past the plane), consecutive work-items on consecutive columns. */
static inline __attribute__((always_inline)) void lds_stage_halo(__local float *xs, const __global float *xn, int cb,
                                                                 int nc, int hy, int hx, int oy0, int ox0, int Wp,
                                                                 int plane, int lid) {
  for (int e = lid; e < nc * hy * hx; e += CONV_LWS) {
    int c = e / (hy * hx), r = e - c * (hy * hx), y = r / hx, x = r - y * hx;
    int gy = oy0 + y, gx = ox0 + x;
    xs[e] = gx < Wp && gy * Wp + gx < plane ? xn[(size_t)(cb + c) * plane + gy * Wp + gx] : 0.0f;
  }
}

/* The epilogue of a work-item's tile, as conv2d_common.h's conv_fwd_store: accumulate / bias /
 * affine / ReLU, acc[m][j] stored at y0[(co0 + m) * hw + j * step] for the channels below Cout and
 * the first nj outputs (those inside the image; the rest of the tile lies past its edge). Guards
 * instead of breaks, so both loops unroll fully and acc stays in registers (an early exit leaves a
 * loop rolled and acc indexed at run time, which GPU compilers put on the stack). */
static inline __attribute__((always_inline)) void lds_store_tile(float acc[CONV_TM][CONV_TN], __global float *y0,
                                                                 int hw, int step, int nj, int co0, int Cout,
                                                                 int flags, const __global float *bias,
                                                                 const __global float *scale,
                                                                 const __global float *shift) {
  const int mmax = min(CONV_TM, Cout - co0);
#pragma unroll
  for (int m = 0; m < CONV_TM; m++) {
    if (m >= mmax) continue;
    const int co = co0 + m;
    const float b = (flags & FL_BIAS) ? bias[co] : 0.0f, sc = (flags & FL_SCALE) ? scale[co] : 1.0f;
    const float sh = (flags & FL_SHIFT) ? shift[co] : 0.0f;
#pragma unroll
    for (int j = 0; j < CONV_TN; j++) {
      if (j >= nj) continue;
      __global float *yo = y0 + (size_t)co * hw + j * step;
      float v = acc[m][j];
      if (flags & FL_ACCUM) v = *yo + v;
      if (flags & FL_BIAS) v = v + b;
      if (flags & FL_SCALE) v = v * sc + sh;
      if (flags & FL_RELU) v = fmax(v, 0.0f);
      *yo = v;
    }
  }
}

#if CONV_LWS % CONV_LDS_TX == 0
/* Global: dim0 = CoutP/CONV_TM * ceil(Wo/LDS_TX) * ceil(Ho/LDS_TY) groups of CONV_LWS (channel
 * tile fastest), dim1 = N. Input channels [ci0, ci1) only (the host's channel-block passes). */
__kernel __attribute__((reqd_work_group_size(CONV_LWS, 1, 1))) void spx_conv2d_fwd_k3s1_lds(CONV_FWD_ARGS) {
  __local float xs[CONV_LDS_CB * LDS_HY * LDS_HX];
  __local float ws[CONV_LDS_CB * 9 * CONV_TM];
  const int ncot = CoutP / CONV_TM, ntx = (Wo + LDS_TX - 1) / LDS_TX, grp = (int)get_group_id(0);
  const int cot = grp % ncot, tile = grp / ncot, ox0 = (tile % ntx) * LDS_TX, oy0 = (tile / ntx) * LDS_TY;
  const int lid = (int)get_local_id(0), lx = lid % LDS_TX, ly = lid / LDS_TX, n = (int)get_global_id(1);
  const __global float *xn = xp + (size_t)n * Cin * plane;
  const __global float *wt = wpk + (size_t)cot * Cin * 9 * CONV_TM;
  (void)pix_major;
  (void)k;
  float acc[CONV_TM][CONV_TN] = {{0.0f}};

  for (int cb = ci0; cb < ci1; cb += CONV_LDS_CB) {
    const int nc = min(CONV_LDS_CB, ci1 - cb);
    barrier(CLK_LOCAL_MEM_FENCE); /* the previous block is consumed */
    lds_stage_halo(xs, xn, cb, nc, LDS_HY, LDS_HX, oy0, ox0, Wp, plane, lid);
    for (int e = lid; e < nc * 9 * CONV_TM; e += CONV_LWS) ws[e] = wt[(size_t)cb * 9 * CONV_TM + e];
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int c = 0; c < nc; c++)
      for (int ky = 0; ky < 3; ky++)
#pragma unroll
        for (int kx = 0; kx < 3; kx++) {
          const __local float *wr = ws + (c * 9 + ky * 3 + kx) * CONV_TM;
          const __local float *xr = xs + (c * LDS_HY + ly + ky) * LDS_HX + lx + kx;
          float xv[CONV_TN];
#pragma unroll
          for (int j = 0; j < CONV_TN; j++) xv[j] = xr[j * LDS_WY * LDS_HX];
          CONV_TILE_FMA(float, acc, wr, xv);
        }
  }

  const int ox = ox0 + lx, hw = Ho * Wo, oy = oy0 + ly;
  if (ox >= Wo || oy >= Ho) return;
  /* rows oy + j * LDS_WY, those below Ho */
  lds_store_tile(acc, y + y_off + (size_t)n * Cout * hw + oy * Wo + ox, hw, LDS_WY * Wo,
                 (Ho - 1 - oy) / LDS_WY + 1, cot * CONV_TM, Cout, flags, bias + b_off, scale + sc_off, shift + sh_off);
}
#endif

#ifndef CONV_LDS_CG
#define CONV_LDS_CG 1
#endif
#define L2_PT (CONV_LWS / CONV_LDS_CG)  /* pixel work-items of a group */
#define L2_PX (CONV_LDS_TX / CONV_TN)   /* pixel work-items per tile row */
#define L2_TY (L2_PT / L2_PX)           /* output rows of a tile */
#define L2_HX (CONV_LDS_TX + 2)
#define L2_HY (L2_TY + 2)
#define L2_CM (CONV_LDS_CG * CONV_TM)   /* output channels of a group */

#if CONV_LWS % CONV_LDS_CG == 0 && CONV_LDS_TX % CONV_TN == 0 && L2_PT % L2_PX == 0
/* TM weights of one tap from local memory: float4 loads when TM is a multiple of 4 (the tap's
 * panel starts at a multiple of TM floats, so they are aligned). */
static inline __attribute__((always_inline)) void l2_weights(const __local float *wr, float wv[CONV_TM]) {
#if CONV_TM % 4 == 0
#pragma unroll
  for (int m = 0; m < CONV_TM; m += 4) {
    float4 v = vload4(0, wr + m);
    wv[m] = v.s0, wv[m + 1] = v.s1, wv[m + 2] = v.s2, wv[m + 3] = v.s3;
  }
#else
#pragma unroll
  for (int m = 0; m < CONV_TM; m++) wv[m] = wr[m];
#endif
}

/* Global: dim0 = ceil(CoutP / L2_CM) * ceil(Wo / CONV_LDS_TX) * ceil(Ho / L2_TY) groups of
 * CONV_LWS (channel group fastest), dim1 = N. Work-item lid: channel group lid / L2_PT, pixel
 * work-item p = lid % L2_PT at row p / L2_PX, columns (p % L2_PX) * CONV_TN + [0, CONV_TN). */
__kernel __attribute__((reqd_work_group_size(CONV_LWS, 1, 1))) void spx_conv2d_fwd_k3s1_lds2(CONV_FWD_ARGS) {
  __local float xs[CONV_LDS_CB * L2_HY * L2_HX];
  __local float ws[CONV_LDS_CB * 9 * L2_CM];
  float acc[CONV_TM][CONV_TN] = {{0.0f}}; /* channels x adjacent columns */
  const int ncot = CoutP / CONV_TM, ncg = (ncot + CONV_LDS_CG - 1) / CONV_LDS_CG;
  const int ntx = (Wo + CONV_LDS_TX - 1) / CONV_LDS_TX, grp = (int)get_group_id(0);
  const int cg = grp % ncg, tile = grp / ncg, ox0 = (tile % ntx) * CONV_LDS_TX, oy0 = (tile / ntx) * L2_TY;
  const int lid = (int)get_local_id(0), g = lid / L2_PT, p = lid - g * L2_PT;
  const int py = p / L2_PX, px = (p - py * L2_PX) * CONV_TN, n = (int)get_global_id(1);
  const int cot0 = cg * CONV_LDS_CG, ntiles = min(CONV_LDS_CG, ncot - cot0); /* channel tiles of this group */
  const __global float *xn = xp + (size_t)n * Cin * plane;
  (void)pix_major;
  (void)k;
  for (int cb = ci0; cb < ci1; cb += CONV_LDS_CB) {
    const int nc = min(CONV_LDS_CB, ci1 - cb);
    barrier(CLK_LOCAL_MEM_FENCE); /* the previous block is consumed */
    lds_stage_halo(xs, xn, cb, nc, L2_HY, L2_HX, oy0, ox0, Wp, plane, lid);
    /* weights: ws[(c*9 + tap) * L2_CM + t*TM + m] from tile cot0 + t's panel wpk[cot][ci*9 + tap][m] */
    for (int e = lid; e < nc * 9 * L2_CM; e += CONV_LWS) {
      int ct = e / L2_CM, tm = e - ct * L2_CM, t = tm / CONV_TM;
      ws[e] = t < ntiles ? wpk[((size_t)(cot0 + t) * Cin * 9 + (size_t)cb * 9 + ct) * CONV_TM + (tm - t * CONV_TM)]
                         : 0.0f;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int c = 0; c < nc; c++)
#pragma unroll
      for (int ky = 0; ky < 3; ky++) {
        const __local float *xr = xs + (c * L2_HY + py + ky) * L2_HX + px;
        float xv[CONV_TN + 2];
#pragma unroll
        for (int j = 0; j < CONV_TN + 2; j++) xv[j] = xr[j];
#pragma unroll
        for (int kx = 0; kx < 3; kx++) {
          float wv[CONV_TM];
          l2_weights(ws + (c * 9 + ky * 3 + kx) * L2_CM + g * CONV_TM, wv);
#pragma unroll
          for (int m = 0; m < CONV_TM; m++)
#pragma unroll
            for (int j = 0; j < CONV_TN; j++) acc[m][j] = fma(wv[m], xv[j + kx], acc[m][j]);
        }
      }
  }

  const int oy = oy0 + py, hw = Ho * Wo, ox = ox0 + px;
  if (oy >= Ho || ox >= Wo || g >= ntiles) return;
  /* columns ox + j, those below Wo */
  lds_store_tile(acc, y + y_off + (size_t)n * Cout * hw + oy * Wo + ox, hw, 1, Wo - ox, (cot0 + g) * CONV_TM, Cout,
                 flags, bias + b_off, scale + sc_off, shift + sh_off);
}
#endif
