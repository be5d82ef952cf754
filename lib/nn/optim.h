/* Private: optimizers over flat parameter slabs (kernels/optim.cl), PyTorch semantics, with
 * double references. params, grads and the state buffers are flat tensors with the same element
 * count (usually whole slabs, so a step is one kernel launch). */
#ifndef SPX_NN_OPTIM_H
#define SPX_NN_OPTIM_H

#include <stdint.h>

#include "nn/tensor.h"

/* torch.optim.Adam(lr, betas=(beta1, beta2), eps, weight_decay): L2 decay added to the
 * gradient; amsgrad and maximize are not supported. */
typedef struct spx_adam_params {
  double lr, beta1, beta2, eps, weight_decay;
} spx_adam_params;

/* One Adam step. step: the step number AFTER incrementing (1 on the first call); m and v start
 * at zero and are updated in place. */
spx_status spx_adam_step(spx_ctx *ctx, const spx_adam_params *hp, int64_t step, const spx_tensor *params,
                         const spx_tensor *grads, const spx_tensor *m, const spx_tensor *v);

/* torch.optim.SGD(lr, momentum, dampening, weight_decay, nesterov). */
typedef struct spx_sgd_params {
  double lr, momentum, dampening, weight_decay;
  int nesterov;
} spx_sgd_params;

/* One SGD step. first_step != 0 initialises the momentum buffer to the gradient (as PyTorch
 * does when the buffer does not exist yet). buf may be NULL when momentum == 0. */
spx_status spx_sgd_step(spx_ctx *ctx, const spx_sgd_params *hp, int first_step, const spx_tensor *params,
                        const spx_tensor *grads, const spx_tensor *buf);

void spx_ref_adam_step(const spx_adam_params *hp, int64_t step, double *params, const double *grads, double *m,
                       double *v, size_t n);
void spx_ref_sgd_step(const spx_sgd_params *hp, int first_step, double *params, const double *grads, double *buf,
                      size_t n);

#endif
