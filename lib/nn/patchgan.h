/* Private: pix2pixHD's multi-scale PatchGAN discriminator (MultiscaleDiscriminator with
 * n_layers = 3, getIntermFeat = True, InstanceNorm, LSGAN: no sigmoid) on its own tape.
 *
 * One scale = 5 layers of 4x4 convolutions with padding 2 (pix2pixHD's padw = ceil(3/2)):
 *   layer0: conv s2 (in -> ndf) + LeakyReLU 0.2
 *   layer1: conv s2 (ndf -> 2ndf) + InstanceNorm + LeakyReLU      (channel counts capped at 512)
 *   layer2: conv s2 (2ndf -> 4ndf) + IN + LReLU
 *   layer3: conv s1 (4ndf -> 8ndf) + IN + LReLU
 *   layer4: conv s1 (8ndf -> 1)
 * num_d scales; the input is downsampled between scales by AvgPool2d(3, 2, 1,
 * count_include_pad=False). Every conv has a bias; InstanceNorm(affine=False) has no tensors.
 *
 * Tensor names are the state_dict names of pix2pixHD's MultiscaleDiscriminator(getIntermFeat=True):
 * "scale{i}_layer{j}.0.weight" / ".0.bias" (the conv is item 0 of each layer's nn.Sequential).
 * pix2pixHD runs scale{num_d-1} on the FULL resolution and scale0 on the coarsest; so does this
 * module: feature index k = 0 (full resolution) belongs to the tensors named scale{num_d-1-k}.
 * Checkpoints add "optimizer.<name>.exp_avg/exp_avg_sq" and "optimizer.step" (like the UNet). */
#ifndef SPX_NN_PATCHGAN_H
#define SPX_NN_PATCHGAN_H

#include "nn/tape.h"
#include "smplpix/patchgan.h"

#define SPX_PG_LAYERS 5
#define SPX_PG_MAX_D 4

/* in_ch input channels (7 for SMPLpix: RGB-D + RGB), base width ndf (64 in pix2pixHD), num_d
 * scales (3 in the paper). Weights N(0, 0.02) (pix2pixHD's weights_init), biases
 * U(-1/sqrt(fan_in), 1/sqrt(fan_in)) (PyTorch's default), drawn from seed. */
spx_status spx_patchgan_create(spx_ctx *ctx, int in_ch, int ndf, int num_d, uint64_t seed, spx_tape_backend backend,
                               spx_patchgan **out);
spx_tape *spx_patchgan_tape(spx_patchgan *d);
int spx_patchgan_in_channels(const spx_patchgan *d);

/* Inside a build of the discriminator's tape (spx_tape_pass): run every scale on the activation x
 * [B, in_ch, H, W]; feat[k][j] = output of layer j at resolution k (k = 0 full). Returns 0, or -1
 * after a tape error (sticky, reported by spx_tape_pass). */
int spx_patchgan_forward(spx_patchgan *d, int x, int feat[SPX_PG_MAX_D][SPX_PG_LAYERS]);

/* One Adam step (PyTorch semantics) over every discriminator parameter; the step count advances. */
spx_status spx_patchgan_adam(spx_patchgan *d, double lr, double beta1, double beta2, double eps);

/* Tensor access by state_dict name (also "optimizer.<name>.exp_avg" / ".exp_avg_sq"). */
int spx_patchgan_tensor_count(const spx_patchgan *d);
const char *spx_patchgan_tensor_name(const spx_patchgan *d, int i, int *ndim, int64_t shape[4]);
int spx_patchgan_value_id(const spx_patchgan *d, const char *name);

/* (Save: smplpix/patchgan.h.) Load checks every tensor's presence and shape (one line naming the
 * file and the tensor), reads ndf from scale0_layer0.0.weight and num_d from the scales present,
 * restores the optimizer when optimizer.step is present. expect_in_ch > 0: the input channel count
 * must be this. */
spx_status spx_patchgan_load(spx_ctx *ctx, const char *path, int expect_in_ch, spx_tape_backend backend,
                             spx_patchgan **out);

#endif
