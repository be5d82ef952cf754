/* Winograd F(4x4, 3x3) convolution for 3x3, stride 1, pad 1 layers (host: lib/nn/conv2d_winograd.c;
 * reference: the direct convolution's, lib/nn/conv2d_ref.c; test: tests/test_nn_conv2d_winograd.c).
 *
 * Every 4x4 output tile is A^T [ (G g G^T) .* (B^T d B) ] A, d being the 6x6 input patch around
 * it (rows 4ty-1 .. 4ty+4, zero outside the image) and g the 3x3 filter (Lavin & Gray 2016, points
 * 0, +-1, +-2, inf). The sum over input channels moves inside the transform, so a layer becomes
 *   1. spx_wino_in:      V[n][ci][e][t] = (B^T d B)[e]          (e = 0..35, t = tile index; a
 *                        channel's 36 planes together, so that a work-item's 36 stores lie within
 *                        36 Tp floats: 36 C Tp apart they had made this kernel wait on its stores)
 *   2. spx_wino_weights: U[e][cot][ci][m] = (G g G^T)[e] of out channel cot*CONV_TM+m
 *   3. spx_wino_gemm:    M[n][e][co][t] = sum_ci U[e][co][ci] V[n][ci][e][t]  (36 GEMMs per image)
 *   4. spx_wino_out:     y = A^T M A + epilogue (accumulate / bias / affine / ReLU, as conv2d.cl)
 * (spx_wino_in reads the input itself, with zeros outside the image.)
 * 36 GEMMs of Cout x Cin x T do the work of one direct convolution of Cout x 9Cin x 16T: 4x fewer
 * multiply-adds. The GEMM uses the direct kernel's register tiling and tunables (CONV_TM out
 * channels x CONV_TN vectors of CONV_VW tiles, CONV_LWS work-items with interleaved tiles). The
 * tile count is padded to Tp (a multiple of a work-group's tiles); padding tiles hold zeros. (On the
 * GPU class's GEMM engine, stage 3 is kernels/conv2d_gemm.cl's strided-batched GEMM instead.)
 * Reduction orders are fixed: results are bit-identical from run to run (but not equal to the
 * direct convolution's; see the test for the error bound). */
/* tunable defaults, the CONV_VW vector type vf, the FL_* epilogue flags */
#include "conv2d_common.h"
/* the transforms (WINO_BT, WINO_AT, wino_filter), shared with conv2d_winograd_lds.cl */
#include "winograd_tf.h"

/* Row i of the 6 x 6 patches of the CONV_VW tiles of one work-item (D[i*6 + j] lane l = the
 * patch row's element 4l + j), from the row's first 4*CONV_VW + 4 elements as CONV_VW == 16:
 * eight 16-float vectors L(0), L(16), L(32), L(48), L(4), L(20), L(36), L(52) (L(o): elements
 * o .. o+15), de-interleaved by 4; other widths: gathered lane by lane with G(k) (element k). */
#if CONV_VW == 16
#define WINO_IN_ROW(D, L, G, i)                                                           \
  do {                                                                                 \
    float16 a0 = L(0), a1 = L(16), a2 = L(32), a3 = L(48);                             \
    float16 b0 = L(4), b1 = L(20), b2 = L(36), b3 = L(52);                             \
    (D)[(i) * 6 + 0] = (float16)(a0.s048c, a1.s048c, a2.s048c, a3.s048c);                \
    (D)[(i) * 6 + 1] = (float16)(a0.s159d, a1.s159d, a2.s159d, a3.s159d);                \
    (D)[(i) * 6 + 2] = (float16)(a0.s26ae, a1.s26ae, a2.s26ae, a3.s26ae);                \
    (D)[(i) * 6 + 3] = (float16)(a0.s37bf, a1.s37bf, a2.s37bf, a3.s37bf);                \
    (D)[(i) * 6 + 4] = (float16)(b0.s048c, b1.s048c, b2.s048c, b3.s048c);                \
    (D)[(i) * 6 + 5] = (float16)(b0.s159d, b1.s159d, b2.s159d, b3.s159d);                \
  } while (0)
#else
#define WINO_IN_ROW(D, L, G, i)                                          \
  do {                                                                \
    for (int j = 0; j < 6; j++) {                                     \
      float lanes[CONV_VW];                                           \
      for (int l = 0; l < CONV_VW; l++) lanes[l] = G(4 * l + j);      \
      (D)[(i) * 6 + j] = VLOAD(lanes);                                  \
    }                                                                 \
  } while (0)
#endif
#define WINO_IN_COLS (4 * CONV_VW + 4)

/* Elements x .. x+15 of an image row (a null pointer: a row outside the image), zero outside [0, W), for
 * the rows spx_wino_in does not load whole (outside the image, or touching its plane's first or
 * last element). */
