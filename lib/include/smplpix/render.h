/* Point projection with collision resolution (SMPLpix eq. 3-4): colored vertices → sparse RGB-D
 * images. Contract (DESIGN.md): (u',v',d) = K(Rx+t); column floor(u'/d), row floor(v'/d); d <= 0
 * and out-of-image points dropped; background (1,1,1,1); nearest depth wins, equal depth → the
 * smallest vertex index; bit-identical on every device. */
#ifndef SMPLPIX_RENDER_H
#define SMPLPIX_RENDER_H

#include "smplpix/camera.h"
#include "smplpix/core.h"
#include "smplpix/device.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum spx_layout {
  SPX_LAYOUT_HWC = 0, /* per image: H x W x 4 (R,G,B,depth) — the file layout */
  SPX_LAYOUT_NCHW = 1 /* per image: 4 x H x W — the network layout */
} spx_layout;

/* Reusable device state (scratch buffers grow as needed, kernels cached). */
typedef struct spx_projector spx_projector;
spx_status spx_projector_create(spx_ctx *ctx, spx_projector **out);
void spx_projector_destroy(spx_projector *p);

typedef struct spx_project_args {
  int32_t batch;              /* B vertex sets */
  int32_t nverts;             /* N vertices per set */
  const float *pos;           /* B*N*3 */
  const float *col;           /* B*N*3 in any range, or NULL for white */
  int32_t ncams;              /* C cameras, all of the same width and height */
  const spx_camera *cams;
  spx_layout layout;
} spx_project_args;

/* Project B sets through C cameras: out holds B*C images (image b*C + c) of H*W*4 floats.
 * winners (optional, B*C*H*W): the vertex index kept at each pixel, -1 for background. */
spx_status spx_project(spx_ctx *ctx, spx_projector *p, const spx_project_args *a, float *out, int32_t *winners);

/* Project into a device tensor (smplpix/device.h) instead of host memory: the network's input
 * stays on the device (spx_unet_forward_tensor in smplpix/unet.h reads it; no host round trip).
 * a->layout must be SPX_LAYOUT_NCHW; out must hold B*C*4*H*W floats and gets the shape
 * [B*C, 4, H, W]. The images equal spx_project's bit for bit. Only enqueues work (the positions
 * and colours are uploaded first); reading the tensor or spx_device_finish waits for it. */
spx_status spx_project_to_tensor(spx_ctx *ctx, spx_projector *p, const spx_project_args *a, spx_device_tensor *out);

/* Gradient of a loss through the projection. grad_img has the shape/layout of the forward's
 * output; winners is the forward's winners. Accumulates (+=) into grad_col (B*N*3) and
 * grad_pos (B*N*3; only through depth: u,v are floored), either may be NULL. */
spx_status spx_project_backward(spx_ctx *ctx, spx_projector *p, const spx_project_args *a, const int32_t *winners,
                                const float *grad_img, float *grad_col, float *grad_pos);

/* The plain-C reference (single thread z-buffer, same float arithmetic). */
spx_status spx_project_ref(spx_ctx *ctx, const spx_project_args *a, float *out, int32_t *winners);
void spx_project_backward_ref(const spx_project_args *a, const int32_t *winners, const float *grad_img,
                              float *grad_col, float *grad_pos);

#ifdef __cplusplus
}
#endif
#endif
