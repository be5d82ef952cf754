/* Shared by the Winograd tests (tests/test_nn_conv2d_winograd*.c): the transform matrices of
 * F(4x4,3x3) as the kernels use them and the magnitude |B^T| |d| |B| of an input tile, the
 * building block of their derived error bounds. */
#ifndef SPX_WINO_TEST_H
#define SPX_WINO_TEST_H

#include <math.h>
#include <stddef.h>

static const double WT_BT[6][6] = {{4, 0, -5, 0, 1, 0},  {0, -4, -4, 1, 1, 0}, {0, 4, -4, -1, 1, 0},
                                   {0, -2, -1, 2, 1, 0}, {0, 2, -1, -2, 1, 0}, {0, 4, 0, -5, 0, 1}};
static const double WT_G[6][3] = {{0.25, 0, 0},           {-1.0 / 6, -1.0 / 6, -1.0 / 6}, {-1.0 / 6, 1.0 / 6, -1.0 / 6},
                                  {1.0 / 24, 1.0 / 12, 1.0 / 6}, {1.0 / 24, -1.0 / 12, 1.0 / 6}, {0, 0, 1}};
static const double WT_AT[4][6] = {{1, 1, 1, 1, 1, 0}, {0, 1, -1, 2, -2, 0}, {0, 1, 1, 4, 4, 0}, {0, 1, -1, 8, -8, 1}};

/* Element (i, k) of a matrix stored with row stride rs and column stride cs (cs = rows' length for
 * a transposed view: A (6x4) is WT_AT read with rs = 1, cs = 6). */
#define WT_EL(m, rs, cs, i, k) ((m)[(size_t)(i) * (rs) + (size_t)(k) * (cs)])

/* out (rows x rows) = |M| d |M|^T for M (rows x cols, strides rs, cs) and d (cols x cols, >= 0). */
static inline void wt_abs_sandwich(const double *m, int rs, int cs, int rows, int cols, const double *d, double *out) {
  double t[6 * 6];
  for (int a = 0; a < rows; a++)
    for (int j = 0; j < cols; j++) {
      double v = 0;
      for (int k = 0; k < cols; k++) v += fabs(WT_EL(m, rs, cs, a, k)) * d[k * cols + j];
      t[a * cols + j] = v;
    }
  for (int a = 0; a < rows; a++)
    for (int b = 0; b < rows; b++) {
      double v = 0;
      for (int k = 0; k < cols; k++) v += t[a * cols + k] * fabs(WT_EL(m, rs, cs, b, k));
      out[a * rows + b] = v;
    }
}

/* sum_k M[a][k]^2 over the n columns of row a. */
static inline double wt_row_sq(const double *m, int rs, int cs, int a, int n) {
  double v = 0;
  for (int k = 0; k < n; k++) v += WT_EL(m, rs, cs, a, k) * WT_EL(m, rs, cs, a, k);
  return v;
}

/* out[i*6+j] = (|B^T| |d| |B|)[i][j], d the 6x6 patch of the h x w plane xc around tile (ty, tx)
 * (rows 4ty-1 .. 4ty+4, zero outside the image), taken in absolute value. */
static inline void wt_input_magnitude(const double *xc, int h, int w, int ty, int tx, double *out) {
  double d[36];
  for (int i = 0; i < 6; i++)
    for (int j = 0; j < 6; j++) {
      int yy = 4 * ty - 1 + i, xx = 4 * tx - 1 + j;
      d[i * 6 + j] = yy >= 0 && yy < h && xx >= 0 && xx < w ? fabs(xc[(size_t)yy * w + xx]) : 0;
    }
  wt_abs_sandwich(&WT_BT[0][0], 6, 1, 6, 6, d, out);
}

/* The largest |sum_a A^T_ia G_ak B^T_ap - [p == i + k]|: 0 (to rounding) when the matrices multiply
 * out to the 3-tap correlation. */
static inline double wt_identity_error(void) {
  double worst = 0;
  for (int i = 0; i < 4; i++)
    for (int k = 0; k < 3; k++)
      for (int p = 0; p < 6; p++) {
        double e = 0;
        for (int a = 0; a < 6; a++) e += WT_AT[i][a] * WT_G[a][k] * WT_BT[a][p];
        worst = fmax(worst, fabs(e - (p == i + k)));
      }
  return worst;
}

#endif
