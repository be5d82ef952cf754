/* The stride-1 'same' forwards (3x3 pad 1, 1x1 pad 0) read straight from the unpadded input, with
 * no zero-padded copy of it (#included by conv2d.cl and conv2d_narrow.cl after conv2d_common.h,
 * so each register tile gets its own copy; host: lib/nn/conv2d_direct.c, tunable CONV_NOPAD).
 *
 * Same register tiling and group order as conv_fwd, on the virtual grid q = oy*W + ox of the
 * input itself (no padding columns: every q is an output). The tap (ky, kx) of output q reads
 * x[ci*H*W + q + (ky-P)*W + (kx-P)] (P = (K-1)/2), i.e. contiguous vectors as in conv_fwd, except
 * where the tap falls outside the image. Each work-item classifies its own pixels once:
 *  - NP_PLAIN: every tap of every lane lies in the (n, ci) plane and no lane sits in the first or
 *    last column: plain vector loads (most work-items);
 *  - NP_MASK: the same, but some lane is at ox = 0 / ox = W-1: its kx = 0 / kx = K-1 taps, which
 *    read the neighbouring row's edge, are replaced by zero with a select;
 *  - NP_SAFE: the work-item touches the first or last row or the end of the grid (a few
 *    work-items per image): a tap vector that lies inside the plane is loaded and masked as on
 *    NP_MASK; only one that crosses the plane's start or end gathers its lanes one by one with
 *    bounds tests. (A lane whose tap leaves the image through the top or bottom reads before the
 *    plane's start or past its end, except the corner taps (dx = +1 at the last column, dx = -1
 *    at the first), which the column masks zero; lanes past the grid are dropped at the store.)
 * A zero tap is fma(w, 0, acc), exactly what conv_fwd does with the padded zeros, in the same
 * (ci, ky, kx) order: the results are bit-identical to the padded path. */
#define NP_PLAIN 0
#define NP_MASK 1
#define NP_SAFE 2

#if CONV_VW == 16
typedef int16 vi_np;
#define VLOADI_NP(p) vload16(0, (p))
#elif CONV_VW == 8
typedef int8 vi_np;
#define VLOADI_NP(p) vload8(0, (p))
#elif CONV_VW == 4
typedef int4 vi_np;
#define VLOADI_NP(p) vload4(0, (p))
#else
typedef int vi_np;
#define VLOADI_NP(p) (*(p))
#endif

/* Lane l of vector j of a work-item is pixel q0 + j*CONV_LWS*CONV_VW + l. */
#define NP_Q(q0, j) ((q0) + (j) * (CONV_LWS * CONV_VW))

/* One tap of vector j on the safe path: lanes outside the image (or past the grid) give zero. */
static inline vf np_gather(const __global float *xc, const int oy[CONV_VW], const int ox[CONV_VW], int H, int W,
                           int dy, int dx) {
  float t[CONV_VW];
  for (int l = 0; l < CONV_VW; l++) {
    int iy = oy[l] + dy, ix = ox[l] + dx;
    t[l] = (iy >= 0 && iy < H && ix >= 0 && ix < W) ? xc[iy * W + ix] : 0.0f;
  }
  return VLOAD(t);
}

