/* The GEMM engine of the GPU class (tunable CONV_GEMM; host: lib/nn/conv2d_gemm.c; reference:
 * lib/nn/conv2d_ref.c; tests: tests/test_nn_conv2d_gemm.c). Stride-1 convolutions as GEMMs whose
 * operands are both staged in local memory, two slices at a time, and read from there into a
 * register tile on each side (the design of CLBlast's Xgemm and dlprimitives' convolutions):
 *
 *   forward / data gradient (spx_gemm_conv): C[m][q] = sum_k A[k][m] B[k][q], M = output channels,
 *     N = pixels of the "virtual grid" of kernels/conv2d.cl (q = oy*Wp + ox over the zero-padded
 *     input, columns ox >= Wo computed and dropped), K = k*k*Cin in tap-major order (k = tap*Cin + ci),
 *     A = the weights packed by spx_gemm_pack ([tap][ci][Mp], flipped and transposed for the data
 *     gradient), B[k][q] = xp[ci][q + ky*Wp + kx]: an implicit im2col, no copy of it is made.
 *     Epilogue as conv2d.cl's: accumulate, bias, batch-norm scale / shift, ReLU.
 *   weight gradient (spx_gemm_dw): C[co][j] = sum_q dyq[co][q] xp[ci][q + ky*Wp + kx], j = ci*k*k + tap,
 *     the reduction over the pixels of every image split into chunks of CONV_DW_QC (partials).
 *   spx_gemm_reduce: the split partials summed in split order (fixed: same bits every run), then the
 *     forward's epilogue, or added to dw.
 *
 * Tiling: a work-group of (BM/TM) x (BN/TN) work-items owns a BM x BN tile of C; a work-item owns
 * TM x TN of it, as float4 runs 4*WM (rows) and 4*WN (columns) apart, so the float4 reads of a
 * local row by neighbouring work-items are adjacent (no bank conflicts). The lanes of a warp are
 * laid out 4 (rows) x 8 (columns): per reduction step a warp reads 64 bytes of A (broadcast) and
 * 128 bytes of B per float4 column run. The reduction runs in slices of KS steps: while the
 * work-group multiplies slice s from one local buffer, each work-item holds its share of slice
 * s+1 in registers (loaded from global memory along the pixels: coalesced) and stores it into the
 * other buffer after; one barrier per slice. Every sum runs in a fixed order with fma. */
#include "conv2d_common.h"
#include "winograd_tf.h"

#ifndef CONV_GEMM_BM
#define CONV_GEMM_BM 64
#endif
#ifndef CONV_GEMM_BN
#define CONV_GEMM_BN 128
#endif
#ifndef CONV_GEMM_TM
#define CONV_GEMM_TM 4
#endif
#ifndef CONV_GEMM_TN
#define CONV_GEMM_TN 8
#endif
#ifndef CONV_GEMM_KS
#define CONV_GEMM_KS 16
#endif
#define GBM CONV_GEMM_BM
#define GBN CONV_GEMM_BN
#define GTM CONV_GEMM_TM
#define GTN CONV_GEMM_TN
#define GKS CONV_GEMM_KS
#define GWM (GBM / GTM)         /* work-items along the rows */
#define GWN (GBN / GTN)         /* ... along the columns */
#define GWG (GWM * GWN)         /* work-group size */
#define GLA (GBM + 4)           /* local row of A (floats; float4-aligned) */
#define GLB (GBN + 4)
#define GSA (GKS * GLA)         /* one slice of A in local memory */
#define GSB (GKS * GLB)
#define GFA (GKS * GBM / 4 / GWG) /* forward: float4s of A per work-item and slice */
#define GFB (GKS * GBN / GWG)     /* forward: floats of B per work-item and slice */

#if GBM % GTM == 0 && GBN % GTN == 0 && GWM % 4 == 0 && GWN % 8 == 0 && GTM % 4 == 0 && GTN % 4 == 0 && \
    (GKS * GBM / 4) % GWG == 0 && (GKS * GBN) % GWG == 0 && GWG % GKS == 0

