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

#endif
