/* Geometry helpers for registration: adjacency, normals, point-to-surface distances. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/fit_internal.h"

void spx_adj_free(spx_adj *a) {
  if (!a) return;
  free(a->start), free(a->idx);
  memset(a, 0, sizeof *a);
}

spx_status spx_fit_vertex_faces(spx_ctx *ctx, int32_t nv, const int32_t *faces, int32_t nf, spx_adj *out) {
  memset(out, 0, sizeof *out);
  out->n = nv;
  out->start = calloc((size_t)nv + 1, sizeof(int32_t));
  out->idx = spx_alloc_array(ctx, (size_t)nf * 3 + 1, sizeof(int32_t), "vertex-face adjacency");
  if (!out->start || !out->idx) {
    spx_adj_free(out);
    return spx_fail(ctx, SPX_E_NOMEM, "vertex-face adjacency: out of memory");
  }
  for (int32_t f = 0; f < nf; f++)
    for (int c = 0; c < 3; c++) out->start[faces[f * 3 + c] + 1]++;
  for (int32_t i = 0; i < nv; i++) out->start[i + 1] += out->start[i];
  int32_t *fill = calloc((size_t)nv + 1, sizeof(int32_t));
  if (!fill) {
    spx_adj_free(out);
    return spx_fail(ctx, SPX_E_NOMEM, "vertex-face adjacency: out of memory");
  }
  for (int32_t f = 0; f < nf; f++)
    for (int c = 0; c < 3; c++) {
      int32_t v = faces[f * 3 + c];
      out->idx[out->start[v] + fill[v]++] = f;
    }
  free(fill);
  return SPX_OK;
}

static int cmp_i32(const void *a, const void *b) {
  int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
  return (x > y) - (x < y);
}

spx_status spx_fit_vertex_neighbours(spx_ctx *ctx, int32_t nv, const int32_t *faces, int32_t nf, spx_adj *out) {
  spx_adj vf;
  spx_status st = spx_fit_vertex_faces(ctx, nv, faces, nf, &vf);
  if (st) return st;
  memset(out, 0, sizeof *out);
  out->n = nv;
  out->start = calloc((size_t)nv + 1, sizeof(int32_t));
  out->idx = spx_alloc_array(ctx, (size_t)nf * 6 + 1, sizeof(int32_t), "vertex neighbours");
  if (!out->start || !out->idx) {
    spx_adj_free(&vf);
    spx_adj_free(out);
    return spx_fail(ctx, SPX_E_NOMEM, "vertex neighbours: out of memory");
  }
  int32_t w = 0;
  for (int32_t i = 0; i < nv; i++) {
    out->start[i] = w;
    int32_t s = w;
    for (int32_t q = vf.start[i]; q < vf.start[i + 1]; q++) {
      const int32_t *F = faces + vf.idx[q] * 3;
      for (int c = 0; c < 3; c++)
        if (F[c] != i) out->idx[w++] = F[c];
    }
    qsort(out->idx + s, (size_t)(w - s), sizeof(int32_t), cmp_i32);
    int32_t u = s;
    for (int32_t q = s; q < w; q++)
      if (q == s || out->idx[q] != out->idx[q - 1]) out->idx[u++] = out->idx[q];
    w = u;
  }
  out->start[nv] = w;
  spx_adj_free(&vf);
  return SPX_OK;
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Closest point on a triangle by Voronoi regions (the classic construction): the point q (as a
 * corner, an edge point or a + s ab + t ac) and its barycentric coordinates (1 - s - t, s, t). */
