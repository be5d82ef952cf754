/* Plain-C double references for kernels/batchnorm.cl (two-pass statistics in double). */
#include <math.h>
#include <stdlib.h>

#include "nn/batchnorm.h"

#define AT(k, ch, s) (((size_t)(k) * c + (ch)) * hw + (s))

void spx_ref_bn_train_forward(const double *x, int n, int c, int hw, const double *weight, const double *bias,
                              double *rm, double *rv, double momentum, double eps, double *save_mean,
                              double *save_invstd, double *y) {
  double cnt = (double)n * hw;
  for (int ch = 0; ch < c; ch++) {
    double s = 0, v = 0;
    for (int k = 0; k < n; k++)
      for (int i = 0; i < hw; i++) s += x[AT(k, ch, i)];
    double mean = s / cnt;
    for (int k = 0; k < n; k++)
      for (int i = 0; i < hw; i++) v += (x[AT(k, ch, i)] - mean) * (x[AT(k, ch, i)] - mean);
    double var = v / cnt, invstd = 1 / sqrt(var + eps);
    for (int k = 0; k < n; k++)
      for (int i = 0; i < hw; i++) y[AT(k, ch, i)] = (x[AT(k, ch, i)] - mean) * invstd * weight[ch] + bias[ch];
    save_mean[ch] = mean;
    save_invstd[ch] = invstd;
    if (rm) rm[ch] = momentum * mean + (1 - momentum) * rm[ch];
    if (rv) rv[ch] = momentum * var * cnt / (cnt - 1) + (1 - momentum) * rv[ch];
  }
}

void spx_ref_bn_eval_forward(const double *x, int n, int c, int hw, const double *weight, const double *bias,
                             const double *rm, const double *rv, double eps, double *y) {
  for (int ch = 0; ch < c; ch++) {
    double invstd = 1 / sqrt(rv[ch] + eps);
    for (int k = 0; k < n; k++)
      for (int i = 0; i < hw; i++) y[AT(k, ch, i)] = (x[AT(k, ch, i)] - rm[ch]) * invstd * weight[ch] + bias[ch];
  }
}

void spx_ref_bn_train_backward(const double *x, int n, int c, int hw, const double *weight, const double *save_mean,
                               const double *save_invstd, const double *dy, double *dx, double *dweight,
                               double *dbias) {
  double cnt = (double)n * hw;
  for (int ch = 0; ch < c; ch++) {
    double mean = save_mean[ch], invstd = save_invstd[ch], sdy = 0, sdyx = 0;
    for (int k = 0; k < n; k++)
      for (int i = 0; i < hw; i++) {
        sdy += dy[AT(k, ch, i)];
        sdyx += dy[AT(k, ch, i)] * (x[AT(k, ch, i)] - mean);
      }
    if (dweight) dweight[ch] += sdyx * invstd;
    if (dbias) dbias[ch] += sdy;
    if (dx)
      for (int k = 0; k < n; k++)
        for (int i = 0; i < hw; i++)
          dx[AT(k, ch, i)] += (dy[AT(k, ch, i)] - sdy / cnt - (x[AT(k, ch, i)] - mean) * sdyx * invstd * invstd / cnt) *
                              invstd * weight[ch];
  }
}

int spx_ref_bn_relu_train_backward(const double *x, int n, int c, int hw, const double *weight, const double *bias,
                                   const double *save_mean, const double *save_invstd, const double *dy, double *dx,
                                   double *dweight, double *dbias) {
  size_t total = (size_t)n * c * hw;
  double *g = malloc((total ? total : 1) * sizeof *g);
  if (!g) return -1;
  for (int k = 0; k < n; k++)
    for (int ch = 0; ch < c; ch++)
      for (int i = 0; i < hw; i++) {
        size_t j = AT(k, ch, i);
        double y = (x[j] - save_mean[ch]) * save_invstd[ch] * weight[ch] + bias[ch];
        g[j] = y > 0 ? dy[j] : 0.0;
      }
  spx_ref_bn_train_backward(x, n, c, hw, weight, save_mean, save_invstd, g, dx, dweight, dbias);
  free(g);
  return 0;
}
