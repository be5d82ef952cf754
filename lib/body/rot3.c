/* The small 3x3 / rotation module (lib/body/rot3.h): Rodrigues' formula with its derivative
 * (public: spx_body_rodrigues), inverse, the aligning rotation and a symmetric eigensolver. */
#include "body/rot3.h"

#include <math.h>
#include <string.h>

#include "smplpix/body.h"

/* R = I + a [r]x + b [r]x^2 with a = sin(t)/t, b = (1-cos t)/t^2, t = |r|. */
void spx_body_rodrigues(const double r[3], double R[9], double dR[27]) {
  double t2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2], t = sqrt(t2);
  double a, b, da, db; /* da = a'(t)/t, db = b'(t)/t */
  if (t < 1e-4) {
    a = 1 - t2 / 6 + t2 * t2 / 120;
    b = 0.5 - t2 / 24 + t2 * t2 / 720;
    da = -1.0 / 3 + t2 / 30;
    db = -1.0 / 12 + t2 / 180;
  } else {
    double s = sin(t), co = cos(t);
    a = s / t;
    b = (1 - co) / t2;
    da = (t * co - s) / (t2 * t);
    db = (t * s - 2 * (1 - co)) / (t2 * t2);
  }
  double K[9] = {0, -r[2], r[1], r[2], 0, -r[0], -r[1], r[0], 0}, K2[9];
  spx_rot3_mul(K, K, K2);
  for (int i = 0; i < 9; i++) R[i] = (i % 4 == 0 ? 1.0 : 0.0) + a * K[i] + b * K2[i];
  if (!dR) return;
  for (int c = 0; c < 3; c++) {
    double e[3] = {0, 0, 0};
    e[c] = 1;
    double E[9] = {0, -e[2], e[1], e[2], 0, -e[0], -e[1], e[0], 0}, EK[9], KE[9];
    spx_rot3_mul(E, K, EK);
    spx_rot3_mul(K, E, KE);
    for (int i = 0; i < 9; i++) dR[c * 9 + i] = da * r[c] * K[i] + a * E[i] + db * r[c] * K2[i] + b * (EK[i] + KE[i]);
  }
}

int spx_rot3_inv(const double a[9], double o[9]) {
  double c0 = a[4] * a[8] - a[5] * a[7], c1 = a[5] * a[6] - a[3] * a[8], c2 = a[3] * a[7] - a[4] * a[6];
  double det = a[0] * c0 + a[1] * c1 + a[2] * c2;
  if (!(fabs(det) > 1e-12)) return 0;
  double id = 1.0 / det;
  o[0] = c0 * id, o[1] = (a[2] * a[7] - a[1] * a[8]) * id, o[2] = (a[1] * a[5] - a[2] * a[4]) * id;
  o[3] = c1 * id, o[4] = (a[0] * a[8] - a[2] * a[6]) * id, o[5] = (a[2] * a[3] - a[0] * a[5]) * id;
  o[6] = c2 * id, o[7] = (a[1] * a[6] - a[0] * a[7]) * id, o[8] = (a[0] * a[4] - a[1] * a[3]) * id;
  return 1;
}

void spx_rot3_sym_eig(const double A0[9], double w[3], double V[9]) {
  double A[9];
  memcpy(A, A0, sizeof A);
  for (int i = 0; i < 9; i++) V[i] = (i % 4 == 0);
  for (int sweep = 0; sweep < 50; sweep++) {
    double off = fabs(A[1]) + fabs(A[2]) + fabs(A[5]);
    if (off < 1e-15) break;
    for (int p = 0; p < 2; p++)
      for (int q = p + 1; q < 3; q++) {
        double apq = A[p * 3 + q];
        if (fabs(apq) < 1e-300) continue;
        double th = (A[q * 3 + q] - A[p * 3 + p]) / (2 * apq);
        double t = (th >= 0 ? 1.0 : -1.0) / (fabs(th) + sqrt(th * th + 1));
        double c = 1 / sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < 3; k++) { /* A = J^T A J */
          double akp = A[k * 3 + p], akq = A[k * 3 + q];
          A[k * 3 + p] = c * akp - s * akq, A[k * 3 + q] = s * akp + c * akq;
        }
        for (int k = 0; k < 3; k++) {
          double apk = A[p * 3 + k], aqk = A[q * 3 + k];
          A[p * 3 + k] = c * apk - s * aqk, A[q * 3 + k] = s * apk + c * aqk;
        }
        for (int k = 0; k < 3; k++) {
          double vkp = V[k * 3 + p], vkq = V[k * 3 + q];
          V[k * 3 + p] = c * vkp - s * vkq, V[k * 3 + q] = s * vkp + c * vkq;
        }
      }
  }
  int ord[3] = {0, 1, 2};
  for (int i = 0; i < 3; i++)
    for (int j = i + 1; j < 3; j++)
      if (A[ord[j] * 4] > A[ord[i] * 4]) {
        int t = ord[i];
        ord[i] = ord[j], ord[j] = t;
      }
  double W[9];
  for (int i = 0; i < 3; i++) {
    w[i] = A[ord[i] * 4];
    for (int k = 0; k < 3; k++) W[k * 3 + i] = V[k * 3 + ord[i]];
  }
  memcpy(V, W, sizeof W);
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
