/* Stage 3 of the registration (SPX_FIT_FREE): every vertex free, coupled to the posed model
 * (coupling weight annealed from w_couple_start to w_couple_end; where no scan point supports a
 * vertex, to the posed model moved by the continued offset of the supported ones), with a
 * uniform-Laplacian regulariser that keeps each vertex's Laplacian close to the posed model's, and
 * the pose stage's data terms (both along the normal). The scan → model term is gathered into one
 * residual per vertex (spx_fit_gather_scan), so its cost does not grow with the scan sample: the
 * stage takes up to max_points_free (100,000) points, every point of a 50k scan and all or most of
 * four fused depth frames, where a sample of 20,000 left the registration noisier
 * (benchmarks/RESULTS.md). With SPX_FIT_AID_SURFACE the gathered points are first moved out by
 * their ring gap (spx_fit_ring_gap): fitted to its vertices' tangent planes, the surface between
 * the vertices ended ~0.5 mm inside the scan on every body. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/stage.h"

int spx_fit_free_plane_cost(void *user, const double *const *par, double *res, double **jac) {
  const spx_fit_free_pair *q = user;
  const double *x = par[0];
  res[0] = q->a * (q->n[0] * (x[0] - q->q[0]) + q->n[1] * (x[1] - q->q[1]) + q->n[2] * (x[2] - q->q[2]));
  if (jac && jac[0])
    for (int d = 0; d < 3; d++) jac[0][d] = q->a * q->n[d];
  return 1;
}

int spx_fit_free_point_cost(void *user, const double *const *par, double *res, double **jac) {
  const spx_fit_free_pair *q = user;
  for (int d = 0; d < 3; d++) res[d] = q->a * (par[0][d] - q->q[d]);
  if (jac && jac[0])
    for (int d = 0; d < 9; d++) jac[0][d] = (d % 4 == 0) ? q->a : 0.0;
  return 1;
}

int spx_fit_lap_cost(void *user, const double *const *par, double *res, double **jac) {
  const spx_fit_lap *l = user;
  for (int d = 0; d < 3; d++) {
    double s = 0;
    for (int32_t k = 0; k < l->deg; k++) s += par[1 + k][d];
    res[d] = l->a * (par[0][d] - s / l->deg - l->target[d]);
  }
  if (jac)
    for (int32_t k = 0; k <= l->deg; k++) {
      if (!jac[k]) continue;
      double v = k == 0 ? l->a : -l->a / l->deg;
      for (int d = 0; d < 9; d++) jac[k][d] = (d % 4 == 0) ? v : 0.0;
    }
  return 1;
}


/* Support of vertex j by the scan: 1 within 2 cm of a scan point, falling to 0 at 5 cm; 0 with a
 * view when no camera would have seen j (w->seen). */
static double support(const spx_fit_work *w, int32_t j) {
  double d = sqrt(w->d2_m[j]), s = !w->neye || w->seen[j] ? (0.05 - d) / 0.03 : 0.0;
  return s < 0 ? 0 : s > 1 ? 1 : s;
}

/* Unsupported vertices (holes, the side no camera saw) are drawn to the posed model's surface moved
 * by the continued offset (continue_offsets): their coupling weight is W_UNSUPPORTED instead of the
 * annealed wc. It is about the annealed weight's end (w_couple_end, 0.02), not a stiff hold: the
 * Laplacian term then carries the seen surface's shape on over the unseen part, and the seen
 * vertices next to it are not held back by a model surface that is wrong there (on the bodies the
 * model cannot reproduce, 30 times this weight left both the seen and the unseen part farther off;
 * benchmarks/RESULTS.md). Returns sqrt(weight / wc), the factor on the coupling residual. */
#define W_UNSUPPORTED 0.03
static double support_coupling(double s, double wc) { return sqrt((s * wc + (1 - s) * W_UNSUPPORTED) / wc); }

