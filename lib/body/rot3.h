/* Private: the one small 3x3 / rotation module (row-major, double) of lib/body and the layers above
 * it (lib/fit's registration, retargeting). Rodrigues' formula itself is public
 * (spx_body_rodrigues in smplpix/body.h) and is defined in rot3.c.
 *
 * The products are static inline: they sit in the inner loops of the body Jacobian
 * (lib/body/lbs_ref.c). Each keeps the summation order a[.0] b + a[.1] b + a[.2] b, which the
 * registration's bit-for-bit outputs depend on (lib is built with -ffp-contract=off). */
#ifndef SPX_BODY_ROT3_H
#define SPX_BODY_ROT3_H

#include <string.h>

static inline void spx_rot3_eye(double R[9]) {
  memset(R, 0, 9 * sizeof(double));
  R[0] = R[4] = R[8] = 1;
}

/* o = a b (o may alias a or b) */
static inline void spx_rot3_mul(const double a[9], const double b[9], double o[9]) {
  double t[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) t[r * 3 + c] = a[r * 3] * b[c] + a[r * 3 + 1] * b[3 + c] + a[r * 3 + 2] * b[6 + c];
  memcpy(o, t, sizeof t);
}

/* o = a^T b (o may alias) */
static inline void spx_rot3_mul_tn(const double a[9], const double b[9], double o[9]) {
  double t[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) t[r * 3 + c] = a[r] * b[c] + a[3 + r] * b[3 + c] + a[6 + r] * b[6 + c];
  memcpy(o, t, sizeof t);
}

/* o = a b^T (o may alias) */
static inline void spx_rot3_mul_nt(const double a[9], const double b[9], double o[9]) {
  double t[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) t[r * 3 + c] = a[r * 3] * b[c * 3] + a[r * 3 + 1] * b[c * 3 + 1] + a[r * 3 + 2] * b[c * 3 + 2];
  memcpy(o, t, sizeof t);
}

/* o = a v (o may alias v) */
static inline void spx_rot3_apply(const double a[9], const double v[3], double o[3]) {
  double t[3];
  for (int r = 0; r < 3; r++) t[r] = a[r * 3] * v[0] + a[r * 3 + 1] * v[1] + a[r * 3 + 2] * v[2];
  memcpy(o, t, sizeof t);
}

/* o = a^T v (o may alias v) */
static inline void spx_rot3_apply_t(const double a[9], const double v[3], double o[3]) {
  double t[3];
  for (int r = 0; r < 3; r++) t[r] = a[r] * v[0] + a[3 + r] * v[1] + a[6 + r] * v[2];
  memcpy(o, t, sizeof t);
}

/* o = a x b (o may alias) */
static inline void spx_rot3_cross(const double a[3], const double b[3], double o[3]) {
  double t[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  memcpy(o, t, sizeof t);
}

/* o = a^-1 by cofactors; returns 0 (o untouched) when |det a| <= 1e-12. */
int spx_rot3_inv(const double a[9], double o[9]);

/* The smallest rotation taking direction a onto direction b (neither needs unit length; both
 * non-zero). Opposite directions: a half turn about an axis orthogonal to a. */
void spx_rot3_align(const double a[3], const double b[3], double R[9]);

/* Symmetric 3x3 eigen-decomposition by cyclic Jacobi rotations (at most 50 sweeps): eigenvalues w
 * in descending order, the matching unit eigenvectors in the columns of V. */
void spx_rot3_sym_eig(const double A[9], double w[3], double V[9]);

#endif
