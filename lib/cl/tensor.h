/* Private side of the public device tensor (smplpix/device.h): the buffer and the checks every
 * producer / consumer of a tensor makes (lib/render/project.c, lib/nn/unet_tensor.c). */
#ifndef SPX_CL_TENSOR_H
#define SPX_CL_TENSOR_H

#include "cl/cl_internal.h"

struct spx_device_tensor {
  spx_ctx *ctx; /* owner */
  cl_mem mem;
  size_t capacity; /* floats */
  int shape[4];
};

/* SPX_OK when t is non-NULL and was created on ctx; else SPX_E_ARG naming `what`. */
spx_status spx_device_tensor_check(spx_ctx *ctx, const spx_device_tensor *t, const char *what);

#endif
