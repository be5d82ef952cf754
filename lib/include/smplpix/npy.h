/* NumPy .npy arrays (format 1.0/2.0/3.0, C order, little endian or byte-neutral). */
#ifndef SMPLPIX_NPY_H
#define SMPLPIX_NPY_H

#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SPX_NPY_MAX_DIMS 8

typedef struct spx_array {
  spx_dtype dtype;
  int ndim;
  int64_t shape[SPX_NPY_MAX_DIMS];
  void *data;    /* C order, native (little endian) byte order */
  size_t nbytes; /* product(shape) * dtype size */
} spx_array;

/* Load f4/f8/u1/i4/i8 (plus i1/u4/u8/b1) arrays; big-endian files are byte-swapped. Fortran
 * order, object arrays, shapes that overflow or disagree with the file size, and headers
 * over 64 KiB are rejected with a message naming the file. */
spx_status spx_npy_load(spx_ctx *ctx, const char *path, spx_array *out);
spx_status spx_npy_parse(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_array *out);
/* Save atomically. */
spx_status spx_npy_save(spx_ctx *ctx, const char *path, const spx_array *a);
/* Convenience: save float32 data with the given shape. */
spx_status spx_npy_save_f32(spx_ctx *ctx, const char *path, const float *data, int ndim, const int64_t *shape);
/* Number of elements (product of the shape). */
int64_t spx_array_numel(const spx_array *a);
/* Convert any numeric array to a new float32 buffer (malloc'd). */
spx_status spx_array_to_f32(spx_ctx *ctx, const spx_array *a, float **out);
void spx_array_free(spx_array *a);

#ifdef __cplusplus
}
#endif
#endif
