/* Staged scan-to-body registration: rigid (similarity + orientation search), pose + shape with
 * priors, free vertices with a Laplacian regulariser. All solves go through the Ceres bridge
 * (lib/fit/ceres_bridge.cpp) with the analytic Jacobians written out here; nearest neighbours come
 * from nanoflann k-d trees rebuilt between outer iterations. See smplpix/fit.h for the stages. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "fit/fit_internal.h"

void spx_fit_options_default(spx_fit_options *o) {
  memset(o, 0, sizeof *o);
  o->stages = SPX_FIT_ALL;
  o->threads = 1;
  o->nbetas = -1;
  o->unit_scale = 0;
  o->max_points_rigid = 2000;
  o->max_points_pose = 6000;
  o->max_points_free = 20000;
  o->pose_steps = 20;
  o->free_steps = 4;
  o->inner_iterations = 4;
  o->free_inner_iterations = 2;
  o->w_shape = 2e-3;
  o->w_pose = 1e-3;
  o->w_pose_start = 0.1;
  o->w_limits = 0.1;
  o->w_scale = 1.0;
  o->w_m2s = 1.0;
  o->w_lap = 1.0;
  o->w_couple_start = 0.3;
  o->w_couple_end = 0.02;
  o->robust_m = 0.01;
  o->seed = 0x5eed;
}

void spx_fit_result_free(spx_fit_result *r) {
  if (!r) return;
  free(r->betas), free(r->pose), free(r->verts_model), free(r->verts_pose), free(r->verts_scan);
  free(r->colors), free(r->template_unposed), free(r->faces);
  memset(r, 0, sizeof *r);
}

/* ---------- small helpers ---------- */

static void mat3_mul(const double *A, const double *B, double *C) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) C[i * 3 + j] = A[i * 3] * B[j] + A[i * 3 + 1] * B[3 + j] + A[i * 3 + 2] * B[6 + j];
}
static void mat3_vec(const double *A, const double *x, double *y) {
  for (int i = 0; i < 3; i++) y[i] = A[i * 3] * x[0] + A[i * 3 + 1] * x[1] + A[i * 3 + 2] * x[2];
}
static void mat3t_vec(const double *A, const double *x, double *y) {
  for (int i = 0; i < 3; i++) y[i] = A[i] * x[0] + A[3 + i] * x[1] + A[6 + i] * x[2];
}
static void cross3(const double *a, const double *b, double *c) {
  c[0] = a[1] * b[2] - a[2] * b[1], c[1] = a[2] * b[0] - a[0] * b[2], c[2] = a[0] * b[1] - a[1] * b[0];
}

static uint64_t rng_next(uint64_t *s) {
  *s ^= *s >> 12, *s ^= *s << 25, *s ^= *s >> 27;
  return *s * 2685821657736338717ULL;
}

/* Deterministic subsample of n indices down to at most k (partial Fisher-Yates). */
static int32_t *subsample(spx_ctx *ctx, int32_t n, int32_t k, uint64_t seed, int32_t *out_k) {
  if (k <= 0 || k > n) k = n;
  int32_t *idx = spx_alloc_array(ctx, (size_t)n, sizeof(int32_t), "scan subsample");
  if (!idx) return NULL;
  for (int32_t i = 0; i < n; i++) idx[i] = i;
  uint64_t s = seed ? seed : 1;
  for (int32_t i = 0; i < k && k < n; i++) {
    int32_t j = i + (int32_t)(rng_next(&s) % (uint64_t)(n - i));
    int32_t t = idx[i];
    idx[i] = idx[j], idx[j] = t;
  }
  *out_k = k;
  return idx;
}

/* Symmetric 3x3 eigen-decomposition by Jacobi rotations: columns of V, values descending. */
static void eig3(const double *A0, double *w, double *V) {
  double A[9];
  memcpy(A, A0, sizeof A);
  for (int i = 0; i < 9; i++) V[i] = (i % 4 == 0);
  for (int sweep = 0; sweep < 50; sweep++) {
    double off = fabs(A[1]) + fabs(A[2]) + fabs(A[5]);
    if (off < 1e-15) break;
    for (int p = 0; p < 2; p++)
      for (int q = p + 1; q < 3; q++) {
        double apq = A[p * 3 + q];
        if (fabs(apq) < 1e-300) continue;
        double th = (A[q * 3 + q] - A[p * 3 + p]) / (2 * apq);
        double t = (th >= 0 ? 1.0 : -1.0) / (fabs(th) + sqrt(th * th + 1));
        double c = 1 / sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < 3; k++) { /* A = J^T A J */
          double akp = A[k * 3 + p], akq = A[k * 3 + q];
          A[k * 3 + p] = c * akp - s * akq, A[k * 3 + q] = s * akp + c * akq;
        }
        for (int k = 0; k < 3; k++) {
          double apk = A[p * 3 + k], aqk = A[q * 3 + k];
          A[p * 3 + k] = c * apk - s * aqk, A[q * 3 + k] = s * apk + c * aqk;
        }
        for (int k = 0; k < 3; k++) {
          double vkp = V[k * 3 + p], vkq = V[k * 3 + q];
          V[k * 3 + p] = c * vkp - s * vkq, V[k * 3 + q] = s * vkp + c * vkq;
        }
      }
  }
  int ord[3] = {0, 1, 2};
  for (int i = 0; i < 3; i++)
    for (int j = i + 1; j < 3; j++)
      if (A[ord[j] * 4] > A[ord[i] * 4]) {
        int t = ord[i];
        ord[i] = ord[j], ord[j] = t;
      }
  double W[9];
  for (int i = 0; i < 3; i++) {
    w[i] = A[ord[i] * 4];
    for (int k = 0; k < 3; k++) W[k * 3 + i] = V[k * 3 + ord[i]];
  }
  memcpy(V, W, sizeof W);
}

/* Rotation whose columns are the model axes' images: x → up × front, y → up, z → front. */
static void frame_from(const double up[3], const double front[3], double *R) {
  double r[3];
  cross3(up, front, r);
  for (int i = 0; i < 3; i++) R[i * 3] = r[i], R[i * 3 + 1] = up[i], R[i * 3 + 2] = front[i];
}

static void report(const spx_fit_options *o, const char *stage, int32_t step, int32_t n, double energy, double mean,
                   double t0, const char *note) {
  if (!o->progress) return;
  spx_fit_progress p = {stage, step, n, energy, mean, spx_now() - t0, note};
  o->progress(o->progress_user, &p);
}

static spx_status ceres_err(spx_ctx *ctx, const char *what) {
  return spx_fail(ctx, SPX_E_NUMERIC, "registration (%s): %s", what, spx_ceres_last_error());
}

/* ---------- stage 1: rigid (similarity) ---------- */

typedef struct rigid_pair {
  const double *z; /* Rc (v - cm) of the model sample point */
  double p[3];     /* scan point (metres) */
  double a;        /* residual weight */
} rigid_pair;

/* x = s R(w) z + t;  r = a (x - p). Blocks: w(3), s(1), t(3). */
static int rigid_cost(void *user, const double *const *par, double *res, double **jac) {
  const rigid_pair *q = user;
  double R[9], dR[27], Rz[3];
  spx_body_rodrigues(par[0], R, jac && jac[0] ? dR : NULL);
  double s = par[1][0];
  mat3_vec(R, q->z, Rz);
  for (int d = 0; d < 3; d++) res[d] = q->a * (s * Rz[d] + par[2][d] - q->p[d]);
  if (jac) {
    if (jac[0])
      for (int c = 0; c < 3; c++) {
        double o[3];
        mat3_vec(dR + c * 9, q->z, o);
        for (int d = 0; d < 3; d++) jac[0][d * 3 + c] = q->a * s * o[d];
      }
    if (jac[1])
      for (int d = 0; d < 3; d++) jac[1][d] = q->a * Rz[d];
    if (jac[2])
      for (int d = 0; d < 3; d++)
        for (int c = 0; c < 3; c++) jac[2][d * 3 + c] = d == c ? q->a : 0.0;
  }
  return 1;
}

