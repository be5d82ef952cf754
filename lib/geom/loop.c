/* Loop subdivision as a sparse linear operator (CSR), plus whole-mesh subdivision.
 *
 * New vertices: the nv old ("even") vertices keep their indices 0..nv-1; one new ("odd") vertex
 * per unique edge follows, numbered nv + (edge rank in (min,max) order).
 * Rules (Loop 1987, with Warren's simplified weights):
 *   interior even vertex of valence n: (1 - n*beta) v + beta * sum(neighbours),
 *                                      beta = 3/(8n) for n > 3, 3/16 for n <= 3;
 *   interior odd vertex (edge a-b with exactly two faces, opposite vertices c, d):
 *                                      3/8 a + 3/8 b + 1/8 c + 1/8 d;
 *   boundary odd vertex (edge with one face): 1/2 a + 1/2 b;
 *   boundary even vertex with exactly two boundary neighbours b0, b1: 3/4 v + 1/8 b0 + 1/8 b1.
 * Non-manifold edges (three or more faces) are treated as boundary edges (midpoint rule, and
 * their end vertices use the boundary rule). An even vertex on more than two boundary edges
 * (a corner where several boundaries or non-manifold fans meet) and a vertex used by no face
 * stay where they are (weight 1). All weights are non-negative and every row sums to 1, so
 * colors stay in range.
 * Each triangle (v0 v1 v2) with edge vertices m01 m12 m20 becomes (v0 m01 m20), (v1 m12 m01),
 * (v2 m20 m12), (m01 m12 m20): orientation is kept. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/mesh.h"

typedef struct half_edge {
  uint64_t key; /* min << 32 | max */
  int32_t he;   /* face*3 + corner of the edge's first vertex */
} half_edge;

static int cmp_he(const void *a, const void *b) {
  const half_edge *x = a, *y = b;
  if (x->key != y->key) return x->key < y->key ? -1 : 1;
  return (x->he > y->he) - (x->he < y->he);
}

void spx_loop_plan_free(spx_loop_plan *plan) {
  if (!plan) return;
  free(plan->faces_out);
  free(plan->row_start);
  free(plan->col);
  free(plan->w);
  memset(plan, 0, sizeof *plan);
}

/* The edges of a mesh: its half-edges sorted by edge, the unique edges (ends a <= b, face count,
 * first half-edge in he), each half-edge's edge, and per vertex its valence (deg), boundary valence
 * (bdeg) and neighbours (adj[adj_start[v] ..], with adj_bnd: over a boundary edge). */
typedef struct edges {
  size_t nhe, ne;
  half_edge *he;
  int32_t *he_edge, *a, *b, *cnt, *first;
  int32_t *deg, *bdeg, *adj;
  uint8_t *adj_bnd;
  int64_t *adj_start;
} edges;

static void edges_free(edges *E) {
  free(E->he);
  free(E->he_edge);
  free(E->a);
  free(E->b);
  free(E->cnt);
  free(E->first);
  free(E->deg);
  free(E->bdeg);
  free(E->adj);
  free(E->adj_bnd);
  free(E->adj_start);
}

