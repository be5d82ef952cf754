/* Mesh load/save dispatch by extension, free, deep copy and validation. */
#include <math.h>
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

void spx_mesh_free(spx_mesh *m) {
  if (!m) return;
  free(m->pos);
  free(m->col);
  free(m->nrm);
  free(m->faces);
  free(m->uv);
  free(m->face_uv);
  memset(m, 0, sizeof *m);
}

static spx_status dup_array(spx_ctx *ctx, const void *src, size_t n, size_t elem, void **dst) {
  *dst = NULL;
  if (!src) return SPX_OK;
  *dst = spx_alloc_array(ctx, n, elem, "mesh copy");
  if (!*dst) return SPX_E_NOMEM;
  memcpy(*dst, src, n * elem);
  return SPX_OK;
}

spx_status spx_mesh_copy(spx_ctx *ctx, const spx_mesh *src, spx_mesh *dst) {
  if (!dst) return spx_fail(ctx, SPX_E_ARG, "spx_mesh_copy: no destination");
  memset(dst, 0, sizeof *dst);
  if (!src || src->nv < 0 || src->nf < 0 || src->nuv < 0) return spx_fail(ctx, SPX_E_ARG, "spx_mesh_copy: bad source mesh");
  spx_mesh m = {0};
  m.nv = src->nv;
  m.nf = src->nf;
  m.nuv = src->nuv;
  size_t nv = (size_t)src->nv, nf = (size_t)src->nf, nuv = (size_t)src->nuv;
  void *p;
  spx_status st;
#define DUP(field, n, elem)                                                                                           \
  if ((st = dup_array(ctx, src->field, n, elem, &p))) goto fail;                                                       \
  m.field = p;
  DUP(pos, nv, 3 * sizeof(float));
  DUP(col, nv, 3 * sizeof(float));
  DUP(nrm, nv, 3 * sizeof(float));
  DUP(faces, nf, 3 * sizeof(int32_t));
  DUP(uv, nuv, 2 * sizeof(float));
  DUP(face_uv, nf, 3 * sizeof(int32_t));
#undef DUP
  *dst = m;
  return SPX_OK;
fail:
  spx_mesh_free(&m);
  return st;
}

static spx_status check_finite(spx_ctx *ctx, const char *name, const float *a, size_t n, int per, const char *what) {
  if (!a) return SPX_OK;
  for (size_t i = 0; i < n * (size_t)per; i++)
    if (!isfinite(a[i]))
      return spx_fail(ctx, SPX_E_NUMERIC, "%s: %s %zu is not finite", name, what, i / (size_t)per);
  return SPX_OK;
}

spx_status spx_mesh_validate(spx_ctx *ctx, const char *name, const spx_mesh *m) {
  if (!name) name = "mesh";
  if (!m) return spx_fail(ctx, SPX_E_ARG, "%s: no mesh", name);
  if (m->nv < 0 || m->nf < 0 || m->nuv < 0) return spx_fail(ctx, SPX_E_ARG, "%s: negative counts", name);
  if (m->nv > 0 && !m->pos) return spx_fail(ctx, SPX_E_ARG, "%s: %d vertices but no positions", name, m->nv);
  if (m->nf > 0 && !m->faces) return spx_fail(ctx, SPX_E_ARG, "%s: %d faces but no indices", name, m->nf);
  if (m->nuv > 0 && !m->uv) return spx_fail(ctx, SPX_E_ARG, "%s: %d texture coordinates but no array", name, m->nuv);
  if (m->face_uv && !m->uv) return spx_fail(ctx, SPX_E_ARG, "%s: face_uv without uv", name);
  spx_status st;
  if ((st = check_finite(ctx, name, m->pos, (size_t)m->nv, 3, "vertex"))) return st;
  if ((st = check_finite(ctx, name, m->col, (size_t)m->nv, 3, "color of vertex"))) return st;
  if ((st = check_finite(ctx, name, m->nrm, (size_t)m->nv, 3, "normal of vertex"))) return st;
  if ((st = check_finite(ctx, name, m->uv, (size_t)m->nuv, 2, "texture coordinate"))) return st;
  for (size_t i = 0; i < (size_t)m->nf * 3; i++) {
    if (m->faces[i] < 0 || m->faces[i] >= m->nv)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: face %zu uses vertex %d, outside 0..%d", name, i / 3, m->faces[i], m->nv - 1);
    if (m->face_uv && (m->face_uv[i] < 0 || m->face_uv[i] >= m->nuv))
      return spx_fail(ctx, SPX_E_FORMAT, "%s: face %zu uses texture coordinate %d, outside 0..%d", name, i / 3,
                      m->face_uv[i], m->nuv - 1);
  }
  return SPX_OK;
}
