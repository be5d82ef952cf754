/* Private side of the UNet (lib/nn/unet.c): construction on either tape backend (the HOST one
 * runs the double-precision references, used by the whole-graph finite-difference test) and
 * access to the tape and value ids. The public API is smplpix/unet.h. */
#ifndef SPX_NN_UNET_H
#define SPX_NN_UNET_H

#include "nn/tape.h"
#include "smplpix/unet.h"

/* Any width >= 1 (tests use tiny ones); backend DEVICE needs an open device. */
spx_status spx_unet_create_ex(spx_ctx *ctx, int width, int sigmoid, uint64_t seed, spx_tape_backend backend,
                              spx_unet **out);
spx_tape *spx_unet_tape(spx_unet *u);
/* Tape value id of a state_dict tensor (-1 if unknown). */
int spx_unet_value_id(const spx_unet *u, const char *name);
/* Value id of the loss of the last forward_loss (-1 if none). */
int spx_unet_loss_id(const spx_unet *u);
/* Value id of the network's output (the image) in the last forward (-1 if none). */
int spx_unet_output_id(const spx_unet *u);
spx_ctx *spx_unet_ctx(spx_unet *u);

/* Inference forward (batch norm folded, like spx_unet_forward with train = 0) from an input
 * already on the device (the public form is spx_unet_forward_tensor, smplpix/unet.h): n*4*h*w floats NCHW in `input` at byte `offset` (e.g. straight from
 * spx_project_device), copied on the device into the network's input; no host round trip.
 * output: host [n,3,h,w], or NULL to leave the result on the device. Device backend only. */
spx_status spx_unet_forward_device(spx_unet *u, cl_mem input, size_t offset, int n, int h, int w, float *output);

#endif