typedef struct rigid_state {
  double Rc[9];
  double w[3], s[1], t[3];
  double score;
} rigid_state;

/* ICP from a candidate orientation. Y: nm centred model points, S: ns scan points (with kd tree). */
static spx_status rigid_icp(spx_ctx *ctx, const spx_fit_options *o, const double *Y, int32_t nm, const float *S,
                            int32_t ns, const spx_kdtree *scan_tree, int rounds, int iters, int free_scale,
                            rigid_state *st_io) {
  spx_status st = SPX_OK;
  double *Z = spx_alloc_array(ctx, (size_t)nm * 3, sizeof(double), "rigid");
  float *X = spx_alloc_array(ctx, (size_t)nm * 3, sizeof(float), "rigid");
  int32_t *i_s2m = spx_alloc_array(ctx, (size_t)ns, sizeof(int32_t), "rigid");
  int32_t *i_m2s = spx_alloc_array(ctx, (size_t)nm, sizeof(int32_t), "rigid");
  float *d_s2m = spx_alloc_array(ctx, (size_t)ns, sizeof(float), "rigid");
  float *d_m2s = spx_alloc_array(ctx, (size_t)nm, sizeof(float), "rigid");
  rigid_pair *pairs = spx_alloc_array(ctx, (size_t)(ns + nm), sizeof(rigid_pair), "rigid");
  spx_kdtree *mt = NULL;
  spx_ceres_problem *pb = NULL;
  if (!Z || !X || !i_s2m || !i_m2s || !d_s2m || !d_m2s || !pairs) {
    st = SPX_E_NOMEM;
    goto cleanup;
  }
  for (int32_t j = 0; j < nm; j++) mat3_vec(st_io->Rc, Y + j * 3, Z + j * 3);
  for (int r = 0; r <= rounds; r++) {
    double R[9];
    spx_body_rodrigues(st_io->w, R, NULL);
    for (int32_t j = 0; j < nm; j++) {
      double x[3];
      mat3_vec(R, Z + j * 3, x);
      for (int d = 0; d < 3; d++) X[j * 3 + d] = (float)(st_io->s[0] * x[d] + st_io->t[d]);
    }
    spx_kdtree_free(mt);
    mt = NULL;
    if ((st = spx_fit_kd_build(ctx, X, nm, &mt))) goto cleanup;
    if ((st = spx_fit_kd_query(ctx, mt, S, ns, 1, i_s2m, d_s2m, o->threads))) goto cleanup;
    if ((st = spx_fit_kd_query(ctx, scan_tree, X, nm, 1, i_m2s, d_m2s, o->threads))) goto cleanup;
    double m1 = 0, m2 = 0;
    for (int32_t i = 0; i < ns; i++) m1 += sqrt(d_s2m[i]);
    for (int32_t j = 0; j < nm; j++) m2 += sqrt(d_m2s[j]);
    st_io->score = m1 / ns + m2 / nm;
    if (r == rounds) break;
    pb = spx_ceres_problem_create(NULL, NULL);
    if (!pb) {
      st = ceres_err(ctx, "rigid");
      goto cleanup;
    }
    int sizes[3] = {3, 1, 3};
    double *blocks[3] = {st_io->w, st_io->s, st_io->t};
    double a1 = sqrt(1.0 / ns), a2 = sqrt(o->w_m2s / nm), scale = 0.1;
    int np = 0;
    for (int32_t i = 0; i < ns; i++) {
      rigid_pair *q = pairs + np++;
      q->z = Z + i_s2m[i] * 3, q->a = a1;
      for (int d = 0; d < 3; d++) q->p[d] = S[i * 3 + d];
      if (spx_ceres_add_residual(pb, rigid_cost, q, 3, 3, sizes, blocks, SPX_LOSS_HUBER, a1 * scale)) {
        st = ceres_err(ctx, "rigid");
        goto cleanup;
      }
    }
    for (int32_t j = 0; j < nm; j++) {
      rigid_pair *q = pairs + np++;
      q->z = Z + j * 3, q->a = a2;
      for (int d = 0; d < 3; d++) q->p[d] = S[i_m2s[j] * 3 + d];
      if (spx_ceres_add_residual(pb, rigid_cost, q, 3, 3, sizes, blocks, SPX_LOSS_HUBER, a2 * scale)) {
        st = ceres_err(ctx, "rigid");
        goto cleanup;
      }
    }
    /* a free scale from a bad start lets robust ICP shrink the model: only refined at the end */
    if (spx_ceres_set_constant(pb, st_io->s, !free_scale || r + 2 < rounds)) {
      st = ceres_err(ctx, "rigid");
      goto cleanup;
    }
    spx_ceres_options co;
    spx_ceres_options_default(&co);
    co.threads = o->threads;
    co.max_iterations = iters;
    spx_ceres_summary sum;
    if (spx_ceres_solve(pb, &co, &sum)) {
      st = ceres_err(ctx, "rigid");
      goto cleanup;
    }
    spx_ceres_problem_destroy(pb);
    pb = NULL;
    if (!(st_io->s[0] > 1e-3)) st_io->s[0] = 1e-3; /* keep the similarity proper */
  }
cleanup:
  spx_ceres_problem_destroy(pb);
  spx_kdtree_free(mt);
  free(Z), free(X), free(i_s2m), free(i_m2s), free(d_s2m), free(d_m2s), free(pairs);
  return st;
}

#define RIGID_MAXCAND 64

