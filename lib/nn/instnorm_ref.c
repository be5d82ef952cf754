/* Plain-C double reference for kernels/instnorm.cl (lib/nn/instnorm.h). */
#include <math.h>

#include "nn/instnorm.h"

void spx_ref_instnorm_forward(const double *x, int planes, int hw, double eps, double *save, double *y) {
  for (int p = 0; p < planes; p++) {
    const double *xp = x + (size_t)p * hw;
    double m = 0, v = 0;
    for (int i = 0; i < hw; i++) m += xp[i];
    m /= hw;
    for (int i = 0; i < hw; i++) v += (xp[i] - m) * (xp[i] - m);
    v /= hw;
    double is = 1.0 / sqrt(v + eps);
    save[p] = m, save[planes + p] = is;
    for (int i = 0; i < hw; i++) y[(size_t)p * hw + i] = (xp[i] - m) * is;
  }
}

void spx_ref_instnorm_backward(const double *x, int planes, int hw, const double *save, const double *dy, double *dx) {
  for (int p = 0; p < planes; p++) {
    const double *xp = x + (size_t)p * hw, *gp = dy + (size_t)p * hw;
    double m = save[p], is = save[planes + p], sg = 0, sgx = 0;
    for (int i = 0; i < hw; i++) {
      sg += gp[i];
      sgx += gp[i] * (xp[i] - m) * is;
    }
    sg /= hw, sgx /= hw;
    for (int i = 0; i < hw; i++) dx[(size_t)p * hw + i] += is * (gp[i] - sg - (xp[i] - m) * is * sgx);
  }
}
