/* Private helpers of lib/fit: geometry (normals, adjacency, point-to-triangle) and k-d trees. */
#ifndef SPX_FIT_INTERNAL_H
#define SPX_FIT_INTERNAL_H

#include "core/internal.h"
#include "fit/ceres_bridge.h"
#include "smplpix/fit.h"

/* CSR adjacency: for each vertex, the incident faces (or neighbouring vertices). */
typedef struct spx_adj {
  int32_t n;
  int32_t *start; /* n+1 */
  int32_t *idx;
} spx_adj;
spx_status spx_fit_vertex_faces(spx_ctx *ctx, int32_t nv, const int32_t *faces, int32_t nf, spx_adj *out);
spx_status spx_fit_vertex_neighbours(spx_ctx *ctx, int32_t nv, const int32_t *faces, int32_t nf, spx_adj *out);
void spx_adj_free(spx_adj *a);

/* Squared distance from p to triangle (a, b, c); _closest also gives the closest point's
 * barycentric coordinates w (weights of a, b, c). */
double spx_fit_point_tri_closest(const double p[3], const double a[3], const double b[3], const double c[3],
                                 double w[3]);
double spx_fit_point_tri_d2(const double p[3], const double a[3], const double b[3], const double c[3]);
/* Same as spx_fit_surface_distance, with an already computed vertex → face adjacency. */
spx_status spx_fit_surface_distance_adj(spx_ctx *ctx, const float *pts, int32_t n, const float *verts, int32_t nv,
                                        const int32_t *faces, const spx_adj *vf, int threads, float *dist);
/* k-d tree wrappers that record failures on ctx. */
spx_status spx_fit_kd_build(spx_ctx *ctx, const float *pts, int32_t n, spx_kdtree **out);
spx_status spx_fit_kd_query(spx_ctx *ctx, const spx_kdtree *t, const float *q, int32_t nq, int k, int32_t *idx,
                            float *d2, int threads);

#endif