/* Finds the similarity model → scan. Sc: scan in metres (ns points). */
static spx_status stage_rigid(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, const float *Sc,
                              int32_t ns, spx_fit_result *r) {
  double t0 = spx_now();
  spx_status st = SPX_OK;
  int32_t nsub = 0, *sidx = subsample(ctx, ns, o->max_points_rigid, o->seed, &nsub);
  int32_t nm = 0, *midx = subsample(ctx, m->nv, o->max_points_rigid, o->seed ^ 0x9e3779b97f4a7c15ULL, &nm);
  float *S = NULL;
  double *Y = NULL;
  spx_kdtree *stree = NULL;
  if (!sidx || !midx) {
    st = SPX_E_NOMEM;
    goto cleanup;
  }
  S = spx_alloc_array(ctx, (size_t)nsub * 3, sizeof(float), "rigid");
  Y = spx_alloc_array(ctx, (size_t)nm * 3, sizeof(double), "rigid");
  if (!S || !Y) {
    st = SPX_E_NOMEM;
    goto cleanup;
  }
  double cs[3] = {0, 0, 0}, cm[3] = {0, 0, 0}, C[9] = {0};
  for (int32_t i = 0; i < ns; i++)
    for (int d = 0; d < 3; d++) cs[d] += Sc[i * 3 + d] / ns;
  for (int32_t i = 0; i < ns; i++) {
    double e[3] = {Sc[i * 3] - cs[0], Sc[i * 3 + 1] - cs[1], Sc[i * 3 + 2] - cs[2]};
    for (int a = 0; a < 3; a++)
      for (int b = 0; b < 3; b++) C[a * 3 + b] += e[a] * e[b] / ns;
  }
  for (int32_t i = 0; i < m->nv; i++)
    for (int d = 0; d < 3; d++) cm[d] += (double)m->v_template[i * 3 + d] / m->nv;
  /* the scan is metric after the unit check: screen at scale 1, refine the scale at the end */
  double s0 = 1.0;
  for (int32_t i = 0; i < nsub; i++)
    for (int d = 0; d < 3; d++) S[i * 3 + d] = Sc[sidx[i] * 3 + d];
  for (int32_t j = 0; j < nm; j++)
    for (int d = 0; d < 3; d++) Y[j * 3 + d] = m->v_template[midx[j] * 3 + d] - cm[d];
  if ((st = spx_fit_kd_build(ctx, S, nsub, &stree))) goto cleanup;

  /* candidate orientations: 6 axis-aligned ups x 8 headings, plus principal axes */
  rigid_state cand[RIGID_MAXCAND];
  int nc = 0;
  for (int u = 0; u < 6; u++) {
    double up[3] = {0, 0, 0}, a[3] = {0, 0, 0}, b[3];
    up[u / 2] = (u % 2) ? -1.0 : 1.0;
    a[(u / 2 + 1) % 3] = 1.0;
    cross3(up, a, b);
    for (int h = 0; h < 8; h++) {
      double th = h * (M_PI / 4), f[3];
      for (int d = 0; d < 3; d++) f[d] = cos(th) * a[d] + sin(th) * b[d];
      frame_from(up, f, cand[nc++].Rc);
    }
  }
  double ev[3], V[9];
  eig3(C, ev, V);
  for (int su = 0; su < 2; su++)
    for (int sf = 0; sf < 2; sf++) {
      double up[3], f[3];
      for (int d = 0; d < 3; d++) up[d] = (su ? -1 : 1) * V[d * 3], f[d] = (sf ? -1 : 1) * V[d * 3 + 2];
      frame_from(up, f, cand[nc++].Rc);
    }
  for (int c = 0; c < nc; c++) {
    memset(cand[c].w, 0, sizeof cand[c].w);
    cand[c].s[0] = s0;
    memcpy(cand[c].t, cs, sizeof cs);
    /* coarse screening on a quarter of the points */
    int32_t nq = nsub / 4 > 50 ? nsub / 4 : nsub, mq = nm / 4 > 50 ? nm / 4 : nm;
    spx_kdtree *qt = NULL;
    if ((st = spx_fit_kd_build(ctx, S, nq, &qt))) goto cleanup;
    st = rigid_icp(ctx, o, Y, mq, S, nq, qt, 2, 6, 0, &cand[c]);
    spx_kdtree_free(qt);
    if (st) goto cleanup;
  }
  /* refine the best three */
  for (int k = 0; k < 3 && k < nc; k++) {
    int best = k;
    for (int c = k + 1; c < nc; c++)
      if (cand[c].score < cand[best].score) best = c;
    rigid_state tmp = cand[k];
    cand[k] = cand[best], cand[best] = tmp;
    if ((st = rigid_icp(ctx, o, Y, nm, S, nsub, stree, 5, 15, 1, &cand[k]))) goto cleanup;
  }
  int best = 0;
  for (int k = 1; k < 3 && k < nc; k++)
    if (cand[k].score < cand[best].score) best = k;
  double Rw[9], R[9], Rcm[3];
  spx_body_rodrigues(cand[best].w, Rw, NULL);
  mat3_mul(Rw, cand[best].Rc, R);
  mat3_vec(R, cm, Rcm);
  memcpy(r->sim_R, R, sizeof R);
  r->sim_scale = cand[best].s[0];
  for (int d = 0; d < 3; d++) r->sim_t[d] = cand[best].t[d] - r->sim_scale * Rcm[d];
  r->stage_seconds[0] = spx_now() - t0;
  r->stage_mean[0] = cand[best].score * 0.5;
  r->stage_energy[0] = cand[best].score;
  report(o, "rigid", 1, 1, cand[best].score, cand[best].score * 0.5, t0, NULL);
cleanup:
  spx_kdtree_free(stree);
  free(sidx), free(midx), free(S), free(Y);
  return st;
}

/* ---------- stage 2: pose + shape ---------- */

typedef struct body_state {
  spx_ctx *ctx;
  const spx_body_model *m;
  int32_t nb, ncol;
  double *pose, *betas, trans[3], bscale[1];
  double *F; /* nv*3 forward vertices (unscaled) */
  double *J; /* nv*3*ncol */
  int have_jac;
  spx_status st;
} body_state;

static int body_prepare(void *user, int want_jac, int new_point) {
  body_state *b = user;
  if (!new_point && (!want_jac || b->have_jac)) return 1;
  spx_body_params p = {b->nb, b->betas, b->pose, b->trans, NULL};
  spx_status st;
  if (want_jac) st = spx_body_jacobian(b->ctx, b->m, &p, b->m->nv, NULL, b->F, b->J);
  else st = spx_body_forward_ref(b->ctx, b->m, &p, b->F, NULL);
  b->have_jac = want_jac;
  if (st) b->st = st;
  return st == SPX_OK;
}

typedef struct body_pair {
  const body_state *b;
  int32_t j;
  double q[3], n[3]; /* target point; plane normal (point-to-plane) */
  double a;
} body_pair;

/* r = a n.(s F_j - q). Blocks: pose, betas, trans, scale (betas omitted when nb = 0). */
static void body_jac_rows(const body_state *b, int32_t j, const double *wrow, int nrows, double s, double a,
                          double **jac, int scale_block) {
  /* wrow: nrows x 3 projection of the vertex (rows of n^T or I) */
  int K3 = 3 * b->m->nj, nb = b->nb;
  const double *Jv = b->J + (size_t)j * 3 * b->ncol;
  for (int r = 0; r < nrows; r++) {
    const double *w = wrow + r * 3;
    if (jac[0])
      for (int c = 0; c < K3; c++)
        jac[0][r * K3 + c] = a * s * (w[0] * Jv[c] + w[1] * Jv[b->ncol + c] + w[2] * Jv[2 * b->ncol + c]);
    int blk = 1;
    if (nb) {
      if (jac[blk])
        for (int c = 0; c < nb; c++) {
          int cc = K3 + c;
          jac[blk][r * nb + c] = a * s * (w[0] * Jv[cc] + w[1] * Jv[b->ncol + cc] + w[2] * Jv[2 * b->ncol + cc]);
        }
      blk++;
    }
    if (jac[blk])
      for (int c = 0; c < 3; c++) {
        int cc = K3 + nb + c;
        jac[blk][r * 3 + c] = a * s * (w[0] * Jv[cc] + w[1] * Jv[b->ncol + cc] + w[2] * Jv[2 * b->ncol + cc]);
      }
    if (jac[scale_block]) {
      const double *F = b->F + (size_t)j * 3;
      jac[scale_block][r] = a * (w[0] * F[0] + w[1] * F[1] + w[2] * F[2]);
    }
  }
}

static int body_plane_cost(void *user, const double *const *par, double *res, double **jac) {
  const body_pair *q = user;
  const body_state *b = q->b;
  int sb = b->nb ? 3 : 2;
  double s = par[sb][0];
  const double *F = b->F + (size_t)q->j * 3;
  res[0] = q->a * (q->n[0] * (s * F[0] - q->q[0]) + q->n[1] * (s * F[1] - q->q[1]) + q->n[2] * (s * F[2] - q->q[2]));
  if (jac) body_jac_rows(b, q->j, q->n, 1, s, q->a, jac, sb);
  return 1;
}

typedef struct prior_data {
  int n;
  double w;
  double lim;        /* unused */
  int offset;        /* first component (pose prior skips the root) */
  double target;     /* scale prior: w (x*target - 1) */
  const double *lims; /* joint limits: |x_i| beyond lims[i] is penalised */
} prior_data;

