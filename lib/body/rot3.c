/* Small 3x3 rotation helpers (lib/body/rot3.h). */
#include "body/rot3.h"

#include <math.h>
#include <string.h>

#include "smplpix/body.h"

void spx_rot3_eye(double R[9]) {
  memset(R, 0, 9 * sizeof(double));
  R[0] = R[4] = R[8] = 1;
}

void spx_rot3_mul(const double a[9], const double b[9], double o[9]) {
  double t[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) t[r * 3 + c] = a[r * 3] * b[c] + a[r * 3 + 1] * b[3 + c] + a[r * 3 + 2] * b[6 + c];
  memcpy(o, t, sizeof t);
}

void spx_rot3_mul_tn(const double a[9], const double b[9], double o[9]) {
  double t[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) t[r * 3 + c] = a[r] * b[c] + a[3 + r] * b[3 + c] + a[6 + r] * b[6 + c];
  memcpy(o, t, sizeof t);
}

void spx_rot3_mul_nt(const double a[9], const double b[9], double o[9]) {
  double t[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) t[r * 3 + c] = a[r * 3] * b[c * 3] + a[r * 3 + 1] * b[c * 3 + 1] + a[r * 3 + 2] * b[c * 3 + 2];
  memcpy(o, t, sizeof t);
}

void spx_rot3_apply(const double a[9], const double v[3], double o[3]) {
  double t[3];
  for (int r = 0; r < 3; r++) t[r] = a[r * 3] * v[0] + a[r * 3 + 1] * v[1] + a[r * 3 + 2] * v[2];
  memcpy(o, t, sizeof t);
}

void spx_rot3_align(const double a0[3], const double b0[3], double R[9]) {
  double a[3], b[3], na = sqrt(a0[0] * a0[0] + a0[1] * a0[1] + a0[2] * a0[2]);
  double nb = sqrt(b0[0] * b0[0] + b0[1] * b0[1] + b0[2] * b0[2]);
  for (int d = 0; d < 3; d++) a[d] = a0[d] / na, b[d] = b0[d] / nb;
  double v[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  double c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2], s = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), r[3];
  if (s < 1e-12 && c < 0) { /* opposite: half turn about an axis orthogonal to a */
    double e[3] = {fabs(a[0]) < 0.9 ? 1.0 : 0.0, fabs(a[0]) < 0.9 ? 0.0 : 1.0, 0};
    double o[3] = {a[1] * e[2] - a[2] * e[1], a[2] * e[0] - a[0] * e[2], a[0] * e[1] - a[1] * e[0]};
    double no = sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
    for (int d = 0; d < 3; d++) r[d] = o[d] / no * M_PI;
  } else {
    double th = atan2(s, c);
    for (int d = 0; d < 3; d++) r[d] = s > 1e-15 ? v[d] / s * th : 0.0;
  }
  spx_body_rodrigues(r, R, NULL);
}