/* The work-item's place in the grid of register tiles: 4 x 8 lanes per warp, warps row-major. */
static inline __attribute__((always_inline)) void g_place(int lid, int *tm, int *tn) {
  const int lane = lid % 32, warp = lid / 32, wn = warp % (GWN / 8), wm = warp / (GWN / 8);
  *tm = wm * 4 + lane / 8;
  *tn = wn * 8 + lane % 8;
}

/* The work-item's place (g_place) and its register tile zeroed. */
static inline __attribute__((always_inline)) void g_start(int lid, int *tm, int *tn, float acc[GTM][GTN]) {
  g_place(lid, tm, tn);
#pragma unroll
  for (int i = 0; i < GTM; i++)
#pragma unroll
    for (int j = 0; j < GTN; j++) acc[i][j] = 0.0f;
}

/* acc += the slice (as, bs) of local memory: per step, TM values of A and TN of B as float4s. */
static inline __attribute__((always_inline)) void g_mma(const __local float4 *as, const __local float4 *bs, int tm,
                                                        int tn, float acc[GTM][GTN]) {
#pragma unroll
  for (int kk = 0; kk < GKS; kk++) {
    float a[GTM], b[GTN];
#pragma unroll
    for (int g = 0; g < GTM / 4; g++) {
      const float4 v = as[kk * (GLA / 4) + tm + GWM * g];
      a[4 * g] = v.s0, a[4 * g + 1] = v.s1, a[4 * g + 2] = v.s2, a[4 * g + 3] = v.s3;
    }
#pragma unroll
    for (int g = 0; g < GTN / 4; g++) {
      const float4 v = bs[kk * (GLB / 4) + tn + GWN * g];
      b[4 * g] = v.s0, b[4 * g + 1] = v.s1, b[4 * g + 2] = v.s2, b[4 * g + 3] = v.s3;
    }
#pragma unroll
    for (int i = 0; i < GTM; i++)
#pragma unroll
      for (int j = 0; j < GTN; j++) acc[i][j] = fma(a[i], b[j], acc[i][j]);
  }
}

/* Row (or column) of a register-tile entry: float4 run g = i / 4 of the work-item at t. */
#define G_ROW(t, i) (4 * (t) + 4 * GWM * ((i) / 4) + (i) % 4)
#define G_COL(t, j) (4 * (t) + 4 * GWN * ((j) / 4) + (j) % 4)

/* Where a forward slice starts: its input channel c0 (of Cin), the A row tap*Cin + c0 of the packed
 * weights, the offset ky*Wp + kx of its tap in the padded input, and kx. */
typedef struct gslice {
  int c0, arow, toff, kx;
} gslice;

static inline __attribute__((always_inline)) gslice g_slice_at(int sl, int nspt, int Cin, int k, int Wp) {
  const int tap = sl / nspt, c0 = (sl - tap * nspt) * GKS, kx = tap % k;
  gslice g = {c0, tap * Cin + c0, (tap / k) * Wp + kx, kx};
  return g;
}

/* the next slice: KS more channels, or the next tap (no divisions in the loop) */
static inline __attribute__((always_inline)) void g_slice_next(gslice *g, int Cin, int k, int Wp) {
  g->c0 += GKS, g->arow += GKS;
  if (g->c0 >= Cin) {
    g->arow += Cin - g->c0, g->c0 = 0, g->kx++, g->toff++;
    if (g->kx == k) g->kx = 0, g->toff += Wp - k;
  }
}

/* Forward slice g into registers: A rows arow + r of the packed weights (float4 runs along the
 * output channels), B rows c0 + r of the input shifted by the tap (along the pixels). No tests:
 * the reduction channels are a whole number of slices (the host pads them with zero planes and
 * zero weights), and a column past the last pixel reads the last pixel's inputs instead (its sums
 * are dropped). wb: the work-group's first weight column (float4s), xq: its first pixel of
 * channel 0, nq: the pixels left from there. */
