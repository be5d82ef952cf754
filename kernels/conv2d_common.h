/* Shared by the conv2d programs (conv2d.cl, conv2d_strided.cl, conv2d_bwd.cl, conv2d_lds.cl,
 * conv2d_winograd.cl, conv2d_winograd_dw.cl; #included by the kernel loader): tunable defaults, the CONV_VW vector type,
 * the epilogue flags, the forward implicit GEMM conv_fwd and its epilogue. The layout and tiling are described at the top of kernels/conv2d.cl. */
#ifndef CONV_VW
#define CONV_VW 1
#endif
#ifndef CONV_TM
#define CONV_TM 4
#endif
#ifndef CONV_TN
#define CONV_TN 4
#endif
#ifndef CONV_LWS
#define CONV_LWS 64
#endif
#ifndef CONV_CT
#define CONV_CT 1
#endif
#ifndef CONV_CB
#define CONV_CB (1 << 30)
#endif
#ifndef CONV_DW_TM
#define CONV_DW_TM 4
#endif
#ifndef CONV_DW_TN
#define CONV_DW_TN 4
#endif
#ifndef CONV_DW_G
#define CONV_DW_G 1
#endif
#ifndef CONV_DW_QB
#define CONV_DW_QB 1024
#endif
#ifndef CONV_RED_WG
#define CONV_RED_WG 64
#endif

/* The weight gradients' register tile (conv2d_bwd.cl, conv2d_winograd_dw.cl): acc[m][j] +=
 * a[m] b[j] (fma) over CONV_DW_TM x CONV_DW_TN, and a copy of such a tile. */
#define DW_TILE_FMA(acc, a, b)                                  \
  _Pragma("unroll") for (int m_ = 0; m_ < CONV_DW_TM; m_++)     \
      _Pragma("unroll") for (int j_ = 0; j_ < CONV_DW_TN; j_++) \
          (acc)[m_][j_] = fma((a)[m_], (b)[j_], (acc)[m_][j_])
#define DW_TILE_COPY(dst, src)                                  \
  _Pragma("unroll") for (int m_ = 0; m_ < CONV_DW_TM; m_++)     \
      _Pragma("unroll") for (int j_ = 0; j_ < CONV_DW_TN; j_++) (dst)[m_][j_] = (src)[m_][j_]
/* The forwards' CONV_TM x CONV_TN register tile: acc[m][j] += wr[m] * xv[j] (m outer, each weight
 * made a T once), and a tile copy. */
#define CONV_TILE_FMA(T, acc, wr, xv)                                                              \
  _Pragma("unroll") for (int m_ = 0; m_ < CONV_TM; m_++) {                                        \
    T wm_ = (T)((wr)[m_]); /* not (T)(wr)[m_]: OpenCL reads that as a vector literal */           \
    _Pragma("unroll") for (int j_ = 0; j_ < CONV_TN; j_++)                                         \
        (acc)[m_][j_] = fma(wm_, (xv)[j_], (acc)[m_][j_]);                                         \
  }
#define CONV_TILE_COPY(dst, src)                                \
  _Pragma("unroll") for (int m_ = 0; m_ < CONV_TM; m_++)        \
      _Pragma("unroll") for (int j_ = 0; j_ < CONV_TN; j_++) (dst)[m_][j_] = (src)[m_][j_]

#if CONV_VW == 16
typedef float16 vf;
#define VLOAD(p) vload16(0, (p))
#define VLOAD2(p) ((float16)(vload16(0, (p)).even, vload16(0, (p) + 16).even))
#define VSTORE(v, p) vstore16((v), 0, (p))
#define VSUM(v) vsum16(v)
#elif CONV_VW == 8
typedef float8 vf;
#define VLOAD(p) vload8(0, (p))
#define VLOAD2(p) vload16(0, (p)).even
#define VSTORE(v, p) vstore8((v), 0, (p))
#define VSUM(v) vsum8(v)
#elif CONV_VW == 4
typedef float4 vf;
#define VLOAD(p) vload4(0, (p))
#define VLOAD2(p) vload8(0, (p)).even
#define VSTORE(v, p) vstore4((v), 0, (p))
#define VSUM(v) vsum4(v)
#elif CONV_VW == 1
typedef float vf;
#define VLOAD(p) (*(p))
#define VLOAD2(p) (*(p))
#define VSTORE(v, p) (*(p) = (v))
#define VSUM(v) (v)
#else
#error "CONV_VW must be 1, 4, 8 or 16"
#endif

