/* Private declarations shared by the mesh readers/writers: mesh.c (dispatch by extension) calls
 * the stream writers of obj.c and ply.c; obj.c and ply.c use nothing of each other (the growable
 * index array both readers use is core's spx_ivec). */
#ifndef SPX_IO_MESH_INTERNAL_H
#define SPX_IO_MESH_INTERNAL_H

#include <stdio.h>

#include "core/internal.h"
#include "smplpix/mesh.h"

/* Largest mesh file we read (the public contract: files over 2 GiB are rejected). */
#define SPX_MESH_MAX_FILE ((size_t)2 << 30)

/* Write a mesh to an open stream (no atomicity; mesh.c wraps these in spx_atomic_*).
 * Return SPX_OK or an error naming `name`. */
spx_status spx_obj_write(spx_ctx *ctx, const char *name, const spx_mesh *m, FILE *fp);
spx_status spx_ply_write(spx_ctx *ctx, const char *name, const spx_mesh *m, FILE *fp, int binary);

#endif