static inline __attribute__((always_inline)) void g_fwd_load(const __global float4 *wb, const __global float *xq,
                                                             gslice g, int Mp4, int nq, int plane, int lid,
                                                             float4 ra[GFA], float rb[GFB]) {
  const __global float4 *wr = wb + g.arow * Mp4;
  const __global float *xr = xq + g.c0 * plane + g.toff;
#pragma unroll
  for (int i = 0; i < GFA; i++) {
    const int e = lid + i * GWG;
    ra[i] = wr[e / (GBM / 4) * Mp4 + e % (GBM / 4)];
  }
#pragma unroll
  for (int i = 0; i < GFB; i++) {
    const int e = lid + i * GWG;
    rb[i] = xr[e / GBN * plane + min(e % GBN, nq - 1)];
  }
}

static inline __attribute__((always_inline)) void g_fwd_store(__local float4 *as, __local float4 *bs, int lid,
                                                              const float4 ra[GFA], const float rb[GFB]) {
  __local float *bf = (__local float *)bs;
#pragma unroll
  for (int i = 0; i < GFA; i++) {
    const int e = lid + i * GWG, r = e / (GBM / 4), g = e % (GBM / 4);
    as[r * (GLA / 4) + g] = ra[i];
  }
#pragma unroll
  for (int i = 0; i < GFB; i++) {
    const int e = lid + i * GWG, r = e / GBN, c = e % GBN;
    bf[r * GLB + c] = rb[i];
  }
}

/* Forward or data gradient. xp: [N][Cin][plane] from x_off (rows of Wp; zero-padded by
 * spx_gemm_pad, or the input itself for a 1x1 pad-0 layer), Cin a multiple of KS; wg:
 * spx_gemm_pack's A ([k*k*Cin][Mp], Mp a multiple of BM); y [N][M][Ho][Wo] from y_off. Reduction split: work-group (., ., s) sums slices
 * [s*spl, (s+1)*spl) of the k*k*Cin/KS and writes to y + s*split_stride (the host passes the
 * partials' buffer and flags 0 when it splits). GEMM n of dim1 takes xp, wg and y from n*x_bs,
 * n*w_bs and n*y_bs floats on (a convolution: the images, x_bs = Cin*plane, w_bs = 0, y_bs =
 * M*Ho*Wo; Winograd: its 36 GEMMs, kernels/conv2d_winograd.cl). Global: dim0 = Mp/BM *
 * ceil(Ho*Wp/BN) groups of BM/TM*BN/TN (row tile fastest: consecutive groups share the input
 * pixels), dim1 = N, dim2 = splits. */
