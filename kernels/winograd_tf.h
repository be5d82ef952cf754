/* The F(4x4, 3x3) transforms shared by the two Winograd programs (conv2d_winograd.cl: the CPU
 * variant on vectors of tiles; conv2d_winograd_lds.cl: the GPU variant with local memory), so
 * both compute every transformed value with the same expressions in the same order: with the
 * same GEMM summation order their results are bit-identical (tests/test_nn_conv2d_winograd_lds.c).
 * #included after conv2d_common.h (the FL_* epilogue flags). The matrices are Lavin & Gray's for
 * the points 0, +-1, +-2, inf (written out in tests/wino_case.h). */

/* r = B^T d for one column of 6 elements of type T (stride s between elements of the column). */
#define WINO_BT(T, r, d, s)                                                                                  \
  do {                                                                                                       \
    T d0 = d[0], d1 = d[(s)], d2 = d[2 * (s)], d3 = d[3 * (s)], d4 = d[4 * (s)], d5 = d[5 * (s)];          \
    r[0] = 4.0f * d0 - 5.0f * d2 + d4;                                                                      \
    r[(s)] = -4.0f * (d1 + d2) + (d3 + d4);                                                                  \
    r[2 * (s)] = 4.0f * (d1 - d2) + (d4 - d3);                                                               \
    r[3 * (s)] = 2.0f * (d3 - d1) + (d4 - d2);                                                               \
    r[4 * (s)] = 2.0f * (d1 - d3) + (d4 - d2);                                                               \
    r[5 * (s)] = 4.0f * d1 - 5.0f * d3 + d5;                                                                 \
  } while (0)

/* o0..o3 (declared here, type T) = A^T m for one column of 6 elements m[0], m[s], .., m[5s]. */
#define WINO_AT(T, o0, o1, o2, o3, m, s)                                                                     \
  T o0, o1, o2, o3;                                                                                          \
  do {                                                                                                       \
    T m0_ = m[0], m1_ = m[(s)], m2_ = m[2 * (s)], m3_ = m[3 * (s)], m4_ = m[4 * (s)], m5_ = m[5 * (s)];    \
    T a_ = m1_ + m2_, b_ = m1_ - m2_, c_ = m3_ + m4_, d_ = m3_ - m4_;                                     \
    o0 = m0_ + a_ + c_;                                                                                      \
    o1 = b_ + 2.0f * d_;                                                                                     \
    o2 = a_ + 4.0f * c_;                                                                                     \
    o3 = b_ + 8.0f * d_ + m5_;                                                                               \
  } while (0)

/* r[0..23] (4 rows of 6) = A^T m for the 6x6 products m[0..35] of one tile, elements of type T. */
#define WINO_AT_COLS(T, r, m)                                                                                \
  for (int j_ = 0; j_ < 6; j_++) {                                                                           \
    WINO_AT(T, o0_, o1_, o2_, o3_, (m + j_), 6);                                                             \
    r[j_] = o0_, r[6 + j_] = o1_, r[12 + j_] = o2_, r[18 + j_] = o3_;                                        \
  }

/* u[0..35] = G g G^T of one 3x3 filter g[0..8] (row-major), h = G g first. */
#define WINO_R6 0.16666667f /* 1/6, 1/12, 1/24 rounded to float (multiplications, not divisions) */
#define WINO_R12 0.083333336f
#define WINO_R24 0.041666668f
static inline void wino_filter(const float *g, float *u) {
  float h[18];
  for (int j = 0; j < 3; j++) {
    float g0 = g[j], g1 = g[3 + j], g2 = g[6 + j];
    h[j] = g0 * 0.25f;
    h[3 + j] = -(g0 + g1 + g2) * WINO_R6;
    h[6 + j] = -(g0 - g1 + g2) * WINO_R6;
    h[9 + j] = g0 * WINO_R24 + g1 * WINO_R12 + g2 * WINO_R6;
    h[12 + j] = g0 * WINO_R24 - g1 * WINO_R12 + g2 * WINO_R6;
    h[15 + j] = g2;
  }
  for (int a = 0; a < 6; a++) {
    float g0 = h[3 * a], g1 = h[3 * a + 1], g2 = h[3 * a + 2];
    u[6 * a] = g0 * 0.25f;
    u[6 * a + 1] = -(g0 + g1 + g2) * WINO_R6;
    u[6 * a + 2] = -(g0 - g1 + g2) * WINO_R6;
    u[6 * a + 3] = g0 * WINO_R24 + g1 * WINO_R12 + g2 * WINO_R6;
    u[6 * a + 4] = g0 * WINO_R24 - g1 * WINO_R12 + g2 * WINO_R6;
    u[6 * a + 5] = g2;
  }
}

/* The 3x3 filter g[0..8] of GEMM row c and reduction index r of w [Cout][Cin][3][3] (zeros for
 * c >= the row count oc). flip = 0: rows are out channels, g = w[c][r]; flip = 1 (backward data):
 * rows are in channels, g[ky][kx] = w[r][c][2-ky][2-kx]. */
static inline void wino_filter_of(const __global float *w, int Cin, int oc, int c, int r, int flip, float *g) {
  for (int k = 0; k < 9; k++) {
    float v = 0.0f;
    if (c < oc) v = flip ? w[((size_t)r * Cin + c) * 9 + (8 - k)] : w[((size_t)c * Cin + r) * 9 + k];
    g[k] = v;
  }
}

/* u = G g G^T of the filter of GEMM column c and reduction index r (wino_filter_of, wino_filter). */
static inline void wino_u_of(const __global float *w, int Cin, int oc, int c, int r, int flip, float *u) {
  float g[9];
  wino_filter_of(w, Cin, oc, c, r, flip, g);
  wino_filter(g, u);
}

/* The epilogue's per-channel values of output channel co (bias, scale, shift; neutral when off). */
static inline void wino_epi_consts(int flags, const __global float *bias, ulong b_off, const __global float *scale,
                                   ulong sc_off, const __global float *shift, ulong sh_off, int co, float *bv,
                                   float *sc, float *sh) {
  *bv = (flags & FL_BIAS) ? bias[b_off + co] : 0.0f;
  *sc = (flags & FL_SCALE) ? scale[sc_off + co] : 1.0f;
  *sh = (flags & FL_SHIFT) ? shift[sh_off + co] : 0.0f;
}

/* Epilogue of one output (accumulate / bias / affine / ReLU, as conv2d.cl), stored at yo. */
static inline void wino_epi1(float v, __global float *yo, int flags, float bv, float sc, float sh) {
  if (flags & FL_ACCUM) v = *yo + v;
  if (flags & FL_BIAS) v = v + bv;
  if (flags & FL_SCALE) v = v * sc + sh;
  if (flags & FL_RELU) v = fmax(v, 0.0f);
  *yo = v;
}
