/* Plain-C double references for kernels/activations.cl. */
#include <math.h>

#include "nn/activations.h"

void spx_ref_act_forward(spx_act_kind kind, double slope, const double *x, double *y, size_t n) {
  for (size_t i = 0; i < n; i++) {
    double v = x[i];
    switch (kind) {
    case SPX_ACT_RELU: y[i] = v > 0 ? v : 0; break;
    case SPX_ACT_LEAKY_RELU: y[i] = v > 0 ? v : v * slope; break;
    case SPX_ACT_SIGMOID: y[i] = 1.0 / (1.0 + exp(-v)); break;
    default: y[i] = tanh(v); break;
    }
  }
}

void spx_ref_act_backward(spx_act_kind kind, double slope, const double *s, const double *dy, double *dx, size_t n) {
  for (size_t i = 0; i < n; i++) {
    double v = s[i], g = dy[i];
    switch (kind) {
    case SPX_ACT_RELU: dx[i] += v > 0 ? g : 0; break;
    case SPX_ACT_LEAKY_RELU: dx[i] += v > 0 ? g : g * slope; break;
    case SPX_ACT_SIGMOID: dx[i] += g * (1 - v) * v; break;
    default: dx[i] += g * (1 - v * v); break;
    }
  }
}