#if CONV_VW >= 4
/* fixed-order pairwise horizontal sums (same bits every run) */
static inline float vsum4(float4 v) { return (v.s0 + v.s1) + (v.s2 + v.s3); }
#endif
#if CONV_VW >= 8
static inline float vsum8(float8 v) { return vsum4(v.lo) + vsum4(v.hi); }
#endif
#if CONV_VW >= 16
static inline float vsum16(float16 v) { return vsum8(v.lo) + vsum8(v.hi); }
#endif

/* CONV_VW floats starting at p with element stride S (S is a literal in the hot kernels). */
static inline vf vload_s(const __global float *p, const int S) {
  if (S == 1) return VLOAD(p);
  if (S == 2) return VLOAD2(p);
  float t[CONV_VW];
  for (int l = 0; l < CONV_VW; l++) t[l] = p[l * S];
  return VLOAD(t);
}

/* Lanes 0 .. cnt-1 of v to p[0 .. cnt-1] (0 <= cnt <= CONV_VW): one store per set bit of cnt,
 * rotating the stored lanes out with constant shuffles. (Through a private array instead, the
 * vector written whole and read back by parts, or written by parts and read whole, stalls on
 * store-to-load forwarding: it had been a fifth of the Winograd input transform's time.) */
static inline __attribute__((always_inline)) void vstore_head(vf v, int cnt, __global float *p) {
#if CONV_VW == 16
  if (cnt >= 16) {
    vstore16(v, 0, p);
    return;
  }
  if (cnt & 8) vstore8(v.lo, 0, p), v = (float16)(v.hi, v.lo), p += 8;
  if (cnt & 4) vstore4(v.s0123, 0, p), v = v.s456789abcdef0123, p += 4;
  if (cnt & 2) vstore2(v.s01, 0, p), v = v.s23456789abcdef01, p += 2;
  if (cnt & 1) p[0] = v.s0;
#elif CONV_VW == 8
  if (cnt >= 8) {
    vstore8(v, 0, p);
    return;
  }
  if (cnt & 4) vstore4(v.lo, 0, p), v = (float8)(v.hi, v.lo), p += 4;
  if (cnt & 2) vstore2(v.s01, 0, p), v = v.s23456701, p += 2;
  if (cnt & 1) p[0] = v.s0;
#else
  float t[CONV_VW];
  VSTORE(v, t);
  for (int l = 0; l < cnt; l++) p[l] = t[l];
#endif
}

#define FL_BIAS 1
#define FL_SCALE 2
#define FL_SHIFT 4
#define FL_RELU 8
#define FL_ACCUM 16 /* y = y + acc, before bias / affine / ReLU */

/* Epilogue of one channel tile: map lanes back to (oy, ox), drop the padding columns, apply
 * accumulate / bias / affine / ReLU, store. */
