/* Private: activations of the network engine (kernels/activations.cl), with double references.
 * Backward takes the SAVED tensor `s`: the input x for ReLU / LeakyReLU, the output y for
 * sigmoid / tanh, and ACCUMULATES into dx. Forward may run in place (x == y). */
#ifndef SPX_NN_ACTIVATIONS_H
#define SPX_NN_ACTIVATIONS_H

#include "nn/tensor.h"

typedef enum spx_act_kind { SPX_ACT_RELU = 0, SPX_ACT_LEAKY_RELU = 1, SPX_ACT_SIGMOID = 2, SPX_ACT_TANH = 3 } spx_act_kind;

/* 1 when backward wants the output y as its saved tensor (sigmoid, tanh), 0 for the input x. */
static inline int spx_act_saves_output(spx_act_kind k) { return k == SPX_ACT_SIGMOID || k == SPX_ACT_TANH; }

spx_status spx_act_forward(spx_ctx *ctx, spx_act_kind kind, float slope, const spx_tensor *x, const spx_tensor *y);
spx_status spx_act_backward(spx_ctx *ctx, spx_act_kind kind, float slope, const spx_tensor *s, const spx_tensor *dy,
                            const spx_tensor *dx);

void spx_ref_act_forward(spx_act_kind kind, double slope, const double *x, double *y, size_t n);
void spx_ref_act_backward(spx_act_kind kind, double slope, const double *s, const double *dy, double *dx, size_t n);

#endif
