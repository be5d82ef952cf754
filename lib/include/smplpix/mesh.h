/* Triangle meshes and point clouds: OBJ / PLY (ascii + binary little endian) I/O and Loop
 * subdivision. A point cloud is a mesh with nf == 0. */
#ifndef SMPLPIX_MESH_H
#define SMPLPIX_MESH_H

#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_mesh {
  int32_t nv;       /* vertices */
  int32_t nf;       /* triangles (polygons are fan-triangulated on load) */
  float *pos;       /* nv*3 positions */
  float *col;       /* nv*3 colors in [0,1] (0-255 input is scaled), or NULL */
  float *nrm;       /* nv*3 normals, or NULL */
  int32_t *faces;   /* nf*3 vertex indices, 0-based */
  int32_t nuv;      /* texture coordinates */
  float *uv;        /* nuv*2, or NULL */
  int32_t *face_uv; /* nf*3 indices into uv (per corner), or NULL */
} spx_mesh;

/* Load by extension (.obj / .ply, case-insensitive). Every error names the file and, for text
 * formats, the line. Rejects NaN/Inf values, out-of-range indices, counts larger than the
 * file, and files over 2 GiB. On error *out is left empty (all NULL, counts 0). */
spx_status spx_mesh_load(spx_ctx *ctx, const char *path, spx_mesh *out);
/* Parse from memory; `name` is used in messages (fuzzing, archives). */
spx_status spx_mesh_parse_obj(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_mesh *out);
spx_status spx_mesh_parse_ply(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_mesh *out);

typedef enum spx_mesh_format {
  SPX_MESH_AUTO = 0,       /* by extension; PLY → binary little endian */
  SPX_MESH_OBJ = 1,
  SPX_MESH_PLY_ASCII = 2,
  SPX_MESH_PLY_BINARY = 3
} spx_mesh_format;
/* Save atomically (temp file + rename). Colors are written as 8-bit in PLY, as floats
 * ("v x y z r g b") in OBJ. */
spx_status spx_mesh_save(spx_ctx *ctx, const char *path, const spx_mesh *m, spx_mesh_format fmt);

void spx_mesh_free(spx_mesh *m);
/* Deep copy. */
spx_status spx_mesh_copy(spx_ctx *ctx, const spx_mesh *src, spx_mesh *dst);
/* Check finiteness and index ranges; `name` is used in messages. */
spx_status spx_mesh_validate(spx_ctx *ctx, const char *name, const spx_mesh *m);

/* Area-weighted vertex normals (lib/geom/normals.c): per vertex, the sum over its faces of
 * (p1 - p0) x (p2 - p0), normalised; (0,0,0) where the sum is zero (isolated vertices,
 * degenerate fans). Differences are taken in the positions' precision, the sums in double.
 * pos: nv*3, faces: nf*3 valid indices, nrm: nv*3 out. */
void spx_vertex_normals(const float *pos, int32_t nv, const int32_t *faces, int32_t nf, double *nrm);
void spx_vertex_normals_d(const double *pos, int32_t nv, const int32_t *faces, int32_t nf, double *nrm);

/* Loop subdivision as a sparse linear operator: every new vertex is a fixed weighted sum of old
 * vertices, so any per-vertex attribute (positions, colors, skinning weights, blend shapes) is
 * subdivided by applying the same operator. Boundaries use the standard crease rules.
 * Non-manifold edges (three or more faces) are treated as boundary edges; a vertex on more than
 * two boundary edges, or on no face, keeps its position. Old vertices keep indices 0..nv_in-1,
 * then one new vertex per edge. Details: lib/geom/loop.c. */
typedef struct spx_loop_plan {
  int32_t nv_in, nv_out, nf_out;
  int32_t *faces_out;  /* nf_out*3 */
  int64_t *row_start;  /* nv_out+1, CSR */
  int32_t *col;        /* old vertex index per nonzero */
  float *w;            /* weight per nonzero */
} spx_loop_plan;
spx_status spx_loop_plan_create(spx_ctx *ctx, int32_t nv, int32_t nf, const int32_t *faces, spx_loop_plan *plan);
/* out[nv_out*dim] = S * in[nv_in*dim] */
void spx_loop_plan_apply(const spx_loop_plan *plan, const float *in, int dim, float *out);
void spx_loop_plan_free(spx_loop_plan *plan);
/* Subdivide a mesh `levels` times (positions, colors, normals renormalised; UVs dropped). */
spx_status spx_mesh_subdivide(spx_ctx *ctx, const spx_mesh *in, int levels, spx_mesh *out);

#ifdef __cplusplus
}
#endif
#endif