static inline __attribute__((always_inline)) float16 wino_row16(const __global float *row, int x, int W) {
  if (!row || x >= W || x + 16 <= 0) return (float16)0.0f;
  if (x >= 0 && x + 16 <= W) return vload16(0, row + x);
  /* lane by lane, in a loop the compiler keeps rolled: unrolled, it hoisted the sixteen lanes'
   * bounds tests of every piece out of the row loop into each work-item's prologue, where they
   * cost more than the transform (a piece crossing the row's start or end, in those few rows) */
  float t[16];
#pragma unroll 1
  for (int l = 0; l < 16; l++) t[l] = x + l >= 0 && x + l < W ? row[x + l] : 0.0f;
  return vload16(0, t);
}
/* Element x of an image row (a null pointer: outside the image), zero outside [0, W). */
static inline __attribute__((always_inline)) float wino_row1(const __global float *row, int x, int W) {
  return row && x >= 0 && x < W ? row[x] : 0.0f;
}

/* Input transform, read straight from the input x [N][C][H][W] (from x_off): the patch of tile
 * (ty, tx) covers rows 4ty-1 .. 4ty+4 and columns 4tx-1 .. 4tx+4, zero outside the image (the
 * padding). Tiles are numbered t = ty*TWp + tx. Row-padded (TWp = TW rounded up to CONV_VW) the
 * CONV_VW tiles of one work-item lie in one tile row; packed (TWp = TW, lib/nn/conv2d_winograd.c
 * CONV_WINO_PACK: no GEMM columns spent on padding tiles) a work-item's tiles may run into the
 * next rows, and it loads each row segment separately. A work-item whose rows and columns (with the
 * loads' overrun) lie inside the image loads them as vectors; the others (image borders, tiles
 * past TW) load each 16-float piece that lies inside as a vector and gather the rest with bounds
 * tests. The values are the same
 * either way, as were those of the zero-padded copy this kernel used to read: same bits.
 * Global: (Tp / CONV_VW, C, N); tiles past TH*TWp are written as zeros. */
__kernel void spx_wino_in(const __global float *x, ulong x_off, __global float *V, int C, int H, int W, int TWp, int T,
                          int Tp, int TWs) {
  const int g = (int)get_global_id(0), c = (int)get_global_id(1), n = (int)get_global_id(2);
  const int TWg = TWp / CONV_VW, ty = g / TWg, tx0 = (g - ty * TWg) * CONV_VW;
  const int col0 = ty * TWs + tx0; /* row-padded (TWs = TWp): col0 = g * CONV_VW */
  __global float *v = V + ((size_t)n * C + c) * 36 * Tp + col0;
  const size_t es = (size_t)Tp;
  vf d[36], r[36];
  if (col0 >= T) { /* row-padded: the GEMM's padding columns past T are zeros */
    if (TWs == TWp && col0 < Tp)
      for (int e = 0; e < 36; e++) VSTORE((vf)0.0f, v + e * es);
    return;
  }
  const int y0 = 4 * ty - 1, x0 = 4 * tx0 - 1;
  const __global float *xc = x + x_off + ((size_t)n * C + c) * H * W;
  if (y0 >= 0 && y0 + 5 < H && x0 >= 0 && x0 + WINO_IN_COLS <= W) {
    for (int i = 0; i < 6; i++) {
      const __global float *p = xc + (size_t)(y0 + i) * W + x0;
#define LD_IN(o) vload16(0, p + (o))
#define G_IN(k) p[k]
      WINO_IN_ROW(d, LD_IN, G_IN, i);
#undef LD_IN
#undef G_IN
    }
  } else {
#if CONV_VW == 16
    /* which lanes of each row piece lie inside the row: the same for the six rows */
    const int16 cx = (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15) + x0;
#define KEEP(o) const int16 keep##o = cx + (o) >= 0 && cx + (o) < W
    KEEP(0);
    KEEP(16);
    KEEP(32);
    KEEP(48);
    KEEP(4);
    KEEP(20);
    KEEP(36);
    KEEP(52);
#undef KEEP
#endif
    for (int i = 0; i < 6; i++) {
      const int yy = y0 + i;
      const __global float *row = yy >= 0 && yy < H ? xc + (size_t)yy * W : (const __global float *)0;
#if CONV_VW == 16
      /* a row inside the image whose pieces all lie inside the plane: whole-vector loads, the
       * lanes outside the row (the neighbouring rows' elements) zeroed by a select */
      if (row && yy * W + x0 >= 0 && yy * W + x0 + WINO_IN_COLS <= H * W) {
#define LD_ROW(o) select((float16)0.0f, vload16(0, row + x0 + (o)), keep##o)
#define G_ROW(k) row[x0 + (k)]
        WINO_IN_ROW(d, LD_ROW, G_ROW, i);
#undef LD_ROW
#undef G_ROW
        continue;
      }
#endif
#define LD_EDGE(o) wino_row16(row, x0 + (o), W)
#define G_EDGE(k) wino_row1(row, x0 + (k), W)
      WINO_IN_ROW(d, LD_EDGE, G_EDGE, i);
#undef LD_EDGE
#undef G_EDGE
    }
  }
  for (int j = 0; j < 6; j++) WINO_BT(vf, (r + j), (d + j), 6); /* columns: r = B^T d */
  for (int i = 0; i < 6; i++) WINO_BT(vf, (d + 6 * i), (r + 6 * i), 1); /* rows: d = r B */
  if (TWs != TWp && tx0 + CONV_VW > TWs) { /* packed: the row's last tiles only (the next row follows) */
    for (int e = 0; e < 36; e++) vstore_head(d[e], TWs - tx0, v + e * es);
    return;
  }
  for (int e = 0; e < 36; e++) VSTORE(d[e], v + e * es);
}