/* The half-edges sorted by (min, max) end, and the unique edges they form. */
static spx_status find_edges(spx_ctx *ctx, int32_t nv, int32_t nf, const int32_t *faces, edges *E) {
  const size_t nhe = (size_t)nf * 3;
  E->nhe = nhe;
  E->he = spx_alloc_array(ctx, nhe, sizeof *E->he, "loop subdivision");
  E->he_edge = spx_alloc_array(ctx, nhe, sizeof *E->he_edge, "loop subdivision");
  if (!E->he || !E->he_edge) return SPX_E_NOMEM;
  half_edge *he = E->he;
  for (size_t i = 0; i < nhe; i++) {
    uint32_t a = (uint32_t)faces[i], b = (uint32_t)faces[i - i % 3 + (i % 3 + 1) % 3];
    he[i].key = a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a;
    he[i].he = (int32_t)i;
  }
  if (nhe) qsort(he, nhe, sizeof *he, cmp_he);
  size_t ne = 0;
  for (size_t i = 0; i < nhe; i++)
    if (i == 0 || he[i].key != he[i - 1].key) ne++;
  if ((uint64_t)nv + ne > INT32_MAX)
    return spx_fail(ctx, SPX_E_ARG, "loop subdivision: result would have more than 2^31 vertices");
  E->ne = ne;
  E->a = spx_alloc_array(ctx, ne ? ne : 1, sizeof(int32_t), "loop subdivision");
  E->b = spx_alloc_array(ctx, ne ? ne : 1, sizeof(int32_t), "loop subdivision");
  E->cnt = spx_alloc_array(ctx, ne ? ne : 1, sizeof(int32_t), "loop subdivision");
  E->first = spx_alloc_array(ctx, ne ? ne : 1, sizeof(int32_t), "loop subdivision"); /* index into he[] */
  E->deg = calloc((size_t)nv + 1, sizeof(int32_t));
  E->bdeg = calloc((size_t)nv + 1, sizeof(int32_t));
  if (!E->a || !E->b || !E->cnt || !E->first || !E->deg || !E->bdeg)
    return spx_fail(ctx, SPX_E_NOMEM, "loop subdivision: out of memory");
  size_t e = 0;
  for (size_t i = 0; i < nhe; i++) {
    if (i > 0 && he[i].key == he[i - 1].key) {
      E->cnt[e - 1]++;
    } else {
      E->a[e] = (int32_t)(he[i].key >> 32);
      E->b[e] = (int32_t)(he[i].key & 0xffffffffu);
      E->cnt[e] = 1;
      E->first[e] = (int32_t)i;
      e++;
    }
    E->he_edge[he[i].he] = (int32_t)(e - 1);
  }
  return SPX_OK;
}

/* Valences and neighbour lists; an edge without exactly two faces is a boundary edge. */
static spx_status find_neighbours(spx_ctx *ctx, int32_t nv, edges *E) {
  for (size_t k = 0; k < E->ne; k++) {
    if (E->a[k] == E->b[k]) continue; /* degenerate triangle edge: no neighbour relation */
    E->deg[E->a[k]]++;
    E->deg[E->b[k]]++;
    if (E->cnt[k] != 2) {
      E->bdeg[E->a[k]]++;
      E->bdeg[E->b[k]]++;
    }
  }
  E->adj_start = malloc(((size_t)nv + 1) * sizeof(int64_t));
  if (!E->adj_start) return spx_fail(ctx, SPX_E_NOMEM, "loop subdivision: out of memory");
  E->adj_start[0] = 0;
  for (int32_t v = 0; v < nv; v++) E->adj_start[v + 1] = E->adj_start[v] + E->deg[v];
  size_t nadj = (size_t)E->adj_start[nv];
  E->adj = malloc((nadj ? nadj : 1) * sizeof(int32_t));
  E->adj_bnd = malloc(nadj ? nadj : 1);
  if (!E->adj || !E->adj_bnd) return spx_fail(ctx, SPX_E_NOMEM, "loop subdivision: out of memory");
  memset(E->deg, 0, (size_t)nv * sizeof(int32_t)); /* reused as fill cursor */
  for (size_t k = 0; k < E->ne; k++) {
    int32_t a = E->a[k], b = E->b[k];
    if (a == b) continue;
    uint8_t bnd = E->cnt[k] != 2;
    int64_t ia = E->adj_start[a] + E->deg[a]++, ib = E->adj_start[b] + E->deg[b]++;
    E->adj[ia] = b;
    E->adj_bnd[ia] = bnd;
    E->adj[ib] = a;
    E->adj_bnd[ib] = bnd;
  }
  return SPX_OK;
}

/* The plan's sizes and arrays: a row per even vertex (1, 3 or 1 + valence weights) and per edge
 * (1, 4 or 2). */
static spx_status plan_alloc(spx_ctx *ctx, int32_t nv, int32_t nf, const edges *E, spx_loop_plan *p) {
  p->nv_in = nv;
  p->nv_out = (int32_t)((size_t)nv + E->ne);
  p->nf_out = nf * 4;
  p->row_start = malloc(((size_t)p->nv_out + 1) * sizeof(int64_t));
  if (!p->row_start) return spx_fail(ctx, SPX_E_NOMEM, "loop subdivision: out of memory");
  p->row_start[0] = 0;
  for (int32_t v = 0; v < nv; v++) {
    int32_t n = E->deg[v];
    int64_t len = n == 0 ? 1 : E->bdeg[v] > 0 ? (E->bdeg[v] == 2 ? 3 : 1) : 1 + n;
    p->row_start[v + 1] = p->row_start[v] + len;
  }
  for (size_t k = 0; k < E->ne; k++) {
    int64_t len = E->a[k] == E->b[k] ? 1 : E->cnt[k] == 2 ? 4 : 2;
    p->row_start[(size_t)nv + k + 1] = p->row_start[(size_t)nv + k] + len;
  }
  size_t nnz = (size_t)p->row_start[p->nv_out];
  p->col = spx_alloc_array(ctx, nnz ? nnz : 1, sizeof(int32_t), "loop subdivision");
  p->w = spx_alloc_array(ctx, nnz ? nnz : 1, sizeof(float), "loop subdivision");
  p->faces_out = spx_alloc_array(ctx, (size_t)p->nf_out ? (size_t)p->nf_out : 1, 3 * sizeof(int32_t), "loop subdivision");
  return p->col && p->w && p->faces_out ? SPX_OK : SPX_E_NOMEM;
}