static inline __attribute__((always_inline)) void conv_fwd_store(vf acc[CONV_TM][CONV_TN], __global float *y,
                                                                 const __global float *bias,
                                                                 const __global float *scale,
                                                                 const __global float *shift, int Cout, int co0,
                                                                 int n, int q0, int Wp, int Ho, int Wo, int flags) {
  const int hw = Ho * Wo;
  __global float *yn = y + (size_t)n * Cout * hw;
  float b[CONV_TM], sc[CONV_TM], sh[CONV_TM];
#pragma unroll
  for (int m = 0; m < CONV_TM; m++) {
    int co = min(co0 + m, Cout - 1);
    b[m] = (flags & FL_BIAS) ? bias[co] : 0.0f;
    sc[m] = (flags & FL_SCALE) ? scale[co] : 1.0f;
    sh[m] = (flags & FL_SHIFT) ? shift[co] : 0.0f;
  }
  const int mmax = min(CONV_TM, Cout - co0);
#pragma unroll
  for (int j = 0; j < CONV_TN; j++) {
    int qs = q0 + j * (CONV_LWS * CONV_VW);
    int oy = qs / Wp, ox = qs - oy * Wp;
    if (oy >= Ho) continue; /* guards, not breaks: both loops unroll and acc stays in registers */
    if (ox + CONV_VW <= Wo) { /* whole vector is one run of valid outputs */
      int o = oy * Wo + ox;
#pragma unroll
      for (int m = 0; m < CONV_TM; m++) {
        if (m >= mmax) continue;
        vf v = acc[m][j];
        __global float *yo = yn + (size_t)(co0 + m) * hw + o;
        if (flags & FL_ACCUM) v = VLOAD(yo) + v;
        if (flags & FL_BIAS) v = v + b[m];
        if (flags & FL_SCALE) v = v * sc[m] + sh[m];
        if (flags & FL_RELU) v = fmax(v, (vf)0.0f);
        VSTORE(v, yo);
      }
    } else {
#pragma unroll
      for (int m = 0; m < CONV_TM; m++) {
        if (m >= mmax) continue;
        float t[CONV_VW];
        VSTORE(acc[m][j], t);
        __global float *yc = yn + (size_t)(co0 + m) * hw;
        int ly = oy, lx = ox;
        for (int l = 0; l < CONV_VW; l++) {
          if (ly < Ho && lx < Wo) {
            float v = t[l];
            int o = ly * Wo + lx;
            if (flags & FL_ACCUM) v = yc[o] + v;
            if (flags & FL_BIAS) v = v + b[m];
            if (flags & FL_SCALE) v = v * sc[m] + sh[m];
            if (flags & FL_RELU) v = fmax(v, 0.0f);
            yc[o] = v;
          }
          if (++lx == Wp) lx = 0, ly++;
        }
      }
    }
  }
}

/* Forward. Global: dim0 = (channel super-tiles of CONV_CT tiles) x (pixel groups) work-groups of CONV_LWS,
 * dim1 = N. A group covers CONV_LWS*CONV_TN*CONV_VW consecutive q and one channel tile; the
 * group order is channel-tile-fastest (consecutive groups share input pixels: large images) or
 * pixel-fastest when pix_major (consecutive groups share weights: deep layers with large
 * weights). wpk is packed per channel tile: wpk[cot][kk][TM], contiguous for one work-item.
 * Input channels [ci0, ci1) only: the host may split a deep layer into passes over channel
 * blocks (FL_ACCUM on all passes but the first, epilogue on the last) so the input block stays
 * in cache while each weight panel is read once.
 * KF > 0 fixes the kernel size at compile time (fully unrolled taps), KF = 0 uses k. */
