/* Private helpers shared by the mesh readers/writers (lib/io/obj.c, ply.c, mesh.c). */
#ifndef SPX_IO_MESH_INTERNAL_H
#define SPX_IO_MESH_INTERNAL_H

#include <stdio.h>

#include "core/internal.h"
#include "smplpix/mesh.h"

/* Largest mesh file we read (the public contract: files over 2 GiB are rejected). */
#define SPX_MESH_MAX_FILE ((size_t)2 << 30)

/* Growable int32 array (faces while their count is unknown). */
typedef struct spx_ivec {
  int32_t *v;
  size_t n, cap;
} spx_ivec;
/* Append k values; records SPX_E_NOMEM naming `name` on failure. */
spx_status spx_ivec_push(spx_ctx *ctx, const char *name, spx_ivec *a, const int32_t *vals, size_t k);

/* Write a mesh to an open stream (no atomicity; mesh.c wraps these in spx_atomic_*).
 * Return SPX_OK or an error naming `name`. */
spx_status spx_obj_write(spx_ctx *ctx, const char *name, const spx_mesh *m, FILE *fp);
spx_status spx_ply_write(spx_ctx *ctx, const char *name, const spx_mesh *m, FILE *fp, int binary);

#endif
