/* Plain-C double references for kernels/optim.cl (torch.optim.Adam / SGD formulas). */
#include <math.h>

#include "nn/optim.h"

void spx_ref_adam_step(const spx_adam_params *hp, int64_t step, double *params, const double *grads, double *m,
                       double *v, size_t n) {
  double bc1 = 1 - pow(hp->beta1, (double)step), bc2 = 1 - pow(hp->beta2, (double)step);
  double step_size = hp->lr / bc1, bc2_sqrt = sqrt(bc2);
  for (size_t i = 0; i < n; i++) {
    double g = grads[i];
    if (hp->weight_decay != 0) g += hp->weight_decay * params[i];
    m[i] = m[i] * hp->beta1 + (1 - hp->beta1) * g;
    v[i] = v[i] * hp->beta2 + (1 - hp->beta2) * g * g;
    params[i] -= step_size * m[i] / (sqrt(v[i]) / bc2_sqrt + hp->eps);
  }
}

void spx_ref_sgd_step(const spx_sgd_params *hp, int first_step, double *params, const double *grads, double *buf,
                      size_t n) {
  for (size_t i = 0; i < n; i++) {
    double d = grads[i];
    if (hp->weight_decay != 0) d += hp->weight_decay * params[i];
    if (hp->momentum != 0) {
      buf[i] = first_step ? d : buf[i] * hp->momentum + (1 - hp->dampening) * d;
      d = hp->nesterov ? d + hp->momentum * buf[i] : buf[i];
    }
    params[i] -= hp->lr * d;
  }
}