__kernel __attribute__((reqd_work_group_size(GWG, 1, 1))) void spx_gemm_conv(
    const __global float *xp, ulong x_off, const __global float *wg, __global float *y, ulong y_off,
    ulong split_stride, const __global float *bias, ulong b_off, const __global float *scale, ulong sc_off,
    const __global float *shift, ulong sh_off, int Cin, int M, int Mp, int k, int Wp, int plane, int Ho, int Wo,
    int flags, int spl, ulong x_bs, ulong w_bs, ulong y_bs) {
  __local float4 as[2 * GSA / 4], bs[2 * GSB / 4];
  const int lid = (int)get_local_id(0), n = (int)get_group_id(1), s = (int)get_group_id(2);
  const int nmt = Mp / GBM, grp = (int)get_group_id(0), m0 = (grp % nmt) * GBM, q0 = (grp / nmt) * GBN;
  const int nspt = (Cin + GKS - 1) / GKS, sl0 = s * spl, sl1 = min(k * k * nspt, sl0 + spl);
  const int nq = Ho * Wp - q0, Mp4 = Mp / 4; /* pixels left from q0 */
  const __global float *xq = xp + x_off + n * x_bs + q0;
  const __global float4 *wb = (const __global float4 *)(wg + n * w_bs) + m0 / 4;
  int tm, tn;
  float acc[GTM][GTN];
  g_start(lid, &tm, &tn, acc);
  float4 ra[GFA];
  float rb[GFB];
  gslice g = g_slice_at(sl0, nspt, Cin, k, Wp);
  if (sl0 < sl1) {
    g_fwd_load(wb, xq, g, Mp4, nq, plane, lid, ra, rb);
    g_fwd_store(as, bs, lid, ra, rb);
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int sl = sl0; sl < sl1; sl++) {
    const int cur = (sl - sl0) & 1, more = sl + 1 < sl1;
    if (more) {
      g_slice_next(&g, Cin, k, Wp);
      g_fwd_load(wb, xq, g, Mp4, nq, plane, lid, ra, rb);
    }
    g_mma(as + cur * (GSA / 4), bs + cur * (GSB / 4), tm, tn, acc);
    if (more) g_fwd_store(as + (cur ^ 1) * (GSA / 4), bs + (cur ^ 1) * (GSB / 4), lid, ra, rb);
    barrier(CLK_LOCAL_MEM_FENCE);
  }

  /* epilogue: columns back to (oy, ox), padding columns dropped; guards, not breaks, so the
   * loops unroll and acc stays in registers */
  const int hw = Ho * Wo;
  __global float *yn = y + y_off + (size_t)s * split_stride + n * y_bs;
  int o[GTN];
#pragma unroll
  for (int j = 0; j < GTN; j++) {
    const int q = q0 + G_COL(tn, j), oy = q / Wp, ox = q - oy * Wp;
    o[j] = oy < Ho && ox < Wo ? oy * Wo + ox : -1;
  }
#pragma unroll
  for (int i = 0; i < GTM; i++) {
    const int m = m0 + G_ROW(tm, i);
    if (m >= M) continue;
    const float b = (flags & FL_BIAS) ? bias[b_off + m] : 0.0f, sc = (flags & FL_SCALE) ? scale[sc_off + m] : 1.0f;
    const float sh = (flags & FL_SHIFT) ? shift[sh_off + m] : 0.0f;
    __global float *ym = yn + (size_t)m * hw;
#pragma unroll
    for (int j = 0; j < GTN; j++) {
      if (o[j] < 0) continue;
      float v = acc[i][j];
      if (flags & FL_ACCUM) v = ym[o[j]] + v;
      if (flags & FL_BIAS) v = v + b;
      if (flags & FL_SCALE) v = v * sc + sh;
      if (flags & FL_RELU) v = fmax(v, 0.0f);
      ym[o[j]] = v;
    }
  }
}

/* Weight gradient: per work-item, its rows of both operands are fixed for the whole reduction (A:
 * output channels, B: weight columns j = ci*k*k + tap), and its lane of a slice is one pixel q
 * (lid % KS): loads run along the pixels, and are stored transposed ([step][row]) in local memory. */
#define GDA (GBM * GKS / GWG) /* floats of A per work-item and slice */
#define GDB (GBN * GKS / GWG)
#define GDR (GWG / GKS)       /* rows loaded per pass */

/* Partials part[c][co][j] = sum over the images n and the pixels q of chunk c of
 * dyq[n][co][q] * xp[n][ci][q + ky*Wp + kx] (dyq: dy on the virtual grid, zeros in its padding
 * columns, planes of Qd; xp: the padded input). Global: dim0 = ceil(Cout/BM) * ceil(Cin*k*k/BN)
 * groups of BM/TM*BN/TN, dim1 = chunks of qchunk pixels. */
