/* Private: small 3x3 rotation helpers (row-major, double) for the retargeting code in lib/body. */
#ifndef SPX_BODY_ROT3_H
#define SPX_BODY_ROT3_H

void spx_rot3_eye(double R[9]);
/* o = a b (o may alias a or b) */
void spx_rot3_mul(const double a[9], const double b[9], double o[9]);
/* o = a^T b (o may alias) */
void spx_rot3_mul_tn(const double a[9], const double b[9], double o[9]);
/* o = a b^T (o may alias) */
void spx_rot3_mul_nt(const double a[9], const double b[9], double o[9]);
/* o = a v (o may alias v) */
void spx_rot3_apply(const double a[9], const double v[3], double o[3]);
/* The smallest rotation taking direction a onto direction b (neither needs unit length; both
 * non-zero). Opposite directions: a half turn about an axis orthogonal to a. */
void spx_rot3_align(const double a[3], const double b[3], double R[9]);

#endif