/* the even vertices' rows (the rules at the top of this file) */
static void even_rows(int32_t nv, const edges *E, spx_loop_plan *p) {
  for (int32_t v = 0; v < nv; v++) {
    int64_t o = p->row_start[v];
    int32_t n = E->deg[v];
    const int32_t *nb = E->adj + E->adj_start[v];
    const uint8_t *nbb = E->adj_bnd + E->adj_start[v];
    if (n == 0 || (E->bdeg[v] > 0 && E->bdeg[v] != 2)) {
      p->col[o] = v;
      p->w[o] = 1.0f;
    } else if (E->bdeg[v] == 2) {
      p->col[o] = v;
      p->w[o] = 0.75f;
      int64_t q = o + 1;
      for (int32_t j = 0; j < n; j++)
        if (nbb[j]) {
          p->col[q] = nb[j];
          p->w[q++] = 0.125f;
        }
    } else {
      double beta = n > 3 ? 3.0 / (8.0 * n) : 3.0 / 16.0;
      p->col[o] = v;
      p->w[o] = (float)(1.0 - n * beta);
      for (int32_t j = 0; j < n; j++) {
        p->col[o + 1 + j] = nb[j];
        p->w[o + 1 + j] = (float)beta;
      }
    }
  }
}

/* the odd (edge) vertices' rows */
static void odd_rows(int32_t nv, const int32_t *faces, const edges *E, spx_loop_plan *p) {
  for (size_t k = 0; k < E->ne; k++) {
    int64_t o = p->row_start[(size_t)nv + k];
    int32_t a = E->a[k], b = E->b[k];
    if (a == b) {
      p->col[o] = a;
      p->w[o] = 1.0f;
    } else if (E->cnt[k] == 2) {
      int32_t h0 = E->he[E->first[k]].he, h1 = E->he[E->first[k] + 1].he;
      /* the corner opposite an edge that starts at corner c is corner (c + 2) % 3 */
      int32_t c = faces[h0 - h0 % 3 + (h0 % 3 + 2) % 3], d = faces[h1 - h1 % 3 + (h1 % 3 + 2) % 3];
      p->col[o] = a;
      p->w[o] = 0.375f;
      p->col[o + 1] = b;
      p->w[o + 1] = 0.375f;
      p->col[o + 2] = c;
      p->w[o + 2] = 0.125f;
      p->col[o + 3] = d;
      p->w[o + 3] = 0.125f;
    } else {
      p->col[o] = a;
      p->w[o] = 0.5f;
      p->col[o + 1] = b;
      p->w[o + 1] = 0.5f;
    }
  }
}

/* each triangle into four, orientation kept */
static void split_faces(int32_t nv, int32_t nf, const int32_t *faces, const edges *E, spx_loop_plan *p) {
  for (int32_t f = 0; f < nf; f++) {
    const int32_t *t = faces + (size_t)f * 3;
    const int32_t *he_edge = E->he_edge + (size_t)f * 3;
    int32_t m01 = nv + he_edge[0], m12 = nv + he_edge[1], m20 = nv + he_edge[2];
    int32_t *o = p->faces_out + (size_t)f * 12;
    int32_t nt[12] = {t[0], m01, m20, t[1], m12, m01, t[2], m20, m12, m01, m12, m20};
    memcpy(o, nt, sizeof nt);
  }
}