static int l2_prior_cost(void *user, const double *const *par, double *res, double **jac) {
  const prior_data *d = user;
  const double *x = par[0] + d->offset;
  for (int i = 0; i < d->n; i++) res[i] = d->w * x[i];
  if (jac && jac[0]) {
    int ncols = d->n + d->offset;
    memset(jac[0], 0, (size_t)d->n * (size_t)ncols * sizeof(double));
    for (int i = 0; i < d->n; i++) jac[0][i * ncols + d->offset + i] = d->w;
  }
  return 1;
}

static int limit_cost(void *user, const double *const *par, double *res, double **jac) {
  const prior_data *d = user;
  const double *x = par[0] + d->offset;
  int ncols = d->n + d->offset;
  if (jac && jac[0]) memset(jac[0], 0, (size_t)d->n * (size_t)ncols * sizeof(double));
  for (int i = 0; i < d->n; i++) {
    double e = fabs(x[i]) - d->lims[i];
    res[i] = e > 0 ? d->w * e : 0.0;
    if (jac && jac[0] && e > 0) jac[0][i * ncols + d->offset + i] = x[i] > 0 ? d->w : -d->w;
  }
  return 1;
}

static int scale_prior_cost(void *user, const double *const *par, double *res, double **jac) {
  const prior_data *d = user;
  res[0] = d->w * (par[0][0] * d->target - 1.0);
  if (jac && jac[0]) jac[0][0] = d->w * d->target;
  return 1;
}

/* ---------- stage 3: free vertices ---------- */

typedef struct free_pair {
  double q[3], n[3], a;
} free_pair;

static int free_plane_cost(void *user, const double *const *par, double *res, double **jac) {
  const free_pair *q = user;
  const double *x = par[0];
  res[0] = q->a * (q->n[0] * (x[0] - q->q[0]) + q->n[1] * (x[1] - q->q[1]) + q->n[2] * (x[2] - q->q[2]));
  if (jac && jac[0])
    for (int d = 0; d < 3; d++) jac[0][d] = q->a * q->n[d];
  return 1;
}

static int free_point_cost(void *user, const double *const *par, double *res, double **jac) {
  const free_pair *q = user;
  for (int d = 0; d < 3; d++) res[d] = q->a * (par[0][d] - q->q[d]);
  if (jac && jac[0])
    for (int d = 0; d < 9; d++) jac[0][d] = (d % 4 == 0) ? q->a : 0.0;
  return 1;
}

typedef struct lap_data {
  int32_t deg;
  double a;
  double target[3]; /* Laplacian of the posed model at this vertex */
} lap_data;

/* r = a ((x_i - mean_j x_j) - L_i(model)); blocks x_i, x_j... */
static int lap_cost(void *user, const double *const *par, double *res, double **jac) {
  const lap_data *l = user;
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

/* ---------- driver ---------- */

static double mean_of(const float *d, int32_t n) {
  double s = 0;
  for (int32_t i = 0; i < n; i++) s += d[i];
  return n ? s / n : 0;
}

typedef struct fit_work {
  float *Q;   /* scan subsample in model frame (pose stage) */
  int32_t nq;
  float *Qf;  /* scan subsample in model frame (free stage) */
  int32_t nqf;
  float *Vf;  /* current model vertices, float */
  double *N;  /* normals */
  int32_t *idx;
  float *d2;
  float *dist;
  double *area; /* per model vertex: its share of the rest surface area (sums to 1) */
  double *lim;  /* nj*3 soft joint limits (radians) */
  int32_t *msub; /* model vertices used by the pose stage's model → scan term */
  int32_t nms;
  double msub_w; /* 1 / (area share of the subset) */
  int32_t *idx_m;
  float *d2_m;
  body_pair *bp;
  free_pair *fp;
  lap_data *lp;
  spx_adj vf, nb;
} fit_work;

static void work_free(fit_work *w) {
  free(w->Q), free(w->Qf), free(w->Vf), free(w->N), free(w->idx), free(w->d2), free(w->dist), free(w->idx_m);
  free(w->area), free(w->lim), free(w->msub);
  free(w->d2_m), free(w->bp), free(w->fp), free(w->lp);
  spx_adj_free(&w->vf);
  spx_adj_free(&w->nb);
}

/* Share of the rest surface per vertex (a third of each incident triangle), normalised to sum 1,
 * so densely meshed parts (face, hands) do not dominate the model → scan term. */
static void vertex_areas(const spx_body_model *m, double *area) {
  double tot = 0;
  memset(area, 0, (size_t)m->nv * sizeof(double));
  for (int32_t f = 0; f < m->nf; f++) {
    const int32_t *F = m->faces + f * 3;
    const float *a = m->v_template + F[0] * 3, *b = m->v_template + F[1] * 3, *c = m->v_template + F[2] * 3;
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]}, n[3];
    cross3(e1, e2, n);
    double A = 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) / 3;
    for (int k = 0; k < 3; k++) area[F[k]] += A;
    tot += 3 * A;
  }
  for (int32_t i = 0; i < m->nv; i++) area[i] = tot > 0 ? area[i] / tot : 1.0 / m->nv;
}

/* Soft joint limits (radians per axis-angle component): trunk, neck, head, clavicle and hip
 * helper joints bend little; limbs, hands and feet up to 1.6. Names of the cmu_mb rig and SMPL. */
static void joint_limits(const spx_body_model *m, double *lim) {
  static const char *stiff[] = {"spine", "back", "neck", "head", "collar", "hipjoint", "pelvis", "jaw"};
  for (int32_t k = 0; k < m->nj; k++) {
    double l = 1.6;
    const char *n = m->joint_names ? m->joint_names[k] : NULL;
    for (size_t q = 0; n && q < sizeof stiff / sizeof stiff[0]; q++) {
      size_t L = strlen(stiff[q]);
      for (const char *c = n; *c; c++)
        if (!strncasecmp(c, stiff[q], L)) l = 0.7;
    }
    for (int d = 0; d < 3; d++) lim[k * 3 + d] = l;
  }
}