/* One free step's problem over the vertices X (the parameters). */
typedef struct free_stage {
  const spx_fit_options *o;
  spx_fit_work *w;
  int32_t nv, steps;
  double *X;        /* nv*3 vertices: the parameter blocks */
  const double *Vp; /* the posed model */
  double *Np;       /* nv*3 its normals */
  double *tgt;      /* nv*3 coupling targets: Vp, moved along Np by the continued offset where unsupported */
  double *off;      /* nv offsets along Np */
  unsigned char *known; /* nv */
  double *wsum, *qsum; /* nv, nv*3: spx_fit_gather_scan's scratch */
  int32_t *vert;    /* nv: the vertex of each gathered pair */
  const int32_t *faces; /* the model's */
  double *gap;      /* nqf: spx_fit_ring_gap of each scan point (SPX_FIT_AID_SURFACE), or NULL */
  int *sizes;       /* maxdeg+1 threes */
  double **blocks;  /* maxdeg+1 */
} free_stage;

/* The seen side's offsets from the posed model (along its normals, where a vertex is supported)
 * continued over the unsupported vertices by the screened-harmonic fill (extend.c), clamped to
 * OFFSET_MAX; the coupling targets move with them. What the scan shows of how this person differs
 * from the body model (clothes, a fuller figure) carries on around the side no camera saw instead
 * of stopping at the silhouette. */
#define OFFSET_MAX 0.05
#define OFFSET_EPS 1e-4
static spx_status continue_offsets(spx_ctx *ctx, free_stage *fs) {
  const spx_fit_work *w = fs->w;
  for (int32_t j = 0; j < fs->nv; j++) {
    const double *x = fs->X + j * 3, *v = fs->Vp + j * 3, *n = fs->Np + j * 3;
    fs->known[j] = support(w, j) >= 0.5;
    fs->off[j] = fs->known[j] ? n[0] * (x[0] - v[0]) + n[1] * (x[1] - v[1]) + n[2] * (x[2] - v[2]) : 0;
  }
  spx_status st = !(fs->o->aids & SPX_FIT_AID_CONTINUE) ? SPX_OK
                                                     : spx_fit_harmonic_fill(ctx, &w->nb, fs->known, OFFSET_EPS, 400,
                                                                             fs->off);
  for (int32_t j = 0; !st && j < fs->nv; j++) {
    double s = support(w, j), o = (1 - s) * fmax(-OFFSET_MAX, fmin(OFFSET_MAX, fs->off[j]));
    if (!(fs->o->aids & SPX_FIT_AID_CONTINUE)) o = 0;
    for (int d = 0; d < 3; d++) fs->tgt[j * 3 + d] = fs->Vp[j * 3 + d] + o * fs->Np[j * 3 + d];
  }
  return st;
}

void spx_fit_ring_gap(const float *Q, int32_t nq, const int32_t *idx, const float *d2, double thr, const double *X,
                      const double *N, const int32_t *faces, const spx_adj *vf, double *gap) {
  for (int32_t i = 0; i < nq; i++) {
    int32_t j = idx[i];
    gap[i] = 0;
    if (d2[i] > thr * thr || vf->start[j] == vf->start[j + 1]) continue;
    double p[3] = {Q[i * 3], Q[i * 3 + 1], Q[i * 3 + 2]}, best = INFINITY, c[3] = {0, 0, 0};
    for (int32_t k = vf->start[j]; k < vf->start[j + 1]; k++) {
      const int32_t *F = faces + (size_t)vf->idx[k] * 3;
      double w[3], e = spx_fit_point_tri_closest(p, X + F[0] * 3, X + F[1] * 3, X + F[2] * 3, w);
      if (e >= best) continue;
      best = e;
      for (int d = 0; d < 3; d++) c[d] = w[0] * X[F[0] * 3 + d] + w[1] * X[F[1] * 3 + d] + w[2] * X[F[2] * 3 + d];
    }
    const double *x = X + (size_t)j * 3, *n = N + (size_t)j * 3;
    double g = n[0] * (x[0] - c[0]) + n[1] * (x[1] - c[1]) + n[2] * (x[2] - c[2]);
    gap[i] = fmax(-SPX_FIT_GAP_MAX, fmin(SPX_FIT_GAP_MAX, g));
  }
}