__kernel __attribute__((reqd_work_group_size(GWG, 1, 1))) void spx_gemm_dw(
    const __global float *xp, ulong x_off, const __global float *dyq, ulong dy_off, __global float *part, int N,
    int Cin, int Cout, int k, int Wp, int plane, int Qd, int qchunk) {
  __local float4 as[2 * GSA / 4], bs[2 * GSB / 4];
  const int lid = (int)get_local_id(0), c = (int)get_group_id(1), kk2 = k * k, Kdim = Cin * kk2;
  const int nmt = (Cout + GBM - 1) / GBM, grp = (int)get_group_id(0), m0 = (grp % nmt) * GBM, j0 = (grp / nmt) * GBN;
  const int lq = lid % GKS, lr = lid / GKS;
  const int qa = c * qchunk, qe = min(qa + qchunk, Qd), nq = (qe - qa + GKS - 1) / GKS;
  /* rows past Cout / Kdim load a real row's values (their sums are not stored) */
  int aoff[GDA], boff[GDB];
#pragma unroll
  for (int i = 0; i < GDA; i++) aoff[i] = min(m0 + lr + i * GDR, Cout - 1) * Qd;
#pragma unroll
  for (int i = 0; i < GDB; i++) {
    const int j = min(j0 + lr + i * GDR, Kdim - 1), ci = j / kk2, t = j - ci * kk2;
    boff[i] = ci * plane + (t / k) * Wp + t % k;
  }
  int tm, tn;
  float acc[GTM][GTN];
  g_start(lid, &tm, &tn, acc);
  float ra[GDA], rb[GDB];
  const int nsl = N * nq;
  for (int sl = -1; sl < nsl; sl++) {
    const int cur = sl & 1;
    if (sl + 1 < nsl) { /* slice sl + 1 into registers */
      const int n = (sl + 1) / nq, q = qa + ((sl + 1) - n * nq) * GKS + lq, ok = q < qe;
      const __global float *dn = dyq + dy_off + (size_t)n * Cout * Qd + q, *xn = xp + x_off + (size_t)n * Cin * plane + q;
#pragma unroll
      for (int i = 0; i < GDA; i++) ra[i] = ok ? dn[aoff[i]] : 0.0f;
#pragma unroll
      for (int i = 0; i < GDB; i++) rb[i] = ok ? xn[boff[i]] : 0.0f;
    }
    if (sl >= 0) g_mma(as + cur * (GSA / 4), bs + cur * (GSB / 4), tm, tn, acc);
    if (sl + 1 < nsl) {
      __local float *af = (__local float *)(as + (cur ^ 1) * (GSA / 4)), *bf = (__local float *)(bs + (cur ^ 1) * (GSB / 4));
#pragma unroll
      for (int i = 0; i < GDA; i++) af[lq * GLA + lr + i * GDR] = ra[i];
#pragma unroll
      for (int i = 0; i < GDB; i++) bf[lq * GLB + lr + i * GDR] = rb[i];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  __global float *pc = part + (size_t)c * Cout * Kdim;
#pragma unroll
  for (int i = 0; i < GTM; i++) {
    const int m = m0 + G_ROW(tm, i);
    if (m >= Cout) continue;
#pragma unroll
    for (int j = 0; j < GTN; j++) {
      const int jj = j0 + G_COL(tn, j);
      if (jj < Kdim) pc[(size_t)m * Kdim + jj] = acc[i][j];
    }
  }
}
#endif

/* y[i] = epilogue((accumulate ? y[i] : 0) + sum over s in order of part[s][i]), channel (i / hw) % M
 * (the forward's split partials; the weight gradient's chunks with hw = the weights per channel and
 * FL_ACCUM only). Global: count. */
__kernel void spx_gemm_reduce(const __global float *part, int count, int nsplit, __global float *y, ulong y_off,
                              int hw, int M, const __global float *bias, ulong b_off, const __global float *scale,
                              ulong sc_off, const __global float *shift, ulong sh_off, int flags) {
  const int i = SPX_GID0;
  if (i >= count) return;
  float v = 0.0f;
  for (int s = 0; s < nsplit; s++) v += part[(size_t)s * count + i];
  const int m = (i / hw) % M;
  __global float *yo = y + y_off + i;
  if (flags & FL_ACCUM) v = *yo + v;
  if (flags & FL_BIAS) v = v + bias[b_off + m];
  if (flags & FL_SCALE) v = v * scale[sc_off + m] + ((flags & FL_SHIFT) ? shift[sh_off + m] : 0.0f);
  if (flags & FL_RELU) v = fmax(v, 0.0f);
  *yo = v;
}

/* A of the GEMM: wg[(tap*Rp + r)*Mp + m] for rows r < Rp, columns m < Mp (zero for r >= R and for
 * m past the real columns):
 *  flip = 0 (forward): R = Cin, m = co:  w[co][r][ky][kx]
 *  flip = 1 (data gradient): R = Cout, m = ci:  w[r][m][k-1-ky][k-1-kx]
 * with tap = ky*k + kx. Global: k*k*Rp*Mp. */
__kernel void spx_gemm_pack(const __global float *w, ulong w_off, __global float *wg, int Cout, int Cin, int k, int Rp,
                            int Mp, int flip) {
  const int i = SPX_GID0, kk2 = k * k, R = flip ? Cout : Cin;
  if (i >= kk2 * Rp * Mp) return;
  const int m = i % Mp, tr = i / Mp, tap = tr / Rp, r = tr - tap * Rp, ky = tap / k, kx = tap - ky * k;
  float v = 0.0f;
  if (!flip && m < Cout && r < R) v = w[w_off + ((size_t)m * Cin + r) * kk2 + tap];
  if (flip && m < Cin && r < R) v = w[w_off + ((size_t)r * Cin + m) * kk2 + (k - 1 - ky) * k + (k - 1 - kx)];
  wg[i] = v;
}

/* The B operand of a forward or data gradient: src [N][C][H][W] (from src_off) into dst
 * [N][Cp][plane], element (sy, sx) of a plane at row top + sy*d, column left + sx*d of rows of Wp;
 * zeros elsewhere, in the planes C .. Cp-1 and in the guard after the last plane (the host fills
 * that). Global: (Wp, ceil(plane / Wp), N*Cp). */
__kernel void spx_gemm_pad(const __global float *src, ulong src_off, __global float *dst, int C, int Cp, int H, int W,
                           int Wp, int plane, int top, int left, int d) {
  const int xx = (int)get_global_id(0), yy = (int)get_global_id(1), nc = (int)get_global_id(2);
  const int r = yy * Wp + xx, n = nc / Cp, c = nc - n * Cp;
  if (xx >= Wp || r >= plane) return;
  int sy = yy - top, sx = xx - left, ok = c < C && sy >= 0 && sx >= 0 && sy % d == 0 && sx % d == 0;
  sy /= d, sx /= d;
  dst[(size_t)nc * plane + r] = ok && sy < H && sx < W ? src[src_off + (((size_t)n * C + c) * H + sy) * W + sx] : 0.0f;
}

/* Winograd's transformed weights as the A of its 36 GEMMs (lib/nn/conv2d_winograd.c on the
 * engine): U[e][r][Mp] = (G g G^T)[e] of column m and reduction index r, flip as winograd_tf.h's
 * wino_filter_of (zero past the real columns). Global: R * Mp, m fastest (R = Cin, or Cout when
 * flipped). */
__kernel void spx_gemm_wino_pack(const __global float *w, ulong w_off, __global float *U, int Cout, int Cin, int Mp,
                                 int flip) {
  const int i = SPX_GID0, red = flip ? Cout : Cin;
  if (i >= red * Mp) return;
  const int r = i / Mp, m = i - r * Mp;
  float u[36];
  wino_u_of(w + w_off, Cin, flip ? Cin : Cout, m, r, flip, u);
#pragma unroll
  for (int e = 0; e < 36; e++) U[((size_t)e * red + r) * Mp + m] = u[e];
}