static inline __attribute__((always_inline)) void conv_fwd(
    const __global float *xp, const __global float *wpk, __global float *y, const __global float *bias,
    const __global float *scale, const __global float *shift, int Cin, int Cout, int CoutP, int k, int Wp,
    int plane, int Ho, int Wo, int flags, int pix_major, int ci0, int ci1, const int S, const int KF) {
  const int K = KF > 0 ? KF : k;
  const int ncot = CoutP / CONV_TM, ncst = (ncot + CONV_CT - 1) / CONV_CT, grp = (int)get_group_id(0);
  const int npg = (int)get_num_groups(0) / ncst;
  const int cst = pix_major ? grp / npg : grp % ncst, pg = pix_major ? grp % npg : grp / ncst;
  const int ntl = min(CONV_CT, ncot - cst * CONV_CT);
  const int lid = (int)get_local_id(0);
  const int n = (int)get_global_id(1);
  const int q0 = pg * (CONV_LWS * CONV_TN * CONV_VW) + lid * CONV_VW;
  const __global float *xb = xp + (size_t)n * Cin * plane + (size_t)S * q0;

  /* CONV_CT channel tiles per work-item, walked per block of CONV_CB input channels: the block
   * of input pixels stays in L1 while each tile's accumulators cycle through private memory */
  vf accs[CONV_CT][CONV_TM][CONV_TN];
  for (int t = 0; t < ntl; t++)
#pragma unroll
    for (int m = 0; m < CONV_TM; m++)
#pragma unroll
      for (int j = 0; j < CONV_TN; j++) accs[t][m][j] = (vf)0.0f;

  for (int cb = ci0; cb < ci1; cb += CONV_CB) {
    const int ce = min(cb + CONV_CB, ci1);
    for (int t = 0; t < ntl; t++) {
      const __global float *wb = wpk + (size_t)(cst * CONV_CT + t) * Cin * K * K * CONV_TM;
      vf acc[CONV_TM][CONV_TN];
      CONV_TILE_COPY(acc, accs[t]);
      for (int ci = cb; ci < ce; ci++) {
        const __global float *xc = xb + (size_t)ci * plane;
        const __global float *wc = wb + ci * K * K * CONV_TM;
        for (int ky = 0; ky < K; ky++) {
          for (int kx = 0; kx < K; kx++) {
            const __global float *xr = xc + ky * Wp + kx;
            const __global float *wr = wc + (ky * K + kx) * CONV_TM;
            vf xv[CONV_TN];
#pragma unroll
            for (int j = 0; j < CONV_TN; j++) xv[j] = vload_s(xr + S * j * (CONV_LWS * CONV_VW), S);
            CONV_TILE_FMA(vf, acc, wr, xv);
          }
        }
      }
      CONV_TILE_COPY(accs[t], acc);
    }
  }

  for (int t = 0; t < ntl; t++)
    conv_fwd_store(accs[t], y, bias, scale, shift, Cout, (cst * CONV_CT + t) * CONV_TM, n, q0, Wp, Ho, Wo, flags);
}

/* Pack weights w [Cout][Cin][k][k] into GEMM panels of CONV_TM columns, wpk[ct][r][m] with
 * column c = ct*CONV_TM + m (cols = columns rounded up to CONV_TM, extra columns zero):
 *  flip = 0: rows r = kk = (ci*k+ky)*k+kx, columns co:  w[co][ci][ky][kx]
 *  flip = 1: rows r = (co*k+ky)*k+kx, columns ci:       w[co][ci][k-1-ky][k-1-kx]
 * (flip = 1 is the weight of the backward-data convolution). Global: rows * cols. */
static inline void conv_pack(const __global float *w, ulong w_off, __global float *wpk, int Cout, int Cin, int k,
                             int cols, int flip) {
  int i = SPX_GID0;
  int kk2 = k * k;
  int rows = (flip ? Cout : Cin) * kk2;
  if (i >= rows * cols) return;
  int m = i % CONV_TM, t0 = i / CONV_TM, r = t0 % rows, ct = t0 / rows;
  int c = ct * CONV_TM + m;
  float v = 0.0f;
  if (!flip) {
    if (c < Cout) v = w[w_off + (size_t)c * Cin * kk2 + r];
  } else if (c < Cin) {
    int co = r / kk2, t = r - co * kk2, ky = t / k, kx = t - ky * k;
    v = w[w_off + (((size_t)co * Cin + c) * k + (k - 1 - ky)) * k + (k - 1 - kx)];
  }
  wpk[i] = v;
}
#define CONV_PACK_ARGS                                                                                        \
  const __global float *w, ulong w_off, __global float *wpk, int Cout, int Cin, int k, int cols, int flip

#define CONV_FWD_ARGS                                                                                         \
  const __global float *xp, const __global float *wpk, __global float *y, ulong y_off,                        \
      const __global float *bias, ulong b_off, const __global float *scale, ulong sc_off,                     \
      const __global float *shift, ulong sh_off, int Cin, int Cout, int CoutP, int k, int Wp, int plane,      \
      int Ho, int Wo, int flags, int pix_major, int ci0, int ci1
#define CONV_FWD_PASS                                                                                         \
  xp, wpk, y + y_off, bias + b_off, scale + sc_off, shift + sh_off, Cin, Cout, CoutP, k, Wp, plane, Ho, Wo,   \
      flags, pix_major, ci0, ci1