double spx_fit_point_tri_closest(const double p[3], const double a[3], const double b[3], const double c[3],
                                 double w[3]) {
  double ab[3], ac[3], ap[3], bp[3], cp[3], q[3], s = 0, t = 0;
  for (int d = 0; d < 3; d++)
    ab[d] = b[d] - a[d], ac[d] = c[d] - a[d], ap[d] = p[d] - a[d], bp[d] = p[d] - b[d], cp[d] = p[d] - c[d];
  double d1 = dot3(ab, ap), d2 = dot3(ac, ap), d3 = dot3(ab, bp), d4 = dot3(ac, bp), d5 = dot3(ab, cp),
         d6 = dot3(ac, cp);
  double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
  if (d1 <= 0 && d2 <= 0) {
    memcpy(q, a, sizeof q);
  } else if (d3 >= 0 && d4 <= d3) {
    memcpy(q, b, sizeof q), s = 1;
  } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    s = d1 / (d1 - d3);
    for (int d = 0; d < 3; d++) q[d] = a[d] + s * ab[d];
  } else if (d6 >= 0 && d5 <= d6) {
    memcpy(q, c, sizeof q), t = 1;
  } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    t = d2 / (d2 - d6);
    for (int d = 0; d < 3; d++) q[d] = a[d] + t * ac[d];
  } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    t = (d4 - d3) / ((d4 - d3) + (d5 - d6)), s = 1 - t;
    for (int d = 0; d < 3; d++) q[d] = b[d] + t * (c[d] - b[d]);
  } else {
    double den = 1.0 / (va + vb + vc);
    s = vb * den, t = vc * den;
    for (int d = 0; d < 3; d++) q[d] = a[d] + ab[d] * s + ac[d] * t;
  }
  w[0] = 1 - s - t, w[1] = s, w[2] = t;
  double e[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
  return dot3(e, e);
}

double spx_fit_point_tri_d2(const double p[3], const double a[3], const double b[3], const double c[3]) {
  double w[3];
  return spx_fit_point_tri_closest(p, a, b, c, w);
}

spx_status spx_fit_kd_build(spx_ctx *ctx, const float *pts, int32_t n, spx_kdtree **out) {
  *out = spx_kdtree_build(pts, n);
  if (!*out) return spx_fail(ctx, SPX_E_NOMEM, "%s", spx_ceres_last_error());
  return SPX_OK;
}

spx_status spx_fit_kd_query(spx_ctx *ctx, const spx_kdtree *t, const float *q, int32_t nq, int k, int32_t *idx,
                            float *d2, int threads) {
  if (spx_kdtree_query(t, q, nq, k, idx, d2, threads)) return spx_fail(ctx, SPX_E_ARG, "%s", spx_ceres_last_error());
  return SPX_OK;
}

#define SPX_SURF_K 6

/* Closest surface point of each point over the faces around its k nearest vertices: dist[i] (may
 * be NULL), and when face is not NULL the face and barycentric coordinates (bary: n*3). */
static spx_status closest_adj(spx_ctx *ctx, const float *pts, int32_t n, const float *verts, int32_t nv,
                              const int32_t *faces, const spx_adj *vf, int threads, float *dist, int32_t *face,
                              float *bary) {
  int k = nv < SPX_SURF_K ? nv : SPX_SURF_K;
  spx_kdtree *t = NULL;
  spx_status st = spx_fit_kd_build(ctx, verts, nv, &t);
  if (st) return st;
  int32_t *idx = spx_alloc_array(ctx, (size_t)n, (size_t)k * sizeof(int32_t), "surface distance");
  float *d2 = spx_alloc_array(ctx, (size_t)n, (size_t)k * sizeof(float), "surface distance");
  if (!idx || !d2) {
    st = SPX_E_NOMEM;
    goto cleanup;
  }
  if ((st = spx_fit_kd_query(ctx, t, pts, n, k, idx, d2, threads))) goto cleanup;
  for (int32_t i = 0; i < n; i++) {
    double p[3] = {pts[i * 3], pts[i * 3 + 1], pts[i * 3 + 2]}, best = d2[(size_t)i * k], bt = INFINITY;
    double bw[3] = {1, 0, 0};
    int32_t bf = -1;
    for (int j = 0; j < k; j++) {
      int32_t v = idx[(size_t)i * k + j];
      for (int32_t q = vf->start[v]; q < vf->start[v + 1]; q++) {
        const int32_t *F = faces + vf->idx[q] * 3;
        double a[3], b[3], c[3], w[3];
        for (int d = 0; d < 3; d++)
          a[d] = verts[F[0] * 3 + d], b[d] = verts[F[1] * 3 + d], c[d] = verts[F[2] * 3 + d];
        double e = spx_fit_point_tri_closest(p, a, b, c, w);
        if (e < best) best = e;
        if (e < bt) bt = e, bf = vf->idx[q], memcpy(bw, w, sizeof w);
      }
    }
    if (dist) dist[i] = (float)sqrt(best);
    if (face) {
      face[i] = bf;
      for (int c = 0; c < 3; c++) bary[(size_t)i * 3 + c] = (float)bw[c];
    }
  }
cleanup:
  free(idx), free(d2);
  spx_kdtree_free(t);
  return st;
}