/* Weight transform. w [Cout][Cin][3][3]; GEMM rows (out channels) `cols` (padded to CONV_TM),
 * reduction `red`. flip = 0: out co, reduction ci, g = w[co][ci]; flip = 1 (backward data): out
 * ci, reduction co, g[ky][kx] = w[co][ci][2-ky][2-kx]. U[e][cot][r][m]. Global: red * cols/CONV_TM
 * (one work-item per reduction index and channel tile). */
__kernel void spx_wino_weights(const __global float *w, ulong w_off, __global float *U, int Cout, int Cin, int cols,
                               int flip) {
  const int i = SPX_GID0;
  const int red = flip ? Cout : Cin, ncot = cols / CONV_TM;
  if (i >= red * ncot) return;
  const int r = i % red, cot = i / red;
  const int oc = flip ? Cin : Cout;
  float u[CONV_TM][36];
  for (int m = 0; m < CONV_TM; m++) {
    float g[9];
    wino_filter_of(w + w_off, Cin, oc, cot * CONV_TM + m, r, flip, g);
    wino_filter(g, u[m]);
  }
  for (int e = 0; e < 36; e++) {
    __global float *ue = U + (((size_t)e * ncot + cot) * red + r) * CONV_TM;
    for (int m = 0; m < CONV_TM; m++) ue[m] = u[m][e];
  }
}

/* The 36 GEMMs. Global: dim0 = ncot x (Tp / (CONV_LWS*CONV_TN*CONV_VW)) groups of CONV_LWS
 * (channel tile fastest: consecutive groups reuse the same V tiles), dim1 = N*36. */
__kernel void spx_wino_gemm(const __global float *V, const __global float *U, __global float *M, int Cin, int CoutP,
                            int Tp) {
  const int ncot = CoutP / CONV_TM, grp = (int)get_group_id(0);
  const int cot = grp % ncot, pg = grp / ncot;
  const int lid = (int)get_local_id(0), ne = (int)get_global_id(1), e = ne % 36;
  const int t0 = pg * (CONV_LWS * CONV_TN * CONV_VW) + lid * CONV_VW;
  const __global float *vb = V + ((size_t)(ne / 36) * Cin * 36 + e) * Tp + t0;
  const __global float *ub = U + ((size_t)e * ncot + cot) * Cin * CONV_TM;
  vf acc[CONV_TM][CONV_TN];
#pragma unroll
  for (int m = 0; m < CONV_TM; m++)
#pragma unroll
    for (int j = 0; j < CONV_TN; j++) acc[m][j] = (vf)0.0f;
  for (int ci = 0; ci < Cin; ci++) {
    const __global float *vr = vb + (size_t)ci * 36 * Tp;
    const __global float *ur = ub + ci * CONV_TM;
    vf xv[CONV_TN];
#pragma unroll
    for (int j = 0; j < CONV_TN; j++) xv[j] = VLOAD(vr + j * (CONV_LWS * CONV_VW));
    CONV_TILE_FMA(vf, acc, ur, xv);
  }
  __global float *mb = M + ((size_t)ne * CoutP + cot * CONV_TM) * Tp + t0;
#pragma unroll
  for (int m = 0; m < CONV_TM; m++)
#pragma unroll
    for (int j = 0; j < CONV_TN; j++) VSTORE(acc[m][j], mb + (size_t)m * Tp + j * (CONV_LWS * CONV_VW));
}

/* Output transform + epilogue on CONV_VW tiles of one tile row (packed tiles across rows: lane by
 * lane). Global: (ceil(T / CONV_VW), Cout, N). */
