/* The mesh object's own functions: free, deep copy and validation, and the steps the OBJ and PLY
 * readers share (argument checks, fan triangulation, the final validation). The bottom of lib/io's
 * mesh files: obj.c and ply.c call it, mesh.c (load / save by extension) sits on top of all three. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "io/mesh_internal.h"

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

spx_status spx_mesh_parse_begin(spx_ctx *ctx, const char **name, const char *format, const void *data, size_t size,
                                spx_mesh *out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "%s: no output mesh", *name ? *name : format);
  memset(out, 0, sizeof *out);
  if (!*name) *name = format;
  if (!data && size) return spx_fail(ctx, SPX_E_ARG, "%s: no data", *name);
  if (size > SPX_MESH_MAX_FILE) return spx_fail(ctx, SPX_E_FORMAT, "%s: file is larger than 2 GiB", *name);
  return SPX_OK;
}

spx_status spx_mesh_fan(spx_ctx *ctx, const char *name, spx_ivec *tris, const int32_t *corners, size_t first,
                        size_t n) {
  for (size_t k = 1; k + 1 < n; k++) {
    int32_t tri[3];
    if (corners) {
      tri[0] = corners[0], tri[1] = corners[k], tri[2] = corners[k + 1];
    } else {
      tri[0] = (int32_t)first, tri[1] = (int32_t)(first + k), tri[2] = (int32_t)(first + k + 1);
    }
    spx_status st = spx_ivec_push(ctx, name, tris, tri, 3);
    if (st) return st;
  }
  return SPX_OK;
}

spx_status spx_mesh_parse_finish(spx_ctx *ctx, const char *name, spx_mesh *m, spx_mesh *out) {
  spx_status st = spx_mesh_validate(ctx, name, m);
  if (st) return st;
  *out = *m;
  memset(m, 0, sizeof *m);
  return SPX_OK;
}
