/* The perceptual loss of the paper (eq. 5) with a frozen VGG19:
 *   L_VGG(gt, pred) = sum_{i=0..5} 2^-(5-i) mean |f_i(gt) - f_i(pred)|,
 * f_0 the image itself (RGB in [0,1]) and f_1..f_5 the activations of torchvision's vgg19().features
 * at relu1_1, relu2_1, relu3_1, relu4_1, relu5_1 (features[0:2], [2:7], [7:12], [12:21], [21:30])
 * of the ImageNet-normalised image ((x - [0.485, 0.456, 0.406]) / [0.229, 0.224, 0.225]).
 *
 * Weights: a safetensors file with torchvision's state_dict names features.N.weight / .bias for
 * the 13 convolutions N = 0, 2, 5, 7, 10, 12, 14, 16, 19, 21, 23, 25, 28 (other tensors, e.g. the
 * later layers and the classifier, are ignored); tools/vgg19_pth_to_safetensors.py converts a
 * torchvision .pth. The base width is read from features.0.weight (64 for the real VGG19; smaller
 * widths, all channel counts scaled alike, serve tests). The weights are frozen: no gradients and
 * no optimizer state exist for them. */
#ifndef SMPLPIX_VGG_H
#define SMPLPIX_VGG_H

#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_vgg spx_vgg;

/* Missing or misshapen tensors: one line naming the file and the tensor. */
spx_status spx_vgg_open(spx_ctx *ctx, const char *path, spx_vgg **out);
void spx_vgg_destroy(spx_vgg *v);
int spx_vgg_width(const spx_vgg *v);

#ifdef __cplusplus
}
#endif
#endif