static inline vf wino_epi(vf v, const __global float *yo, int flags, float bv, float sc, float sh) {
  if (flags & FL_ACCUM) v = VLOAD(yo) + v;
  if (flags & FL_BIAS) v = v + bv;
  if (flags & FL_SCALE) v = v * sc + sh;
  if (flags & FL_RELU) v = fmax(v, (vf)0.0f);
  return v;
}
__kernel void spx_wino_out(const __global float *M, __global float *y, ulong y_off, const __global float *bias,
                           ulong b_off, const __global float *scale, ulong sc_off, const __global float *shift,
                           ulong sh_off, int Cout, int CoutP, int H, int W, int TWp, int T, int Tp, int flags, int TWs) {
  const int g = (int)get_global_id(0), co = (int)get_global_id(1), n = (int)get_global_id(2);
  const int TWg = TWp / CONV_VW, ty = g / TWg, tx0 = (g - ty * TWg) * CONV_VW, col0 = ty * TWs + tx0;
  if (col0 >= T) return;
  vf m[36], r[24];
  const __global float *mp = M + ((size_t)n * 36 * CoutP + co) * Tp + col0;
  const size_t es = (size_t)CoutP * Tp;
  /* packed: the row's last tiles. Their lanes past the row end (the next row's first tiles, or
   * the GEMM's padding columns) only feed outputs past W, which are not written: a whole vector
   * is loaded where it lies inside M's Tp columns, lane by lane only at the end of M. */
  if (TWs != TWp && tx0 + CONV_VW > TWs && col0 + CONV_VW > Tp) {
    for (int e = 0; e < 36; e++) {
      float lanes[CONV_VW];
      for (int l = 0; l < CONV_VW; l++) lanes[l] = l < TWs - tx0 ? mp[e * es + l] : 0.0f;
      m[e] = VLOAD(lanes);
    }
  } else {
    for (int e = 0; e < 36; e++) m[e] = VLOAD(mp + e * es);
  }
  /* r = A^T m (4x6), then o = r A (4x4) */
  WINO_AT_COLS(vf, r, m);
  float bv, sc, sh;
  wino_epi_consts(flags, bias, b_off, scale, sc_off, shift, sh_off, co, &bv, &sc, &sh);
  const int ox0 = 4 * tx0;
  __global float *yc = y + y_off + ((size_t)n * Cout + co) * H * W;
  for (int i = 0; i < 4; i++) {
    const int oy = 4 * ty + i;
    if (oy >= H) break;
    WINO_AT(vf, o0, o1, o2, o3, (r + 6 * i), 1);
    __global float *yr = yc + (size_t)oy * W + ox0;
#if CONV_VW == 16
    /* interleave: output column 4l + j of lane l */
    const uint16 lo = (uint16)(0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6, 22, 7, 23);
    const uint16 hi = lo + (uint16)8;
    float16 p01l = shuffle2(o0, o1, lo), p01h = shuffle2(o0, o1, hi);
    float16 p23l = shuffle2(o2, o3, lo), p23h = shuffle2(o2, o3, hi);
    const uint16 q0 = (uint16)(0, 1, 16, 17, 2, 3, 18, 19, 4, 5, 20, 21, 6, 7, 22, 23);
    const uint16 q1 = q0 + (uint16)8;
    float16 out[4] = {shuffle2(p01l, p23l, q0), shuffle2(p01l, p23l, q1), shuffle2(p01h, p23h, q0),
                      shuffle2(p01h, p23h, q1)};
    if (ox0 + 64 <= W) {
      for (int k = 0; k < 4; k++) vstore16(wino_epi(out[k], yr + 16 * k, flags, bv, sc, sh), 0, yr + 16 * k);
    } else if (!(flags & FL_ACCUM)) { /* the row's end: whole-vector epilogue, the first lanes stored */
      for (int k = 0; k < 4 && ox0 + 16 * k < W; k++)
        vstore_head(wino_epi(out[k], yr + 16 * k, flags, bv, sc, sh), W - ox0 - 16 * k, yr + 16 * k);
    } else {
      for (int k = 0; k < 4; k++) {
        float tmp[16];
        vstore16(out[k], 0, tmp);
        for (int l = 0; l < 16; l++) {
          if (ox0 + 16 * k + l >= W) break;
          wino_epi1(tmp[l], yr + 16 * k + l, flags, bv, sc, sh);
        }
      }
    }
#else
    float oo[4][CONV_VW];
    VSTORE(o0, oo[0]);
    VSTORE(o1, oo[1]);
    VSTORE(o2, oo[2]);
    VSTORE(o3, oo[3]);
    for (int l = 0; l < CONV_VW; l++)
      for (int j = 0; j < 4; j++) {
        if (ox0 + 4 * l + j >= W) break;
        wino_epi1(oo[j][l], yr + 4 * l + j, flags, bv, sc, sh);
      }
#endif
  }
}
