/* The paper's stage-2 adversarial training (§3.3, pix2pixHD's recipe): a multi-scale PatchGAN
 * discriminator conditional on the RGB-D input (4 + 3 = 7 input channels), least-squares GAN loss
 * and feature matching, trained together with the UNet generator.
 *
 * Discriminator: num_d scales (3 in the paper), each 5 layers of 4x4 convolutions with padding 2:
 * s2 (ndf) + LeakyReLU 0.2, s2 (2ndf) + InstanceNorm + LReLU, s2 (4ndf) + IN + LReLU, s1 (8ndf) +
 * IN + LReLU, s1 (1); the input is average-pooled (3x3, stride 2, padding 1, count_include_pad
 * False) between scales. Checkpoints are safetensors with the state_dict names of pix2pixHD's
 * MultiscaleDiscriminator(input_nc=7, ndf, n_layers=3, norm_layer=InstanceNorm2d,
 * use_sigmoid=False, num_D, getIntermFeat=True): "scale{i}_layer{j}.0.weight" / ".0.bias",
 * scale{num_d-1} being the full-resolution one; plus "optimizer.<name>.exp_avg/_sq" and
 * "optimizer.step" for an exact resume. */
#ifndef SMPLPIX_PATCHGAN_H
#define SMPLPIX_PATCHGAN_H

#include "smplpix/unet.h"
#include "smplpix/vgg.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_patchgan spx_patchgan;

/* A new 7-channel discriminator (weights N(0, 0.02), biases PyTorch's default), on the device. */
spx_status spx_patchgan_new(spx_ctx *ctx, int ndf, int num_d, uint64_t seed, spx_patchgan **out);
/* Load a checkpoint (ndf and num_d read from it; every tensor checked by name and shape). */
spx_status spx_patchgan_open(spx_ctx *ctx, const char *path, spx_patchgan **out);
void spx_patchgan_destroy(spx_patchgan *d);
/* Atomic: a temporary file renamed over path. */
spx_status spx_patchgan_save(spx_patchgan *d, const char *path, int with_optimizer);
int spx_patchgan_num_d(const spx_patchgan *d);
int spx_patchgan_ndf(const spx_patchgan *d);
int64_t spx_patchgan_step(const spx_patchgan *d); /* Adam steps taken */
spx_status spx_patchgan_reset_optimizer(spx_patchgan *d);

/* Data-parallel training (smplpix/comm.h, as spx_unet_set_comm): Adam steps sum the
 * discriminator's gradients over the ranks first; the shard of each step is the generator's
 * (spx_unet_set_shard). broadcast: rank 0's weights, Adam state and step into every rank's. */
spx_status spx_patchgan_set_comm(spx_patchgan *d, const spx_comm *comm);
spx_status spx_patchgan_broadcast(spx_patchgan *d);

typedef struct spx_gan_losses {
  float rec;     /* mean L1 between the generated image and the target */
  float vgg;     /* L_VGG (smplpix/vgg.h) when a VGG is given, else 0 */
  float gan;     /* sum over scales of mean (D_k(fake) - 1)^2 */
  float fm;      /* feature matching: sum_k sum_{l<4} (1/num_d) mean |D_k^l(fake) - D_k^l(real)| */
  float g_total; /* (vgg or rec) + gan + 0.1 fm: what the generator minimises */
  float d_fake, d_real, d_total; /* sum_k mean D_k(fake)^2, sum_k mean (D_k(real) - 1)^2, 0.5 (fake + real) */
} spx_gan_losses;

/* One stage-2 step on a batch (input [n,4,h,w], target [n,3,h,w]): the generator takes an Adam
 * step (lr_g) on L_rec + L_GAN + 0.1 L_FM (L_rec = L_VGG with vgg, else the mean L1), the
 * discriminator one (lr_d) on 0.5 (fake + real) with the generator's image detached; both from the
 * same forward pass (pix2pixHD). Adam betas 0.9 / 0.999, eps 1e-8 for both. out (may be NULL)
 * receives the terms before the step. */
spx_status spx_unet_gan_step(spx_unet *g, spx_patchgan *d, spx_vgg *vgg, const float *input, const float *target,
                             int n, int h, int w, double lr_g, double lr_d, spx_gan_losses *out);
/* One stage-1 step with the perceptual loss: Adam (lr) on L_VGG(target, G(input)). out->vgg is
 * the loss, out->rec the L1 (for reporting). */
spx_status spx_unet_vgg_step(spx_unet *g, spx_vgg *vgg, const float *input, const float *target, int n, int h, int w,
                             double lr, spx_gan_losses *out);

#ifdef __cplusplus
}
#endif
#endif
