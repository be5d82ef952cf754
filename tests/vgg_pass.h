/* The perceptual loss of a frozen VGG (nn/vgg.h) as one training pass on its own tape, for the
 * tests that check its value and its gradient: pred and gt [n,3,h,w] go in, the loss comes out,
 * and pred requires a gradient. */
#ifndef SPX_TEST_VGG_PASS_H
#define SPX_TEST_VGG_PASS_H

#include "nn/vgg.h"

typedef struct spx_t_vgg_pass {
  spx_vgg *v;
  const float *x, *gt;
  int n, h, w;
  int xi, loss; /* ids the build leaves behind */
} spx_t_vgg_pass;

static inline spx_status spx_t_vgg_build(spx_tape *t, void *user) {
  spx_t_vgg_pass *p = user;
  p->xi = spx_tape_input(t, p->n, 3, p->h, p->w, p->x);
  int gi = spx_tape_input(t, p->n, 3, p->h, p->w, p->gt);
  spx_tape_requires_grad(t, p->xi); /* in the build: it is part of the plan */
  p->loss = spx_vgg_loss(p->v, p->xi, gi);
  return SPX_OK;
}

/* The pass of p on t and its backward: the loss into *loss, pred's gradient (n*3*h*w floats) into
 * grad; p->xi and p->loss name them on t afterwards. */
static inline spx_status spx_t_vgg_loss_grad(spx_tape *t, spx_t_vgg_pass *p, float *loss, float *grad) {
  spx_status st = spx_tape_pass(t, 1, 1, spx_t_vgg_build, p);
  if (!st) st = spx_tape_backward(t, p->loss);
  if (!st) st = spx_tape_read(t, p->loss, loss);
  if (!st) st = spx_tape_read_grad(t, p->xi, grad);
  return st;
}

#endif