static spx_status stage_pose(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, fit_work *w,
                             body_state *b, spx_fit_result *r) {
  double t0 = spx_now();
  spx_status st = SPX_OK;
  int32_t nv = m->nv, K3 = 3 * m->nj, nb = b->nb;
  spx_kdtree *qt = NULL, *mt = NULL;
  spx_ceres_problem *pb = NULL;
  prior_data pr_pose = {K3 - 3, 0, 0, 3, 0, NULL}, pr_lim = {K3 - 3, o->w_limits, 0, 3, 0, w->lim + 3};
  prior_data pr_shape = {nb, o->w_shape, 0, 0, 0, NULL}, pr_scale = {1, o->w_scale, 0, 0, r->sim_scale, NULL};
  if ((st = spx_fit_kd_build(ctx, w->Q, w->nq, &qt))) goto cleanup;
  int32_t steps = o->pose_steps > 0 ? o->pose_steps : 1;
  for (int32_t step = 0; step < steps; step++) {
    spx_body_params p = {nb, b->betas, b->pose, b->trans, NULL};
    if ((st = spx_body_forward_ref(ctx, m, &p, b->F, NULL))) goto cleanup;
    double *V = r->verts_pose;
    for (int32_t i = 0; i < nv * 3; i++) V[i] = b->bscale[0] * b->F[i], w->Vf[i] = (float)V[i];
    spx_vertex_normals_d(V, nv, m->faces, m->nf, w->N);
    spx_kdtree_free(mt);
    mt = NULL;
    if ((st = spx_fit_kd_build(ctx, w->Vf, nv, &mt))) goto cleanup;
    if ((st = spx_fit_kd_query(ctx, mt, w->Q, w->nq, 1, w->idx, w->d2, o->threads))) goto cleanup;
    if ((st = spx_fit_kd_query(ctx, qt, w->Vf, nv, 1, w->idx_m, w->d2_m, o->threads))) goto cleanup;
    double frac = steps > 1 ? (double)step / (steps - 1) : 1.0;
    double thr = fmax(0.08, 0.3 * pow(0.7, step)); /* pair rejection distance (m) */
    double robust = o->robust_m * pow(4.0, 1.0 - frac); /* 4x → 1x */
    pb = spx_ceres_problem_create(body_prepare, b);
    if (!pb) {
      st = ceres_err(ctx, "pose");
      goto cleanup;
    }
    int sizes[4] = {K3, nb, 3, 1};
    double *blocks[4] = {b->pose, b->betas, b->trans, b->bscale};
    int nblk = 4;
    if (!nb) sizes[1] = 3, sizes[2] = 1, blocks[1] = b->trans, blocks[2] = b->bscale, nblk = 3;
    double a1 = sqrt(1.0 / w->nq);
    int32_t np = 0;
    for (int32_t i = 0; i < w->nq; i++) {
      if (w->d2[i] > thr * thr) continue;
      body_pair *q = w->bp + np++;
      q->b = b, q->j = w->idx[i], q->a = a1;
      for (int d = 0; d < 3; d++) q->q[d] = w->Q[i * 3 + d], q->n[d] = w->N[q->j * 3 + d];
      if (spx_ceres_add_residual(pb, body_plane_cost, q, 1, nblk, sizes, blocks, SPX_LOSS_HUBER, a1 * robust)) {
        st = ceres_err(ctx, "pose");
        goto cleanup;
      }
    }
    for (int32_t jj = 0; jj < w->nms; jj++) {
      int32_t j = w->msub[jj];
      if (w->d2_m[j] > thr * thr) continue;
      body_pair *q = w->bp + np++;
      double a2 = sqrt(o->w_m2s * w->area[j] * w->msub_w);
      q->b = b, q->j = j, q->a = a2;
      for (int d = 0; d < 3; d++) q->q[d] = w->Q[w->idx_m[j] * 3 + d], q->n[d] = w->N[j * 3 + d];
      /* point-to-plane (model normal): converges much faster than point-to-point */
      if (spx_ceres_add_residual(pb, body_plane_cost, q, 1, nblk, sizes, blocks, SPX_LOSS_CAUCHY, a2 * 2 * robust)) {
        st = ceres_err(ctx, "pose");
        goto cleanup;
      }
    }
    /* priors: the pose prior is annealed from 10x down to 1x */
    pr_pose.w = o->w_pose_start * pow(o->w_pose / o->w_pose_start, frac);
    int one = 1;
    if (spx_ceres_add_residual(pb, l2_prior_cost, &pr_pose, K3 - 3, 1, &K3, &b->pose, SPX_LOSS_NONE, 0) ||
        spx_ceres_add_residual(pb, limit_cost, &pr_lim, K3 - 3, 1, &K3, &b->pose, SPX_LOSS_NONE, 0) ||
        (nb && spx_ceres_add_residual(pb, l2_prior_cost, &pr_shape, nb, 1, &nb, &b->betas, SPX_LOSS_NONE, 0)) ||
        spx_ceres_add_residual(pb, scale_prior_cost, &pr_scale, 1, 1, &one, (double *const *)&blocks[nblk - 1],
                               SPX_LOSS_NONE, 0)) {
      st = ceres_err(ctx, "pose");
      goto cleanup;
    }
    spx_ceres_options co;
    spx_ceres_options_default(&co);
    co.threads = o->threads;
    co.max_iterations = o->inner_iterations;
    co.linear_solver = SPX_LS_DENSE_NORMAL_CHOLESKY;
    co.progress = getenv("SPX_FIT_CERES_PROGRESS") != NULL;
    spx_ceres_summary sum;
    b->st = SPX_OK;
    b->have_jac = 0;
    int rc = spx_ceres_solve(pb, &co, &sum);
    if (b->st) {
      st = b->st;
      goto cleanup;
    }
    if (rc) {
      st = ceres_err(ctx, "pose");
      goto cleanup;
    }
    spx_ceres_problem_destroy(pb);
    pb = NULL;
    /* progress: mean scan → surface distance at the new parameters */
    p = (spx_body_params){nb, b->betas, b->pose, b->trans, NULL};
    if ((st = spx_body_forward_ref(ctx, m, &p, b->F, NULL))) goto cleanup;
    for (int32_t i = 0; i < nv * 3; i++) V[i] = b->bscale[0] * b->F[i], w->Vf[i] = (float)V[i];
    if ((st = spx_fit_surface_distance_adj(ctx, w->Q, w->nq, w->Vf, nv, m->faces, &w->vf, o->threads, w->dist)))
      goto cleanup;
    double md = mean_of(w->dist, w->nq) * r->sim_scale;
    r->stage_energy[1] = sum.final_cost;
    r->stage_mean[1] = md;
    report(o, "pose", step + 1, steps, sum.final_cost, md, t0, NULL);
  }
  r->stage_seconds[1] = spx_now() - t0;
cleanup:
  spx_ceres_problem_destroy(pb);
  spx_kdtree_free(qt);
  spx_kdtree_free(mt);
  return st;
}

