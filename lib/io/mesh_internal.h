/* Private declarations shared by the mesh readers/writers, in one direction: mesh_core.c (the mesh
 * object and the readers' shared steps) at the bottom, obj.c and ply.c on it (they use nothing of
 * each other), mesh.c (dispatch by extension) on top, calling the stream writers of obj.c and ply.c. */
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

/* The readers' first step: with no out, an SPX_E_ARG error naming *name (or `format`); else *out
 * is zeroed, a NULL *name becomes `format` ("obj", "ply"), and data must be there and at most
 * SPX_MESH_MAX_FILE bytes. */
spx_status spx_mesh_parse_begin(spx_ctx *ctx, const char **name, const char *format, const void *data, size_t size,
                                spx_mesh *out);
/* Fan-triangulate one polygon of n corners onto tris: (c0, ck, ck+1) for k = 1 .. n-2, where the
 * corners are corners[i], or first + i when corners is NULL (corners numbered consecutively). */
spx_status spx_mesh_fan(spx_ctx *ctx, const char *name, spx_ivec *tris, const int32_t *corners, size_t first,
                        size_t n);
/* The readers' last step: validate *m (spx_mesh_validate) and move it into *out (*m is zeroed);
 * on an error *m is left to the caller to free. */
spx_status spx_mesh_parse_finish(spx_ctx *ctx, const char *name, spx_mesh *m, spx_mesh *out);

#endif
