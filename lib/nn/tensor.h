/* Private: device tensors for the network engine. NCHW float32 in a cl_mem at an element
 * offset (kernels take (buffer, offset) pairs, so tensors can live inside slabs without
 * sub-buffer alignment rules). */
#ifndef SPX_NN_TENSOR_H
#define SPX_NN_TENSOR_H

#include "cl/cl_internal.h"

typedef struct spx_tensor {
  cl_mem mem;
  size_t off;          /* offset in floats from the start of mem */
  int32_t n, c, h, w;  /* shape; vectors use n = numel, c = h = w = 1 */
} spx_tensor;

static inline size_t spx_tensor_numel(const spx_tensor *t) {
  return (size_t)t->n * (size_t)t->c * (size_t)t->h * (size_t)t->w;
}
static inline spx_tensor spx_tensor_view(cl_mem mem, size_t off, int32_t n, int32_t c, int32_t h, int32_t w) {
  spx_tensor t = {mem, off, n, c, h, w};
  return t;
}

/* Conventions for every op (lib/nn/<op>.c, kernels/<op>.cl, lib/nn/<op>_ref.c, tests/test_nn_<op>.c):
 *  - spx_<op>_forward(ctx, inputs..., params..., out) writes `out` (overwrite).
 *  - spx_<op>_backward(ctx, saved inputs/outputs..., dout, din...) ACCUMULATES (+=) into every
 *    input gradient it is given (NULL = not needed), so a tensor used twice sums its gradients.
 *  - spx_ref_<op>_forward/_backward: plain C in double precision, same semantics; the
 *    finite-difference tests check the reference, and the device kernels are checked against it
 *    (every tape op at once: tests/test_nn_tape_ops.c).
 *  - no float atomics: every reduction runs in a fixed order, so a run repeats bit for bit
 *    (`smplpix train --resume` relies on it). */

#endif