int32_t spx_fit_gather_scan(const float *Q, int32_t nq, const int32_t *idx, const float *d2, double thr,
                            const double *N, int32_t nv, double a1, const double *gap, const float *wt,
                            double *wsum, double *qsum, int32_t *vert, spx_fit_free_pair *out) {
  memset(wsum, 0, (size_t)nv * sizeof *wsum);
  memset(qsum, 0, (size_t)nv * 3 * sizeof *qsum);
  for (int32_t i = 0; i < nq; i++) {
    if (d2[i] > thr * thr) continue;
    int32_t j = idx[i];
    double g = gap ? gap[i] : 0, v = wt ? wt[i] : 1;
    wsum[j] += v;
    for (int d = 0; d < 3; d++) qsum[j * 3 + d] += v * (Q[i * 3 + d] + g * N[j * 3 + d]);
  }
  int32_t np = 0;
  for (int32_t j = 0; j < nv; j++) {
    if (!(wsum[j] > 0)) continue;
    spx_fit_free_pair *q = out + np;
    q->a = a1 * sqrt(wsum[j]);
    for (int d = 0; d < 3; d++) q->q[d] = qsum[j * 3 + d] / wsum[j], q->n[d] = N[j * 3 + d];
    vert[np++] = j;
  }
  return np;
}

static spx_status free_residuals(spx_ctx *ctx, spx_ceres_problem *pb, void *user, int32_t step) {
  free_stage *fs = user;
  const spx_fit_options *o = fs->o;
  spx_fit_work *w = fs->w;
  int32_t nv = fs->nv;
  double *X = fs->X;
  int *sizes = fs->sizes;
  double frac = fs->steps > 1 ? (double)step / (fs->steps - 1) : 1.0;
  double wc = o->w_couple_start * pow(o->w_couple_end / o->w_couple_start, frac);
  double thr = 0.03;
  double a1 = sqrt(1.0 / w->nqf), ac = sqrt(wc / nv), al = sqrt(o->w_lap / nv);
  spx_status st = continue_offsets(ctx, fs);
  if (st) return st;
  if (fs->gap) spx_fit_ring_gap(w->Qf, w->nqf, w->idx, w->d2, thr, X, w->N, fs->faces, &w->vf, fs->gap);
  int32_t np = spx_fit_gather_scan(w->Qf, w->nqf, w->idx, w->d2, thr, w->N, nv, a1, fs->gap, w->wq, fs->wsum,
                                   fs->qsum, fs->vert, w->fp);
  for (int32_t k = 0; k < np; k++) {
    double *blk = X + fs->vert[k] * 3;
    if (spx_ceres_add_residual(pb, spx_fit_free_plane_cost, w->fp + k, 1, 1, sizes, &blk, SPX_LOSS_HUBER,
                               w->fp[k].a * o->robust_m * 0.5))
      return spx_fit_ceres_error(ctx, "free");
  }
  for (int32_t k = 0; k < w->nfs; k++) { /* free space (freespace.c), as in the pose stage */
    spx_fit_free_pair *q = w->fp + np++;
    double *blk = X + w->fs_j[k] * 3;
    q->a = sqrt(W_FREE_SPACE * w->area[w->fs_j[k]]);
    for (int d = 0; d < 3; d++) q->q[d] = w->fs_q[k * 3 + d], q->n[d] = w->fs_n[k * 3 + d];
    if (spx_ceres_add_residual(pb, spx_fit_free_plane_cost, q, 1, 1, sizes, &blk, SPX_LOSS_HUBER, q->a * o->robust_m))
      return spx_fit_ceres_error(ctx, "free");
  }
  for (int32_t j = 0; j < nv; j++) {
    double *blk = X + j * 3;
    if (w->d2_m[j] <= thr * thr && spx_fit_m2s_ok(w, j)) {
      spx_fit_free_pair *q = w->fp + np++;
      q->a = sqrt(o->w_m2s * w->area[j]);
      for (int d = 0; d < 3; d++) q->q[d] = w->Qf[w->idx_m[j] * 3 + d], q->n[d] = w->N[j * 3 + d];
      /* along the normal only: tangential sliding toward noisy samples would distort the mesh */
      if (spx_ceres_add_residual(pb, spx_fit_free_plane_cost, q, 1, 1, sizes, &blk, SPX_LOSS_CAUCHY,
                                 q->a * o->robust_m * 0.5))
        return spx_fit_ceres_error(ctx, "free");
    }
    spx_fit_free_pair *c = w->fp + np++;
    c->a = ac * support_coupling(support(w, j), wc);
    for (int d = 0; d < 3; d++) c->q[d] = fs->tgt[j * 3 + d];
    if (spx_ceres_add_residual(pb, spx_fit_free_point_cost, c, 3, 1, sizes, &blk, SPX_LOSS_NONE, 0))
      return spx_fit_ceres_error(ctx, "free");
    spx_fit_lap *l = w->lp + j;
    if (l->deg == 0) continue;
    l->a = al;
    fs->blocks[0] = blk;
    for (int32_t k = 0; k < l->deg; k++) fs->blocks[1 + k] = X + w->nb.idx[w->nb.start[j] + k] * 3;
    if (spx_ceres_add_residual(pb, spx_fit_lap_cost, l, 3, 1 + l->deg, sizes, fs->blocks, SPX_LOSS_NONE, 0))
      return spx_fit_ceres_error(ctx, "free");
  }
  return SPX_OK;
}

