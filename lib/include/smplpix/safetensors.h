/* safetensors files: an 8-byte little-endian header length, a JSON header
 * {"name": {"dtype": "F32", "shape": [...], "data_offsets": [begin, end]}, "__metadata__": {...}},
 * then the tensor bytes. */
#ifndef SMPLPIX_SAFETENSORS_H
#define SMPLPIX_SAFETENSORS_H

#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SPX_ST_MAX_DIMS 8

typedef struct spx_st_tensor {
  char *name;
  spx_dtype dtype;
  int ndim;
  int64_t shape[SPX_ST_MAX_DIMS];
  const void *data; /* points into the file's data section (little endian) */
  size_t nbytes;
} spx_st_tensor;

typedef struct spx_st_file {
  int count;
  spx_st_tensor *tensors;
  int nmeta;
  char **meta_keys, **meta_values; /* "__metadata__" string pairs */
  unsigned char *blob;             /* whole file */
  size_t blob_size;
} spx_st_file;

/* Load and validate: header size bounded by the file, offsets inside the data section, sorted
 * and non-overlapping, byte counts equal to product(shape) * dtype size, no duplicate names. */
spx_status spx_st_load(spx_ctx *ctx, const char *path, spx_st_file *out);
spx_status spx_st_parse(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_st_file *out);
const spx_st_tensor *spx_st_find(const spx_st_file *f, const char *name);
const char *spx_st_meta(const spx_st_file *f, const char *key);
void spx_st_free(spx_st_file *f);

/* Writing: describe each tensor (data in host memory) and save atomically. */
typedef struct spx_st_entry {
  const char *name;
  spx_dtype dtype;
  int ndim;
  int64_t shape[SPX_ST_MAX_DIMS];
  const void *data;
} spx_st_entry;
spx_status spx_st_save(spx_ctx *ctx, const char *path, const spx_st_entry *entries, int count,
                       const char *const *meta_keys, const char *const *meta_values, int nmeta);

#ifdef __cplusplus
}
#endif
#endif
