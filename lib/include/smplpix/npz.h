/* NumPy .npz archives: a zip of .npy members, stored or deflated (zip64 tolerated).
 * Members are decompressed and parsed lazily (spx_npz_read), so an archive with members this
 * library cannot parse (e.g. pickled object arrays in SMPL-X files) still opens, and only the
 * keys a caller asks for must be valid. Keys are member names without the ".npy" suffix. */
#ifndef SMPLPIX_NPZ_H
#define SMPLPIX_NPZ_H

#include "smplpix/core.h"
#include "smplpix/npy.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_npz_member {
  char *key;            /* member name without ".npy" (NUL-terminated) */
  uint64_t data_offset; /* start of the (compressed) data in the archive */
  uint64_t csize;       /* compressed size */
  uint64_t usize;       /* uncompressed size */
  uint32_t crc;         /* CRC-32 from the central directory */
  uint16_t method;      /* 0 stored, 8 deflate */
} spx_npz_member;

typedef struct spx_npz {
  char *name;               /* file name used in messages */
  unsigned char *data;      /* the whole archive */
  size_t size;
  int32_t count;            /* .npy members (other members are ignored) */
  spx_npz_member *members;
} spx_npz;

/* Largest archive / member accepted (bytes). */
#define SPX_NPZ_MAX_FILE ((size_t)4 << 30)
#define SPX_NPZ_MAX_MEMBER ((uint64_t)4 << 30)

/* Open an archive: reads the file and its central directory (no member is decompressed). */
spx_status spx_npz_open(spx_ctx *ctx, const char *path, spx_npz *out);
/* Same from memory (the bytes are copied); `name` is used in messages. */
spx_status spx_npz_open_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_npz *out);
/* Index of key, or -1. */
int32_t spx_npz_find(const spx_npz *z, const char *key);
/* Decompress, CRC-check and parse member `key` (message names archive and key if absent). */
spx_status spx_npz_read(spx_ctx *ctx, const spx_npz *z, const char *key, spx_array *out);
/* Same by member index. */
spx_status spx_npz_read_index(spx_ctx *ctx, const spx_npz *z, int32_t index, spx_array *out);
void spx_npz_close(spx_npz *z);

/* Write an archive atomically with `count` members named keys[i] + ".npy". compress: 0 stored,
 * 1 deflated. Output is deterministic (fixed timestamps). */
spx_status spx_npz_save(spx_ctx *ctx, const char *path, int32_t count, const char *const *keys,
                        const spx_array *arrays, int compress);

/* Serialise one array as .npy (format 1.0) into a malloc'd buffer. */
spx_status spx_npz_encode_npy(spx_ctx *ctx, const spx_array *a, unsigned char **out, size_t *size);

#ifdef __cplusplus
}
#endif
#endif