spx_status spx_loop_plan_create(spx_ctx *ctx, int32_t nv, int32_t nf, const int32_t *faces, spx_loop_plan *plan) {
  if (!plan) return spx_fail(ctx, SPX_E_ARG, "loop subdivision: no plan");
  memset(plan, 0, sizeof *plan);
  if (nv < 0 || nf < 0 || (nf > 0 && !faces)) return spx_fail(ctx, SPX_E_ARG, "loop subdivision: bad mesh (nv %d, nf %d)", nv, nf);
  if (nf > INT32_MAX / 4) return spx_fail(ctx, SPX_E_ARG, "loop subdivision: %d faces is too many to subdivide", nf);
  for (size_t i = 0; i < (size_t)nf * 3; i++)
    if (faces[i] < 0 || faces[i] >= nv)
      return spx_fail(ctx, SPX_E_ARG, "loop subdivision: face %zu uses vertex %d, outside 0..%d", i / 3, faces[i], nv - 1);
  edges E;
  memset(&E, 0, sizeof E);
  spx_loop_plan p = {0};
  spx_status st = find_edges(ctx, nv, nf, faces, &E);
  if (!st) st = find_neighbours(ctx, nv, &E);
  if (!st) st = plan_alloc(ctx, nv, nf, &E, &p);
  if (!st) {
    even_rows(nv, &E, &p);
    odd_rows(nv, faces, &E, &p);
    split_faces(nv, nf, faces, &E, &p);
    *plan = p;
    memset(&p, 0, sizeof p);
  }
  spx_loop_plan_free(&p);
  edges_free(&E);
  return st;
}

void spx_loop_plan_apply(const spx_loop_plan *plan, const float *in, int dim, float *out) {
  for (int32_t r = 0; r < plan->nv_out; r++) {
    int64_t a = plan->row_start[r], b = plan->row_start[r + 1];
    for (int d = 0; d < dim; d++) {
      double acc = 0;
      for (int64_t k = a; k < b; k++) acc += (double)plan->w[k] * (double)in[(size_t)plan->col[k] * (size_t)dim + (size_t)d];
      out[(size_t)r * (size_t)dim + (size_t)d] = (float)acc;
    }
  }
}

spx_status spx_mesh_subdivide(spx_ctx *ctx, const spx_mesh *in, int levels, spx_mesh *out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "subdivide: no output mesh");
  memset(out, 0, sizeof *out);
  if (!in || levels < 0 || levels > 10) return spx_fail(ctx, SPX_E_ARG, "subdivide: bad arguments (levels %d, 0..10)", levels);
  spx_status st = spx_mesh_validate(ctx, "subdivide input", in);
  if (st) return st;
  spx_mesh cur;
  if ((st = spx_mesh_copy(ctx, in, &cur))) return st;
  free(cur.uv);
  free(cur.face_uv);
  cur.uv = NULL;
  cur.face_uv = NULL;
  cur.nuv = 0;
  for (int l = 0; l < levels; l++) {
    spx_loop_plan plan;
    if ((st = spx_loop_plan_create(ctx, cur.nv, cur.nf, cur.faces, &plan))) goto fail;
    spx_mesh nx = {0};
    nx.nv = plan.nv_out;
    nx.nf = plan.nf_out;
    nx.faces = plan.faces_out;
    plan.faces_out = NULL;
    if (nx.nf == 0) {
      free(nx.faces);
      nx.faces = NULL;
    }
    nx.pos = spx_alloc_array(ctx, (size_t)nx.nv, 3 * sizeof(float), "subdivide");
    if (cur.col) nx.col = spx_alloc_array(ctx, (size_t)nx.nv, 3 * sizeof(float), "subdivide");
    if (cur.nrm) nx.nrm = spx_alloc_array(ctx, (size_t)nx.nv, 3 * sizeof(float), "subdivide");
    if (!nx.pos || (cur.col && !nx.col) || (cur.nrm && !nx.nrm)) {
      st = SPX_E_NOMEM;
      spx_mesh_free(&nx);
      spx_loop_plan_free(&plan);
      goto fail;
    }
    spx_loop_plan_apply(&plan, cur.pos, 3, nx.pos);
    if (cur.col) spx_loop_plan_apply(&plan, cur.col, 3, nx.col);
    if (cur.nrm) {
      spx_loop_plan_apply(&plan, cur.nrm, 3, nx.nrm);
      for (size_t i = 0; i < (size_t)nx.nv; i++) {
        float *n = nx.nrm + i * 3;
        double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (len > 0)
          for (int k = 0; k < 3; k++) n[k] = (float)(n[k] / len);
      }
    }
    spx_loop_plan_free(&plan);
    spx_mesh_free(&cur);
    cur = nx;
  }
  *out = cur;
  return SPX_OK;
fail:
  spx_mesh_free(&cur);
  return st;
}