static spx_status stage_free(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, fit_work *w,
                             spx_fit_result *r) {
  double t0 = spx_now();
  spx_status st = SPX_OK;
  int32_t nv = m->nv;
  double *X = r->verts_model; /* starts at the posed model */
  const double *Vp = r->verts_pose;
  spx_kdtree *qt = NULL, *mt = NULL;
  spx_ceres_problem *pb = NULL;
  int32_t maxdeg = 0;
  for (int32_t i = 0; i < nv; i++) {
    int32_t dg = w->nb.start[i + 1] - w->nb.start[i];
    if (dg > maxdeg) maxdeg = dg;
  }
  int *sizes = NULL;
  double **blocks = NULL;
  sizes = spx_alloc_array(ctx, (size_t)maxdeg + 1, sizeof(int), "free stage");
  blocks = spx_alloc_array(ctx, (size_t)maxdeg + 1, sizeof(double *), "free stage");
  if (!sizes || !blocks) {
    st = SPX_E_NOMEM;
    goto cleanup;
  }
  for (int32_t k = 0; k <= maxdeg; k++) sizes[k] = 3;
  for (int32_t i = 0; i < nv; i++) {
    lap_data *l = w->lp + i;
    l->deg = w->nb.start[i + 1] - w->nb.start[i];
    for (int d = 0; d < 3; d++) {
      double s = 0;
      for (int32_t k = w->nb.start[i]; k < w->nb.start[i + 1]; k++) s += Vp[w->nb.idx[k] * 3 + d];
      l->target[d] = l->deg ? Vp[i * 3 + d] - s / l->deg : 0;
    }
  }
  if ((st = spx_fit_kd_build(ctx, w->Qf, w->nqf, &qt))) goto cleanup;
  int32_t steps = o->free_steps > 0 ? o->free_steps : 1;
  for (int32_t step = 0; step < steps; step++) {
    double frac = steps > 1 ? (double)step / (steps - 1) : 1.0;
    double wc = o->w_couple_start * pow(o->w_couple_end / o->w_couple_start, frac);
    double thr = 0.03;
    for (int32_t i = 0; i < nv * 3; i++) w->Vf[i] = (float)X[i];
    spx_vertex_normals_d(X, nv, m->faces, m->nf, w->N);
    spx_kdtree_free(mt);
    mt = NULL;
    if ((st = spx_fit_kd_build(ctx, w->Vf, nv, &mt))) goto cleanup;
    if ((st = spx_fit_kd_query(ctx, mt, w->Qf, w->nqf, 1, w->idx, w->d2, o->threads))) goto cleanup;
    if ((st = spx_fit_kd_query(ctx, qt, w->Vf, nv, 1, w->idx_m, w->d2_m, o->threads))) goto cleanup;
    pb = spx_ceres_problem_create(NULL, NULL);
    if (!pb) {
      st = ceres_err(ctx, "free");
      goto cleanup;
    }
    double a1 = sqrt(1.0 / w->nqf), ac = sqrt(wc / nv), al = sqrt(o->w_lap / nv);
    int32_t np = 0;
    for (int32_t i = 0; i < w->nqf; i++) {
      if (w->d2[i] > thr * thr) continue;
      free_pair *q = w->fp + np++;
      int32_t j = w->idx[i];
      q->a = a1;
      for (int d = 0; d < 3; d++) q->q[d] = w->Qf[i * 3 + d], q->n[d] = w->N[j * 3 + d];
      double *blk = X + j * 3;
      if (spx_ceres_add_residual(pb, free_plane_cost, q, 1, 1, sizes, &blk, SPX_LOSS_HUBER, a1 * o->robust_m * 0.5)) {
        st = ceres_err(ctx, "free");
        goto cleanup;
      }
    }
    for (int32_t j = 0; j < nv; j++) {
      double *blk = X + j * 3;
      if (w->d2_m[j] <= thr * thr) {
        free_pair *q = w->fp + np++;
        q->a = sqrt(o->w_m2s * w->area[j]);
        for (int d = 0; d < 3; d++) q->q[d] = w->Qf[w->idx_m[j] * 3 + d], q->n[d] = w->N[j * 3 + d];
        /* along the normal only: tangential sliding toward noisy samples would distort the mesh */
        if (spx_ceres_add_residual(pb, free_plane_cost, q, 1, 1, sizes, &blk, SPX_LOSS_CAUCHY, q->a * o->robust_m * 0.5)) {
          st = ceres_err(ctx, "free");
          goto cleanup;
        }
      }
      free_pair *c = w->fp + np++;
      c->a = ac;
      for (int d = 0; d < 3; d++) c->q[d] = Vp[j * 3 + d];
      if (spx_ceres_add_residual(pb, free_point_cost, c, 3, 1, sizes, &blk, SPX_LOSS_NONE, 0)) {
        st = ceres_err(ctx, "free");
        goto cleanup;
      }
      lap_data *l = w->lp + j;
      if (l->deg == 0) continue;
      l->a = al;
      blocks[0] = blk;
      for (int32_t k = 0; k < l->deg; k++) blocks[1 + k] = X + w->nb.idx[w->nb.start[j] + k] * 3;
      if (spx_ceres_add_residual(pb, lap_cost, l, 3, 1 + l->deg, sizes, blocks, SPX_LOSS_NONE, 0)) {
        st = ceres_err(ctx, "free");
        goto cleanup;
      }
    }
    spx_ceres_options co;
    spx_ceres_options_default(&co);
    co.threads = o->threads;
    co.max_iterations = o->free_inner_iterations > 0 ? o->free_inner_iterations : o->inner_iterations;
    co.linear_solver = SPX_LS_SPARSE_NORMAL_CHOLESKY;
    co.progress = getenv("SPX_FIT_CERES_PROGRESS") != NULL;
    spx_ceres_summary sum;
    if (spx_ceres_solve(pb, &co, &sum)) {
      st = ceres_err(ctx, "free");
      goto cleanup;
    }
    spx_ceres_problem_destroy(pb);
    pb = NULL;
    for (int32_t i = 0; i < nv * 3; i++) w->Vf[i] = (float)X[i];
    if ((st = spx_fit_surface_distance_adj(ctx, w->Qf, w->nqf, w->Vf, nv, m->faces, &w->vf, o->threads, w->dist)))
      goto cleanup;
    double md = mean_of(w->dist, w->nqf) * r->sim_scale;
    r->stage_energy[2] = sum.final_cost;
    r->stage_mean[2] = md;
    report(o, "free", step + 1, steps, sum.final_cost, md, t0, NULL);
  }
  r->stage_seconds[2] = spx_now() - t0;
cleanup:
  free(sizes), free(blocks);
  spx_ceres_problem_destroy(pb);
  spx_kdtree_free(qt);
  spx_kdtree_free(mt);
  return st;
}

/* scan (metres) → model frame: R^T (p - t) / s */
static void to_model(const spx_fit_result *r, const float *p, float *q) {
  double e[3] = {p[0] - r->sim_t[0], p[1] - r->sim_t[1], p[2] - r->sim_t[2]}, x[3];
  mat3t_vec(r->sim_R, e, x);
  for (int d = 0; d < 3; d++) q[d] = (float)(x[d] / r->sim_scale);
}

static spx_status transfer_colors(spx_ctx *ctx, const spx_mesh *scan, const float *Sc, const spx_fit_result *r,
                                  const float *Vs, int threads, float *col) {
  enum { KC = 4 };
  int k = scan->nv < KC ? scan->nv : KC;
  spx_kdtree *t = NULL;
  spx_status st = spx_fit_kd_build(ctx, Sc, scan->nv, &t);
  if (st) return st;
  int32_t *idx = spx_alloc_array(ctx, (size_t)r->nv * KC, sizeof(int32_t), "colour transfer");
  float *d2 = spx_alloc_array(ctx, (size_t)r->nv * KC, sizeof(float), "colour transfer");
  if (!idx || !d2) st = SPX_E_NOMEM;
  if (!st) st = spx_fit_kd_query(ctx, t, Vs, r->nv, k, idx, d2, threads);
  for (int32_t i = 0; !st && i < r->nv; i++) {
    double acc[3] = {0, 0, 0}, ws = 0;
    for (int j = 0; j < k; j++) {
      double wgt = 1.0 / (sqrt(d2[i * k + j]) + 1e-3);
      const float *c = scan->col + (size_t)idx[i * k + j] * 3;
      for (int d = 0; d < 3; d++) acc[d] += wgt * c[d];
      ws += wgt;
    }
    for (int d = 0; d < 3; d++) col[i * 3 + d] = (float)(acc[d] / ws);
  }
  free(idx), free(d2);
  spx_kdtree_free(t);
  return st;
}

