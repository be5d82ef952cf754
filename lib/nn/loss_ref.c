/* Plain-C double references for kernels/loss.cl. */
#include <math.h>

#include "nn/loss.h"

double spx_ref_reduce(spx_reduction r, const double *x, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++) s += x[i];
  return r == SPX_REDUCE_MEAN ? s / (double)n : s;
}

double spx_ref_loss_forward(spx_loss_kind kind, spx_reduction r, const double *pred, const double *target, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++) {
    double d = pred[i] - target[i];
    s += kind == SPX_LOSS_L1 ? fabs(d) : d * d;
  }
  return r == SPX_REDUCE_MEAN ? s / (double)n : s;
}

void spx_ref_loss_backward(spx_loss_kind kind, spx_reduction r, const double *pred, const double *target, size_t n,
                           double dout, double *dpred, double *dtarget) {
  double div = r == SPX_REDUCE_MEAN ? (double)n : 1.0;
  for (size_t i = 0; i < n; i++) {
    double d = pred[i] - target[i];
    double v = kind == SPX_LOSS_L1 ? (d > 0 ? 1 : (d < 0 ? -1 : 0)) * dout / div : 2 * d * dout / div;
    if (dpred) dpred[i] += v;
    if (dtarget) dtarget[i] -= v;
  }
}
