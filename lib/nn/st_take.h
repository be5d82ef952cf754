/* Private: copy one float32 tensor out of an opened safetensors file, with the shape checked and
 * NaN/Inf refused; every failure is one message naming the file and the tensor. Used by the
 * networks whose files are float32 only (PatchGAN, VGG19); the UNet also reads float16. */
#ifndef SPX_NN_ST_TAKE_H
#define SPX_NN_ST_TAKE_H

#include "smplpix/safetensors.h"

/* Shape as "[a, b, c]" (truncated to cap). */
void spx_nn_shape_str(char *buf, size_t cap, int ndim, const int64_t *shape);
/* Tensor `name` of f, which must have exactly shape[ndim]: *t, or the error (naming path, the tensor
 * and both shapes). */
spx_status spx_nn_st_find_shaped(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *name, int ndim,
                                 const int64_t *shape, const spx_st_tensor **t);
/* Tensor `name` of shape[ndim], dtype F32, all finite, into dst. */
spx_status spx_nn_st_take_f32(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *name, int ndim,
                              const int64_t *shape, float *dst);

#endif
