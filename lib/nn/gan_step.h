/* Private: one training step of the paper's stage 2 (pix2pixHD's recipe) with the UNet generator
 * G and the multi-scale PatchGAN D (lib/nn/patchgan.h), each on its own tape with its own Adam.
 *
 *   fake = G(in);  D runs ONCE on the batch [concat(in, fake); concat(in, real)] (instance norm is
 *   per sample, so this equals separate passes), giving per scale k the last output D_k and the
 *   intermediate features D_k^l of both halves.
 *   L_GAN  = sum_k mean (D_k(fake) - 1)^2                    (LSGAN, target 1 = real)
 *   L_FM   = sum_k sum_{l<4} (1/num_d) (4/(3+1)) mean |D_k^l(fake) - D_k^l(real)|  (real detached)
 *   G loss = L_rec + L_GAN + lambda_fm L_FM, L_rec = mean |fake - real| (L1)
 *   D loss = 0.5 (sum_k mean D_k(fake)^2 + sum_k mean (D_k(real) - 1)^2), fake detached
 * Both losses come from the same forward, as in pix2pixHD (whose G and D losses are computed
 * before either optimizer steps). G's gradient arrives through D: D's tape is backpropagated from
 * the G loss, the gradient of D's input (fake half, image channels) is handed to G's output
 * gradient with spx_tape_transfer and G's tape runs backward from its own L1 plus that. Then D's
 * parameter gradients are zeroed and D's tape is backpropagated from the D loss; D's input
 * gradient is not handed back (that is the detach), so the D step never touches G. */
#ifndef SPX_NN_GAN_STEP_H
#define SPX_NN_GAN_STEP_H

#include "nn/patchgan.h"
#include "nn/unet.h"
#include "smplpix/vgg.h"

typedef struct spx_gan_opts {
  double lr_g, lr_d, beta1, beta2, eps; /* Adam (the same betas / eps for G and D) */
  float lambda_fm;                      /* 0.1 in the paper */
  float lambda_rec;                     /* weight of the L1 term (1) */
} spx_gan_opts;


/* in [n,4,h,w], target [n,3,h,w] host arrays. D must have 7 input channels; d NULL: no GAN terms
 * (stage 1); vgg non-NULL: the reconstruction term is L_VGG (lib/nn/vgg.h, its own tape, fed
 * [fake; real] and handing the fake half's gradient back like D) instead of the L1. */
spx_status spx_gan_step(spx_ctx *ctx, spx_unet *g, spx_patchgan *d, spx_vgg *vgg, const float *in, const float *target, int n, int h, int w,
                        const spx_gan_opts *o, spx_gan_losses *terms);

#endif
