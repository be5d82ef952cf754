/* Mesh load and save, dispatched by the file's extension to obj.c / ply.c (the mesh object's own
 * functions are in mesh_core.c, below both). */
#include <stdlib.h>
#include <string.h>

#include "io/mesh_internal.h"
#include "smplpix/files.h"

spx_status spx_mesh_load(spx_ctx *ctx, const char *path, spx_mesh *out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "spx_mesh_load: no output mesh");
  memset(out, 0, sizeof *out);
  if (!path) return spx_fail(ctx, SPX_E_ARG, "spx_mesh_load: no path");
  char ext[8];
  spx_path_ext(path, ext, sizeof ext);
  int is_obj = strcmp(ext, "obj") == 0, is_ply = strcmp(ext, "ply") == 0;
  if (!is_obj && !is_ply)
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: unknown mesh extension '.%s' (expected .obj or .ply)", path, ext);
  unsigned char *data;
  size_t size;
  spx_status st = spx_read_file(ctx, path, SPX_MESH_MAX_FILE, &data, &size);
  if (st) return st;
  st = is_obj ? spx_mesh_parse_obj(ctx, path, data, size, out) : spx_mesh_parse_ply(ctx, path, data, size, out);
  free(data);
  return st;
}

spx_status spx_mesh_save(spx_ctx *ctx, const char *path, const spx_mesh *m, spx_mesh_format fmt) {
  if (!path || !m) return spx_fail(ctx, SPX_E_ARG, "spx_mesh_save: no path or mesh");
  spx_status st = spx_mesh_validate(ctx, path, m);
  if (st) return st;
  if (fmt == SPX_MESH_AUTO) {
    char ext[8];
    spx_path_ext(path, ext, sizeof ext);
    if (strcmp(ext, "obj") == 0) fmt = SPX_MESH_OBJ;
    else if (strcmp(ext, "ply") == 0) fmt = SPX_MESH_PLY_BINARY;
    else return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: unknown mesh extension '.%s' (expected .obj or .ply)", path, ext);
  }
  if (fmt != SPX_MESH_OBJ && fmt != SPX_MESH_PLY_ASCII && fmt != SPX_MESH_PLY_BINARY)
    return spx_fail(ctx, SPX_E_ARG, "%s: unknown mesh format %d", path, (int)fmt);
  spx_atomic_file af;
  if ((st = spx_atomic_open(ctx, path, &af))) return st;
  st = fmt == SPX_MESH_OBJ ? spx_obj_write(ctx, path, m, af.fp) : spx_ply_write(ctx, path, m, af.fp, fmt == SPX_MESH_PLY_BINARY);
  if (st) {
    spx_atomic_abort(&af);
    return st;
  }
  return spx_atomic_commit(ctx, &af);
}
