/* Private side of the frozen VGG19 perceptual loss (smplpix/vgg.h, lib/nn/vgg.c). */
#ifndef SPX_NN_VGG_H
#define SPX_NN_VGG_H

#include "nn/tape.h"
#include "smplpix/vgg.h"

#define SPX_VGG_NCONV 13

/* Open on either backend (HOST: double references, for tests). */
spx_status spx_vgg_open_ex(spx_ctx *ctx, const char *path, spx_tape_backend backend, spx_vgg **out);
spx_tape *spx_vgg_tape(spx_vgg *v);

/* Inside a TRAINING pass of the VGG's tape: x [2n, 3, H, W] holds [pred; gt] (RGB in [0,1]);
 * returns the value id of L_VGG(gt, pred) (gradients reach only the pred half: the gt half is the
 * target of every L1 term), or -1 after a tape error. */
int spx_vgg_loss(spx_vgg *v, int x, int n);

#endif