spx_status spx_fit_register(spx_ctx *ctx, const spx_body_model *m, const spx_mesh *scan, const spx_fit_options *oin,
                            spx_fit_result *out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "registration: NULL result");
  memset(out, 0, sizeof *out);
  if (!m || !scan) return spx_fail(ctx, SPX_E_ARG, "registration: NULL model or scan");
  spx_fit_options o;
  if (oin) o = *oin;
  else spx_fit_options_default(&o);
  if (o.threads < 1) o.threads = 1;
  if (scan->nv < 10 || !scan->pos) return spx_fail(ctx, SPX_E_ARG, "registration: the scan has %d points (need at least 10)", scan->nv);
  for (int32_t i = 0; i < scan->nv * 3; i++)
    if (!isfinite(scan->pos[i])) return spx_fail(ctx, SPX_E_NUMERIC, "registration: scan point %d is not finite", i / 3);
  if (m->nv < 10 || m->nf < 1) return spx_fail(ctx, SPX_E_ARG, "registration: the body model has no surface");
  if (!(o.stages & SPX_FIT_ALL)) return spx_fail(ctx, SPX_E_ARG, "registration: no stage selected");
  int32_t nb = o.nbetas < 0 || o.nbetas > m->nbetas ? m->nbetas : o.nbetas;
  int32_t nv = m->nv, ns = scan->nv, ncol = spx_body_nparams(m, nb);
  spx_status st = SPX_OK;
  fit_work w;
  memset(&w, 0, sizeof w);
  body_state b;
  memset(&b, 0, sizeof b);
  float *Sc = NULL;
  int32_t *sidx = NULL;
  spx_fit_result *r = out;
  r->nv = nv, r->nj = m->nj, r->nbetas = nb, r->nf = m->nf;
  r->betas = calloc((size_t)(nb ? nb : 1), sizeof(double));
  r->pose = calloc((size_t)m->nj * 3, sizeof(double));
  r->verts_model = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  r->verts_pose = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  r->verts_scan = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(float), "registration");
  r->template_unposed = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  r->faces = spx_alloc_array(ctx, (size_t)m->nf * 3, sizeof(int32_t), "registration");
  Sc = spx_alloc_array(ctx, (size_t)ns * 3, sizeof(float), "registration");
  b.F = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  b.J = spx_alloc_array(ctx, (size_t)nv * 3, (size_t)ncol * sizeof(double), "registration jacobian");
  w.Vf = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(float), "registration");
  w.N = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  w.idx_m = spx_alloc_array(ctx, (size_t)nv, sizeof(int32_t), "registration");
  w.d2_m = spx_alloc_array(ctx, (size_t)nv, sizeof(float), "registration");
  w.lp = spx_alloc_array(ctx, (size_t)nv, sizeof(lap_data), "registration");
  w.area = spx_alloc_array(ctx, (size_t)nv, sizeof(double), "registration");
  w.lim = spx_alloc_array(ctx, (size_t)m->nj * 3, sizeof(double), "registration");
  if (!r->betas || !r->pose || !r->verts_model || !r->verts_pose || !r->verts_scan || !r->template_unposed ||
      !r->faces || !Sc || !b.F || !b.J || !w.Vf || !w.N || !w.idx_m || !w.d2_m || !w.lp ||
      !w.area || !w.lim) {
    st = spx_fail(ctx, SPX_E_NOMEM, "registration: out of memory");
    goto cleanup;
  }
  memcpy(r->faces, m->faces, (size_t)m->nf * 3 * sizeof(int32_t));
  if ((st = spx_fit_vertex_faces(ctx, nv, m->faces, m->nf, &w.vf))) goto cleanup;
  if ((st = spx_fit_vertex_neighbours(ctx, nv, m->faces, m->nf, &w.nb))) goto cleanup;
  vertex_areas(m, w.area);
  joint_limits(m, w.lim);

  /* units */
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int32_t i = 0; i < ns; i++)
    for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], scan->pos[i * 3 + d]), hi[d] = fmax(hi[d], scan->pos[i * 3 + d]);
  double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
  if (!(ext > 0)) {
    st = spx_fail(ctx, SPX_E_ARG, "registration: the scan has no extent (all points equal)");
    goto cleanup;
  }
  const char *note = NULL;
  if ((st = spx_fit_units(ctx, ext, o.unit_scale, &r->unit_scale, &note))) goto cleanup;
  if (note) report(&o, "units", 0, 0, 0, 0, spx_now(), note);
  for (int32_t i = 0; i < ns * 3; i++) Sc[i] = (float)(scan->pos[i] * r->unit_scale);

  /* stage 1 */
  r->sim_scale = 1.0;
  for (int i = 0; i < 9; i++) r->sim_R[i] = (i % 4 == 0);
  if ((st = stage_rigid(ctx, m, &o, Sc, ns, r))) goto cleanup;
  r->stages_done |= SPX_FIT_RIGID;
  b.ctx = ctx, b.m = m, b.nb = nb, b.ncol = ncol, b.pose = r->pose, b.betas = r->betas;
  b.bscale[0] = 1.0 / r->sim_scale; /* the scan is metric after the unit check: start at true size */
  for (int32_t i = 0; i < nv * 3; i++) r->verts_pose[i] = m->v_template[i];

  /* stage 2 */
  if (o.stages & (SPX_FIT_POSE | SPX_FIT_FREE)) {
    int32_t mp = o.max_points_pose, mf = o.max_points_free;
    int32_t nmax = mp > mf ? mp : mf;
    if (nmax <= 0 || nmax > ns) nmax = ns;
    int32_t nsel = 0;
    if (!(sidx = subsample(ctx, ns, nmax, o.seed * 31 + 7, &nsel))) {
      st = SPX_E_NOMEM;
      goto cleanup;
    }
    w.nq = mp > 0 && mp < nsel ? mp : nsel;
    w.nqf = mf > 0 && mf < nsel ? mf : nsel;
    int32_t nbig = w.nq > w.nqf ? w.nq : w.nqf;
    w.Q = spx_alloc_array(ctx, (size_t)w.nq * 3, sizeof(float), "registration");
    w.Qf = spx_alloc_array(ctx, (size_t)w.nqf * 3, sizeof(float), "registration");
    w.idx = spx_alloc_array(ctx, (size_t)nbig, sizeof(int32_t), "registration");
    w.d2 = spx_alloc_array(ctx, (size_t)nbig, sizeof(float), "registration");
    w.dist = spx_alloc_array(ctx, (size_t)nbig, sizeof(float), "registration");
    w.bp = spx_alloc_array(ctx, (size_t)(nbig + nv), sizeof(body_pair), "registration");
    w.fp = spx_alloc_array(ctx, (size_t)(nbig + 2 * (size_t)nv), sizeof(free_pair), "registration");
    if (!w.Q || !w.Qf || !w.idx || !w.d2 || !w.dist || !w.bp || !w.fp) {
      st = SPX_E_NOMEM;
      goto cleanup;
    }
    for (int32_t i = 0; i < w.nq; i++) to_model(r, Sc + (size_t)sidx[i] * 3, w.Q + i * 3);
    for (int32_t i = 0; i < w.nqf; i++) to_model(r, Sc + (size_t)sidx[i] * 3, w.Qf + i * 3);
    int32_t nms = 0;
    if (!(w.msub = subsample(ctx, nv, mp > 0 ? (mp + 1) / 2 : nv, o.seed ^ 0xabcdefULL, &nms))) {
      st = SPX_E_NOMEM;
      goto cleanup;
    }
    w.nms = nms;
    double asum = 0;
    for (int32_t j = 0; j < nms; j++) asum += w.area[w.msub[j]];
    w.msub_w = asum > 0 ? 1.0 / asum : 1.0;
    if ((st = stage_pose(ctx, m, &o, &w, &b, r))) goto cleanup;
    r->stages_done |= SPX_FIT_POSE;
    memcpy(r->trans, b.trans, sizeof r->trans);
  }
  r->body_scale = (r->stages_done & SPX_FIT_POSE) ? b.bscale[0] : 1.0;
  memcpy(r->verts_model, r->verts_pose, (size_t)nv * 3 * sizeof(double));

  /* stage 3 */
  if (o.stages & SPX_FIT_FREE) {
    if ((st = stage_free(ctx, m, &o, &w, r))) goto cleanup;
    r->stages_done |= SPX_FIT_FREE;
  }

  /* outputs: scan-space vertices, colours, unposed template */
  for (int32_t i = 0; i < nv; i++) {
    double x[3];
    mat3_vec(r->sim_R, r->verts_model + i * 3, x);
    for (int d = 0; d < 3; d++) r->verts_scan[i * 3 + d] = (float)((r->sim_scale * x[d] + r->sim_t[d]) / r->unit_scale);
  }
  if (scan->col) {
    float *Vs = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(float), "colour transfer");
    r->colors = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(float), "colour transfer");
    if (!Vs || !r->colors) {
      free(Vs);
      st = SPX_E_NOMEM;
      goto cleanup;
    }
    for (int32_t i = 0; i < nv * 3; i++) Vs[i] = (float)(r->verts_scan[i] * r->unit_scale);
    st = transfer_colors(ctx, scan, Sc, r, Vs, o.threads, r->colors);
    free(Vs);
    if (st) goto cleanup;
  }
  {
    double *posed = b.F; /* reuse: registration without the body scale */
    for (int32_t i = 0; i < nv * 3; i++) posed[i] = r->verts_model[i] / r->body_scale;
    spx_body_params p = {nb, r->betas, r->pose, r->trans, NULL};
    if ((st = spx_body_unpose_ref(ctx, m, &p, posed, 1, r->template_unposed))) goto cleanup;
  }
