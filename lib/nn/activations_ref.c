/* Plain-C double references for kernels/activations.cl: the f and df of each row of
 * SPX_ACT_LIST (lib/nn/activations.h). */
#include <math.h>

#include "nn/activations.h"

void spx_ref_act_forward(spx_act_kind kind, double slope, const double *x, double *y, size_t n) {
  for (size_t i = 0; i < n; i++) {
    double v = x[i];
    switch (kind) {
#define F(ID, name, saves, f, df) \
  case SPX_ACT_##ID: y[i] = (f); break;
      SPX_ACT_LIST(F)
#undef F
    default: y[i] = NAN; break;
    }
  }
}

void spx_ref_act_backward(spx_act_kind kind, double slope, const double *s, const double *dy, double *dx, size_t n) {
  for (size_t i = 0; i < n; i++) {
    double v = s[i], g = dy[i];
    switch (kind) {
#define DF(ID, name, saves, f, df) \
  case SPX_ACT_##ID: dx[i] += (df); break;
      SPX_ACT_LIST(DF)
#undef DF
    default: dx[i] = NAN; break;
    }
  }
}
