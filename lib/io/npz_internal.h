/* Private: the open / read / close that the loaders of .npz files share. */
#ifndef SPX_IO_NPZ_INTERNAL_H
#define SPX_IO_NPZ_INTERNAL_H

#include "smplpix/npz.h"

/* Reads what a loader wants from an open archive into out. */
typedef spx_status (*spx_npz_read_fn)(spx_ctx *ctx, const spx_npz *z, void *out);

/* The archive at path opened, read(ctx, archive, out) run, the archive closed; the status of the
 * first step that failed. */
spx_status spx_npz_load_with(spx_ctx *ctx, const char *path, spx_npz_read_fn read, void *out);

#endif