spx_status spx_fit_stage_free(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, spx_fit_work *w,
                              spx_fit_result *r) {
  int32_t nv = m->nv;
  double *X = r->verts_model; /* starts at the posed model */
  const double *Vp = r->verts_pose;
  int32_t maxdeg = 0;
  for (int32_t i = 0; i < nv; i++) {
    int32_t dg = w->nb.start[i + 1] - w->nb.start[i];
    if (dg > maxdeg) maxdeg = dg;
  }
  int *sizes = spx_alloc_array(ctx, (size_t)maxdeg + 1, sizeof(int), "free stage");
  double **blocks = spx_alloc_array(ctx, (size_t)maxdeg + 1, sizeof(double *), "free stage");
  double *Np = spx_alloc_array(ctx, (size_t)nv, 7 * sizeof(double), "free stage");
  unsigned char *known = spx_alloc_array(ctx, (size_t)nv, 1, "free stage");
  int32_t *vert = spx_alloc_array(ctx, (size_t)nv, sizeof(int32_t), "free stage");
  double *qsum = spx_alloc_array(ctx, (size_t)nv, 4 * sizeof(double), "free stage");
  int surf = (o->aids & SPX_FIT_AID_SURFACE) != 0;
  double *gap = surf ? spx_alloc_array(ctx, (size_t)w->nqf + 1, sizeof(double), "free stage") : NULL;
  spx_status st = SPX_OK;
  if (!sizes || !blocks || !Np || !known || !vert || !qsum || (surf && !gap)) {
    st = SPX_E_NOMEM;
    goto cleanup;
  }
  spx_vertex_normals_d(Vp, nv, m->faces, m->nf, Np);
  for (int32_t k = 0; k <= maxdeg; k++) sizes[k] = 3;
  for (int32_t i = 0; i < nv; i++) {
    spx_fit_lap *l = w->lp + i;
    l->deg = w->nb.start[i + 1] - w->nb.start[i];
    for (int d = 0; d < 3; d++) {
      double s = 0;
      for (int32_t k = w->nb.start[i]; k < w->nb.start[i + 1]; k++) s += Vp[w->nb.idx[k] * 3 + d];
      l->target[d] = l->deg ? Vp[i * 3 + d] - s / l->deg : 0;
    }
  }
  free_stage fs = {o, w, nv, o->free_steps > 0 ? o->free_steps : 1, X, Vp, Np, Np + 3 * (size_t)nv,
                   Np + 6 * (size_t)nv, known, qsum + 3 * (size_t)nv, qsum, vert, m->faces, gap, sizes, blocks};
  spx_fit_stage s = {"free", 2, fs.steps, w->Qf, w->nqf, X, NULL,
                     {"free", free_residuals, &fs, NULL, NULL, NULL,
                      o->free_inner_iterations > 0 ? o->free_inner_iterations : o->inner_iterations,
                      SPX_LS_SPARSE_NORMAL_CHOLESKY}};
  st = spx_fit_run_stage(ctx, m, o, w, &s, r);
cleanup:
  free(sizes), free(blocks), free(Np), free(known), free(vert), free(qsum), free(gap);
  return st;
}
