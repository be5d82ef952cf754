/* Private: activations of the network engine (kernels/activations.cl), with double references.
 * Backward takes the SAVED tensor `s`: the input x for ReLU / LeakyReLU, the output y for
 * sigmoid / tanh, and ACCUMULATES into dx. Forward may run in place (x == y).
 *
 * One row per activation: X(ID, name, saves, f, df). The kind is SPX_ACT_<ID>; saves is what its
 * backward reads (1: the output y, 0: the input x); f is y as an expression of the input v (and
 * the LeakyReLU slope), df the increment of dx as one of the saved v and the upstream gradient g.
 * f and df ARE the double references (activations_ref.c); the kernels spx_<name>_fwd / _bwd of
 * kernels/activations.cl (ids SPX_K_<ID>_FWD / _BWD in lib/cl/kernels.h) compute the same in float.
 * Adding an activation: a row here, its two kernels and their two lines in lib/cl/kernels.h, and a
 * row in tests/test_nn_tape_ops.c (which fails while a kind has none). */
#ifndef SPX_NN_ACTIVATIONS_H
#define SPX_NN_ACTIVATIONS_H

#include "nn/tensor.h"

#define SPX_ACT_LIST(X)                                                          \
  X(RELU, "relu", 0, v > 0 ? v : 0, v > 0 ? g : 0)                               \
  X(LEAKY_RELU, "leaky_relu", 0, v > 0 ? v : v * slope, v > 0 ? g : g * slope)   \
  X(SIGMOID, "sigmoid", 1, 1.0 / (1.0 + exp(-v)), g * (1 - v) * v)               \
  X(TANH, "tanh", 1, tanh(v), g * (1 - v * v))

#define SPX_ACT_ENUM_(ID, name, saves, f, df) SPX_ACT_##ID,
typedef enum spx_act_kind { SPX_ACT_LIST(SPX_ACT_ENUM_) SPX_ACT_COUNT } spx_act_kind;
#undef SPX_ACT_ENUM_

/* 1 when backward wants the output y as its saved tensor (sigmoid, tanh), 0 for the input x. */
#define SPX_ACT_SAVES_(ID, name, saves, f, df) | ((unsigned)(saves) << SPX_ACT_##ID)
static inline int spx_act_saves_output(spx_act_kind k) {
  return k >= 0 && k < SPX_ACT_COUNT && (((0u SPX_ACT_LIST(SPX_ACT_SAVES_)) >> k) & 1u);
}
#undef SPX_ACT_SAVES_
/* The row's name ("relu", ...); "?" for no kind. */
const char *spx_act_name(spx_act_kind k);

spx_status spx_act_forward(spx_ctx *ctx, spx_act_kind kind, float slope, const spx_tensor *x, const spx_tensor *y);
spx_status spx_act_backward(spx_ctx *ctx, spx_act_kind kind, float slope, const spx_tensor *s, const spx_tensor *dy,
                            const spx_tensor *dx);

void spx_ref_act_forward(spx_act_kind kind, double slope, const double *x, double *y, size_t n);
void spx_ref_act_backward(spx_act_kind kind, double slope, const double *s, const double *dy, double *dx, size_t n);

#endif
