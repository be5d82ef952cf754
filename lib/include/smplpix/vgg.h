/* The frozen VGG perceptual losses of `smplpix train`, on images RGB in [0,1] (pred, gt [n,3,H,W]):
 *
 * VGG19, the paper's eq. 5 (--loss vgg):
 *   L_VGG(gt, pred) = sum_{i=0..5} 2^-(5-i) mean |f_i(gt) - f_i(pred)|,
 * f_0 the image itself and f_1..f_5 the activations of torchvision's vgg19().features at relu1_1,
 * relu2_1, relu3_1, relu4_1, relu5_1 (features[0:2], [2:7], [7:12], [12:21], [21:30]) of the
 * ImageNet-normalised image ((x - [0.485, 0.456, 0.406]) / [0.229, 0.224, 0.225]).
 *
 * VGG16, as the official SMPLpix code computes it (--loss vgg16): the image as it is (no
 * normalisation) through torchvision's vgg16().features[0:4], [4:9], [9:16], [16:23] (relu1_2,
 * relu2_2, relu3_3, relu4_3); the image and the four activations, each flattened per sample and
 * multiplied by 1, 1/16, 1/8, 1/4, 1, are concatenated, and the loss is one mean absolute
 * difference over the whole concatenation (torch.nn.L1Loss):
 *   L = sum_k w_k sum |f_k(pred) - f_k(gt)| / sum_k numel(f_k),
 * so a piece's weight in the sum of per-piece means is w_k numel(f_k) / sum numel (H, W >= 8).
 *
 * Weights: a safetensors file with torchvision's state_dict names features.N.weight / .bias for
 * the convolutions used: VGG19 N = 0, 2, 5, 7, 10, 12, 14, 16, 19, 21, 23, 25, 28; VGG16 N = 0, 2,
 * 5, 7, 10, 12, 14, 17, 19, 21 (other tensors, e.g. later layers and the classifier, are ignored).
 * tools/vgg19_pth_to_safetensors.py converts a torchvision .pth; `make weights` writes VGG16 to
 * the cache (smplpix/metrics.h: spx_weights_path). The base width is read from features.0.weight
 * (64 for the real networks; smaller widths, all channel counts scaled alike, serve tests). The
 * weights are frozen: no gradients and no optimizer state exist for them. */
#ifndef SMPLPIX_VGG_H
#define SMPLPIX_VGG_H

#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_vgg spx_vgg;
typedef enum spx_vgg_kind { SPX_VGG19_EQ5 = 0, SPX_VGG16_SMPLPIX = 1 } spx_vgg_kind;

/* VGG19 (eq. 5) / VGG16 (the official code's loss). Missing or misshapen tensors, or the other
 * network's file: one line naming the file and the problem. */
spx_status spx_vgg_open(spx_ctx *ctx, const char *path, spx_vgg **out);
spx_status spx_vgg16_open(spx_ctx *ctx, const char *path, spx_vgg **out);
spx_vgg_kind spx_vgg_get_kind(const spx_vgg *v);
void spx_vgg_destroy(spx_vgg *v);
int spx_vgg_width(const spx_vgg *v);
/* Adds w * mean |pred - gt| (the image's own L1, on top of its share inside the loss above) to
 * every later loss of v: the colour term the perceptual loss leaves small (VGG16: the image is 3
 * of ~123 channel-pixels per pixel of the one mean). w in [0, 1e3]; 0 (the default): the loss
 * exactly as above. It may change between training steps. */
spx_status spx_vgg_set_image_l1(spx_vgg *v, double w);
/* Keeps the network's features of the target images of later training steps (spx_unet_vgg_step,
 * spx_unet_gan_step), up to max_bytes (device memory, plus a host copy of each image), and reuses
 * them when the same target image comes again in a batch of the same size: on a fixed training
 * set each target's features are computed once instead of every step (the frozen network's
 * forward of the target is about a third of its work in a step). A target is found by its whole
 * image, bit for bit, and its features are the bits its first step computed, so losses, gradients
 * and weights are exactly those without the cache. Entries are kept in the order they come, never
 * evicted; 0 (the default) turns the cache off, and a smaller budget drops every entry. */
spx_status spx_vgg_set_target_cache(spx_vgg *v, size_t max_bytes);
/* Bytes the cache holds now; the bytes one h x w target takes in it. */
size_t spx_vgg_target_cache_bytes(const spx_vgg *v);
size_t spx_vgg_target_bytes(const spx_vgg *v, int h, int w);
/* A budget for a training set of count targets of h x w: all of them, up to a quarter of the
 * device's memory (0 without a device). */
size_t spx_vgg_target_cache_fit(spx_vgg *v, int count, int h, int w);

#ifdef __cplusplus
}
#endif
#endif
