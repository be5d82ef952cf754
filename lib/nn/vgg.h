/* Private side of the frozen VGG perceptual losses (smplpix/vgg.h, lib/nn/vgg.c). */
#ifndef SPX_NN_VGG_H
#define SPX_NN_VGG_H

#include "nn/tape.h"
#include "smplpix/vgg.h"

#define SPX_VGG_NCONV 13

/* Open either network on either backend (HOST: double references, for tests). */
spx_status spx_vgg_open_ex(spx_ctx *ctx, const char *path, spx_vgg_kind kind, spx_tape_backend backend,
                           spx_vgg **out);
spx_tape *spx_vgg_tape(spx_vgg *v);

/* Inside a TRAINING pass of the VGG's tape: pred and gt [n, 3, H, W] (RGB in [0,1]) run through
 * the network one after the other; returns the value id of the loss (smplpix/vgg.h: eq. 5 for
 * VGG19, the official code's for VGG16), or -1 after a tape error. Gradients reach pred only when
 * it was marked with spx_tape_requires_grad; the gt branch needs no gradient (its values are only
 * L1 targets, the weights are state), so backward skips all of its nodes. */
int spx_vgg_loss(spx_vgg *v, int pred, int gt);
/* The weight spx_vgg_set_image_l1 set: part of the graph, so a pass's key holds it. */
float spx_vgg_image_l1(const spx_vgg *v);

#endif