static inline __attribute__((always_inline)) void conv_fwd_np_body(
    const __global float *xn, const __global float *wpk, __global float *y, const __global float *bias,
    const __global float *scale, const __global float *shift, int Cin, int Cout, int H, int W, int flags, int ci0,
    int ci1, int cst, int ntl, int n, int q0, const int K, const int MODE) {
  const int P = (K - 1) / 2, HW = H * W;
  vi_np mL[CONV_TN], mR[CONV_TN];
  int oy[CONV_TN][CONV_VW], ox[CONV_TN][CONV_VW];
  if (MODE != NP_PLAIN) {
#pragma unroll
    for (int j = 0; j < CONV_TN; j++) {
      int tl[CONV_VW], tr[CONV_VW];
      for (int l = 0; l < CONV_VW; l++) {
        int q = NP_Q(q0, j) + l, yy = q / W, xx = q - yy * W;
        /* past the grid: a row no tap reaches, so the lane reads zeros (its output is dropped) */
        oy[j][l] = q < HW ? yy : H + K, ox[j][l] = xx;
        tl[l] = xx == 0 ? -1 : 0;
        tr[l] = xx == W - 1 ? -1 : 0;
      }
      mL[j] = VLOADI_NP(tl), mR[j] = VLOADI_NP(tr);
    }
  }
  const vf zero = (vf)0.0f;
  vf accs[CONV_CT][CONV_TM][CONV_TN];
  for (int t = 0; t < ntl; t++)
#pragma unroll
    for (int m = 0; m < CONV_TM; m++)
#pragma unroll
      for (int j = 0; j < CONV_TN; j++) accs[t][m][j] = zero;

  for (int cb = ci0; cb < ci1; cb += CONV_CB) {
    const int ce = min(cb + CONV_CB, ci1);
    for (int t = 0; t < ntl; t++) {
      const __global float *wb = wpk + (size_t)(cst * CONV_CT + t) * Cin * K * K * CONV_TM;
      vf acc[CONV_TM][CONV_TN];
      CONV_TILE_COPY(acc, accs[t]);
      for (int ci = cb; ci < ce; ci++) {
        const __global float *xc = xn + (size_t)ci * HW;
        const __global float *wc = wb + ci * K * K * CONV_TM;
#pragma unroll
        for (int ky = 0; ky < K; ky++) {
#pragma unroll
          for (int kx = 0; kx < K; kx++) {
            const __global float *wr = wc + (ky * K + kx) * CONV_TM;
            vf xv[CONV_TN];
#pragma unroll
            for (int j = 0; j < CONV_TN; j++) {
              if (MODE == NP_SAFE && (NP_Q(q0, j) + (ky - P) * W + (kx - P) < 0 ||
                                      NP_Q(q0, j) + (ky - P) * W + (kx - P) + CONV_VW > HW)) {
                xv[j] = np_gather(xc, oy[j], ox[j], H, W, ky - P, kx - P);
              } else {
                /* (pointer + each term: the compiler folds the taps into load displacements) */
                xv[j] = VLOAD(xc + NP_Q(q0, j) + (ky - P) * W + (kx - P));
                if (MODE != NP_PLAIN && P > 0 && kx == 0) xv[j] = select(xv[j], zero, mL[j]);
                if (MODE != NP_PLAIN && P > 0 && kx == K - 1) xv[j] = select(xv[j], zero, mR[j]);
              }
            }
            CONV_TILE_FMA(vf, acc, wr, xv);
          }
        }
      }
      CONV_TILE_COPY(accs[t], acc);
    }
  }
  for (int t = 0; t < ntl; t++)
    conv_fwd_store(accs[t], y, bias, scale, shift, Cout, (cst * CONV_CT + t) * CONV_TM, n, q0, W, H, W, flags);
}

/* Arguments as conv_fwd's with x (unpadded, [N][Cin][H][W] from x_off) in place of xp, Wp = W and
 * plane = H*W. Global as conv_fwd's (pixel groups over H*W). */
static inline __attribute__((always_inline)) void conv_fwd_np(
    const __global float *x, const __global float *wpk, __global float *y, const __global float *bias,
    const __global float *scale, const __global float *shift, int Cin, int Cout, int CoutP, int H, int W,
    int flags, int pix_major, int ci0, int ci1, const int K) {
  const int ncot = CoutP / CONV_TM, ncst = (ncot + CONV_CT - 1) / CONV_CT, grp = (int)get_group_id(0);
  const int npg = (int)get_num_groups(0) / ncst;
  const int cst = pix_major ? grp / npg : grp % ncst, pg = pix_major ? grp % npg : grp / ncst;
  const int ntl = min(CONV_CT, ncot - cst * CONV_CT);
  const int n = (int)get_global_id(1), HW = H * W, P = (K - 1) / 2;
  const int q0 = pg * (CONV_LWS * CONV_TN * CONV_VW) + (int)get_local_id(0) * CONV_VW;
  const __global float *xn = x + (size_t)n * Cin * HW;
  /* lowest and highest element any tap of this work-item reads, relative to its plane */
  const int lo = q0 - P * W - P, hi = NP_Q(q0, CONV_TN - 1) + CONV_VW - 1 + P * W + P;
  int mode = NP_SAFE;
  if (lo >= 0 && hi < HW) {
    mode = NP_PLAIN;
    if (P > 0)
      for (int j = 0; j < CONV_TN; j++) {
        int a = NP_Q(q0, j), b = a + CONV_VW - 1;
        if (a % W == 0 || b % W == W - 1 || a / W != b / W) mode = NP_MASK;
      }
  }
  if (mode == NP_PLAIN)
    conv_fwd_np_body(xn, wpk, y, bias, scale, shift, Cin, Cout, H, W, flags, ci0, ci1, cst, ntl, n, q0, K, NP_PLAIN);
  else if (mode == NP_MASK)
    conv_fwd_np_body(xn, wpk, y, bias, scale, shift, Cin, Cout, H, W, flags, ci0, ci1, cst, ntl, n, q0, K, NP_MASK);
  else
    conv_fwd_np_body(xn, wpk, y, bias, scale, shift, Cin, Cout, H, W, flags, ci0, ci1, cst, ntl, n, q0, K, NP_SAFE);
}

#define CONV_NP_ARGS CONV_FWD_ARGS, ulong x_off
/* (the host passes Ho = H, Wo = W = Wp, plane = H*W) */
#define CONV_NP_PASS(K)                                                                                       \
  xp + x_off, wpk, y + y_off, bias + b_off, scale + sc_off, shift + sh_off, Cin, Cout, CoutP, Ho, Wo, flags,  \
      pix_major, ci0, ci1, K