cleanup:
  free(Sc), free(sidx), free(b.F), free(b.J);
  work_free(&w);
  if (st) spx_fit_result_free(out);
  return st;
}

spx_status spx_fit_result_mesh(spx_ctx *ctx, const spx_fit_result *r, spx_mesh *out) {
  memset(out, 0, sizeof *out);
  if (!r || !r->verts_scan || !r->faces) return spx_fail(ctx, SPX_E_ARG, "registration mesh: empty result");
  out->nv = r->nv, out->nf = r->nf;
  out->pos = spx_alloc_array(ctx, (size_t)r->nv * 3, sizeof(float), "registration mesh");
  out->faces = spx_alloc_array(ctx, (size_t)r->nf * 3, sizeof(int32_t), "registration mesh");
  if (r->colors) out->col = spx_alloc_array(ctx, (size_t)r->nv * 3, sizeof(float), "registration mesh");
  if (!out->pos || !out->faces || (r->colors && !out->col)) {
    spx_mesh_free(out);
    return SPX_E_NOMEM;
  }
  memcpy(out->pos, r->verts_scan, (size_t)r->nv * 3 * sizeof(float));
  memcpy(out->faces, r->faces, (size_t)r->nf * 3 * sizeof(int32_t));
  if (r->colors) memcpy(out->col, r->colors, (size_t)r->nv * 3 * sizeof(float));
  return SPX_OK;
}

/* ---------- finite-difference check of every residual's analytic Jacobian (tests) ---------- */

/* Compares fn's Jacobian blocks with central differences at the given parameters; returns the
 * worst |analytic - numeric| / max(1, |numeric|). */
static double fd_check(spx_ceres_cost_fn fn, void *user, int nres, int nblk, const int *sizes, double **par,
                       body_state *b) {
  double worst = 0, *J[16], r0[64], rp[64], rm[64];
  if (nres > 64 || nblk > 16) return INFINITY;
  for (int k = 0; k < nblk; k++) J[k] = malloc((size_t)nres * (size_t)sizes[k] * sizeof(double));
  if (b) body_prepare(b, 1, 1);
  fn(user, (const double *const *)par, r0, J);
  for (int k = 0; k < nblk; k++)
    for (int c = 0; c < sizes[k]; c++) {
      double x0 = par[k][c], h = 1e-6 * fmax(1.0, fabs(x0));
      par[k][c] = x0 + h;
      if (b) body_prepare(b, 0, 1);
      fn(user, (const double *const *)par, rp, NULL);
      par[k][c] = x0 - h;
      if (b) body_prepare(b, 0, 1);
      fn(user, (const double *const *)par, rm, NULL);
      par[k][c] = x0;
      for (int i = 0; i < nres; i++) {
        double num = (rp[i] - rm[i]) / (2 * h), e = fabs(J[k][i * sizes[k] + c] - num) / fmax(1.0, fabs(num));
        if (e > worst) worst = e;
      }
    }
  for (int k = 0; k < nblk; k++) free(J[k]);
  if (b) body_prepare(b, 1, 1);
  return worst;
}

spx_status spx_fit_gradient_selftest(spx_ctx *ctx, const spx_body_model *m, double worst[6]) {
  uint64_t s = 12345;
#define U() ((double)(rng_next(&s) >> 11) * (1.0 / 9007199254740992.0) - 0.5)
  for (int i = 0; i < 6; i++) worst[i] = 0;
  /* rigid */
  double z[3] = {0.3, -0.7, 0.2}, w[3] = {0.4, -0.2, 0.9}, sc[1] = {1.3}, t[3] = {0.1, 0.2, -0.3};
  rigid_pair rp = {z, {0.5, 0.1, -0.2}, 0.7};
  int rs[3] = {3, 1, 3};
  double *rpar[3] = {w, sc, t};
  worst[0] = fd_check(rigid_cost, &rp, 3, 3, rs, rpar, NULL);
  /* body point-to-plane and point-to-point */
  int32_t nb = m->nbetas < 4 ? m->nbetas : 4, K3 = 3 * m->nj, ncol = spx_body_nparams(m, nb);
  body_state b;
  memset(&b, 0, sizeof b);
  b.ctx = ctx, b.m = m, b.nb = nb, b.ncol = ncol, b.bscale[0] = 1.1;
  b.pose = malloc((size_t)K3 * sizeof(double));
  b.betas = malloc((size_t)(nb ? nb : 1) * sizeof(double));
  b.F = malloc((size_t)m->nv * 3 * sizeof(double));
  b.J = malloc((size_t)m->nv * 3 * (size_t)ncol * sizeof(double));
  if (!b.pose || !b.betas || !b.F || !b.J) {
    free(b.pose), free(b.betas), free(b.F), free(b.J);
    return spx_fail(ctx, SPX_E_NOMEM, "gradient self-test: out of memory");
  }
  for (int32_t i = 0; i < K3; i++) b.pose[i] = 0.6 * U();
  for (int32_t i = 0; i < nb; i++) b.betas[i] = 2 * U();
  for (int d = 0; d < 3; d++) b.trans[d] = U();
  body_pair bp = {&b, m->nv / 3, {0.1, 0.2, 0.3}, {0.48, 0.6, 0.64}, 0.9};
  int bs[4] = {K3, nb, 3, 1};
  double *bpar[4] = {b.pose, b.betas, b.trans, b.bscale};
  if (!nb) bs[1] = 3, bs[2] = 1, bpar[1] = b.trans, bpar[2] = b.bscale;
  worst[1] = fd_check(body_plane_cost, &bp, 1, nb ? 4 : 3, bs, bpar, &b);
  bp.n[0] = -0.8, bp.n[1] = 0, bp.n[2] = 0.6, bp.j = m->nv - 1;
  worst[2] = fd_check(body_plane_cost, &bp, 1, nb ? 4 : 3, bs, bpar, &b);
  /* priors */
  double lims[64];
  for (int i = 0; i < 64; i++) lims[i] = 0.1;
  int n = K3 - 3 < 60 ? K3 - 3 : 60;
  prior_data pl = {n, 0.5, 0, 3, 0, lims}, pp = {n, 0.3, 0, 3, 0, NULL};
  int ps = n + 3;
  double *ppar[1] = {b.pose};
  worst[3] = fmax(fd_check(limit_cost, &pl, n, 1, &ps, ppar, NULL), fd_check(l2_prior_cost, &pp, n, 1, &ps, ppar, NULL));
  /* free-vertex terms */
  double x[5][3];
  for (int i = 0; i < 5; i++)
    for (int d = 0; d < 3; d++) x[i][d] = U();
  lap_data ld = {4, 0.8, {0.01, -0.02, 0.03}};
  int ls[5] = {3, 3, 3, 3, 3};
  double *lpar[5] = {x[0], x[1], x[2], x[3], x[4]};
  free_pair fp = {{0.1, 0.2, 0.3}, {0, 0.6, 0.8}, 1.3};
  worst[4] = fd_check(lap_cost, &ld, 3, 5, ls, lpar, NULL);
  worst[5] = fmax(fd_check(free_plane_cost, &fp, 1, 1, ls, lpar, NULL), fd_check(free_point_cost, &fp, 3, 1, ls, lpar, NULL));
#undef U
  free(b.pose), free(b.betas), free(b.F), free(b.J);
  return SPX_OK;
}