spx_status spx_fit_surface_distance_adj(spx_ctx *ctx, const float *pts, int32_t n, const float *verts, int32_t nv,
                                        const int32_t *faces, const spx_adj *vf, int threads, float *dist) {
  return closest_adj(ctx, pts, n, verts, nv, faces, vf, threads, dist, NULL, NULL);
}

static spx_status check_mesh_args(spx_ctx *ctx, const char *fn, const float *pts, int32_t n, const float *verts,
                                  int32_t nv, const int32_t *faces, int32_t nf) {
  if (!pts || n <= 0 || !verts || nv <= 0 || (nf > 0 && !faces) || nf < 0)
    return spx_fail(ctx, SPX_E_ARG, "%s: empty points or mesh", fn);
  for (int32_t f = 0; f < nf * 3; f++)
    if (faces[f] < 0 || faces[f] >= nv) return spx_fail(ctx, SPX_E_ARG, "%s: face index out of range", fn);
  return SPX_OK;
}

spx_status spx_fit_closest_points(spx_ctx *ctx, const float *pts, int32_t n, const float *verts, int32_t nv,
                                  const int32_t *faces, int32_t nf, int threads, int32_t *face, float *bary,
                                  float *dist) {
  spx_status st = check_mesh_args(ctx, "closest points", pts, n, verts, nv, faces, nf);
  if (st) return st;
  if (nf < 1 || !face || !bary) return spx_fail(ctx, SPX_E_ARG, "closest points: a mesh with faces and outputs needed");
  spx_adj vf;
  if ((st = spx_fit_vertex_faces(ctx, nv, faces, nf, &vf))) return st;
  st = closest_adj(ctx, pts, n, verts, nv, faces, &vf, threads < 1 ? 1 : threads, dist, face, bary);
  spx_adj_free(&vf);
  return st;
}

static int cmp_f(const void *a, const void *b) {
  float x = *(const float *)a, y = *(const float *)b;
  return (x > y) - (x < y);
}

spx_status spx_fit_surface_distance(spx_ctx *ctx, const float *pts, int32_t n, const float *verts, int32_t nv,
                                    const int32_t *faces, int32_t nf, float *dist, double *mean, double *median,
                                    double *p95) {
  spx_status st = check_mesh_args(ctx, "surface distance", pts, n, verts, nv, faces, nf);
  if (st) return st;
  spx_adj vf;
  if ((st = spx_fit_vertex_faces(ctx, nv, faces, nf, &vf))) return st;
  float *d = spx_alloc_array(ctx, (size_t)n, sizeof(float), "surface distance");
  if (!d) {
    spx_adj_free(&vf);
    return SPX_E_NOMEM;
  }
  st = spx_fit_surface_distance_adj(ctx, pts, n, verts, nv, faces, &vf, 1, d);
  if (!st) {
    double s = 0;
    for (int32_t i = 0; i < n; i++) s += d[i];
    if (mean) *mean = s / n;
    if (dist) memcpy(dist, d, (size_t)n * sizeof(float));
    if (median || p95) {
      qsort(d, (size_t)n, sizeof(float), cmp_f);
      if (median) *median = d[n / 2];
      if (p95) *p95 = d[(int32_t)fmin((double)n - 1, floor(0.95 * n))];
    }
  }
  free(d);
  spx_adj_free(&vf);
  return st;
}
