/* Stage 1 of the registration (SPX_FIT_RIGID): the similarity model → scan. Candidate
 * orientations (six axis-aligned ups x 8 headings, plus the scan's principal axes) are screened
 * by a short robust ICP on a quarter of the points; the best three (with a camera, also the best
 * one turned about its up axis) are refined and the best of those (two-way mean nearest-point
 * distance over the pairs that count) is kept. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "body/rot3.h"
#include "fit/stage.h"

int spx_fit_rigid_cost(void *user, const double *const *par, double *res, double **jac) {
  const spx_fit_rigid_pair *q = user;
  double R[9], dR[27], Rz[3];
  spx_body_rodrigues(par[0], R, jac && jac[0] ? dR : NULL);
  double s = par[1][0];
  spx_rot3_apply(R, q->z, Rz);
  for (int d = 0; d < 3; d++) res[d] = q->a * (s * Rz[d] + par[2][d] - q->p[d]);
  if (jac) {
    if (jac[0])
      for (int c = 0; c < 3; c++) {
        double o[3];
        spx_rot3_apply(dR + c * 9, q->z, o);
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

/* Rotation whose columns are the model axes' images: x → up × front, y → up, z → front. */
static void frame_from(const double up[3], const double front[3], double *R) {
  double r[3];
  spx_rot3_cross(up, front, r);
  for (int i = 0; i < 3; i++) R[i * 3] = r[i], R[i * 3 + 1] = up[i], R[i * 3 + 2] = front[i];
}

typedef struct rigid_state {
  double Rc[9];
  double w[3], s[1], t[3];
  double score;
} rigid_state;

/* One ICP round's problem: both ways of matched pairs. */
typedef struct icp {
  const spx_fit_options *o;
  const double *Z; /* nm model points in the candidate frame */
  int32_t nm;
  const unsigned char *ok_m; /* nm: the model → scan pair of point j is used */
  const float *S; /* ns scan points */
  int32_t ns;
  const int32_t *i_s2m, *i_m2s;
  spx_fit_rigid_pair *pairs;
  rigid_state *st;
  int rounds, free_scale;
} icp;

static spx_status icp_residuals(spx_ctx *ctx, spx_ceres_problem *pb, void *user, int32_t round) {
  icp *c = user;
  rigid_state *s = c->st;
  int sizes[3] = {3, 1, 3};
  double *blocks[3] = {s->w, s->s, s->t};
  double a1 = sqrt(1.0 / c->ns), a2 = sqrt(c->o->w_m2s / c->nm), scale = 0.1;
  int np = 0;
  for (int32_t i = 0; i < c->ns; i++) {
    spx_fit_rigid_pair *q = c->pairs + np++;
    q->z = c->Z + c->i_s2m[i] * 3, q->a = a1;
    for (int d = 0; d < 3; d++) q->p[d] = c->S[i * 3 + d];
    if (spx_ceres_add_residual(pb, spx_fit_rigid_cost, q, 3, 3, sizes, blocks, SPX_LOSS_HUBER, a1 * scale))
      return spx_fit_ceres_error(ctx, "rigid");
  }
  for (int32_t j = 0; j < c->nm; j++) {
    if (!c->ok_m[j]) continue;
    spx_fit_rigid_pair *q = c->pairs + np++;
    q->z = c->Z + j * 3, q->a = a2;
    for (int d = 0; d < 3; d++) q->p[d] = c->S[c->i_m2s[j] * 3 + d];
    if (spx_ceres_add_residual(pb, spx_fit_rigid_cost, q, 3, 3, sizes, blocks, SPX_LOSS_HUBER, a2 * scale))
      return spx_fit_ceres_error(ctx, "rigid");
  }
  /* a free scale from a bad start lets robust ICP shrink the model: only refined at the end */
  if (spx_ceres_set_constant(pb, s->s, !c->free_scale || round + 2 < c->rounds)) return spx_fit_ceres_error(ctx, "rigid");
  return SPX_OK;
}

/* Which model → scan pairs count (ok_m): not those whose scan point's own nearest model point
 * faces another way (the far side of the body), nor, with cameras (vw, scan frame), model points
 * facing away from every one. Xn: the model points' normals in the scan frame. */
static void pair_filter(const float *X, const double *Xn, int32_t nm, const int32_t *i_s2m, const int32_t *i_m2s,
                        const spx_fit_views *vw, unsigned char *ok_m) {
  for (int32_t j = 0; j < nm; j++) {
    const double *n = Xn + j * 3, *nk = Xn + i_s2m[i_m2s[j]] * 3;
    ok_m[j] = n[0] * nk[0] + n[1] * nk[1] + n[2] * nk[2] >= 0.3;
    int faces = !vw->n;
    for (int32_t k = 0; k < vw->n && !faces; k++) {
      const double *e = vw->eyes + k * 3;
      faces = n[0] * (e[0] - X[j * 3]) + n[1] * (e[1] - X[j * 3 + 1]) + n[2] * (e[2] - X[j * 3 + 2]) > 0;
    }
    ok_m[j] &= faces;
  }
}

/* ICP from a candidate orientation. Y, Yn: nm centred model points and their normals, S: ns scan
 * points (with kd tree); vw: the cameras that saw the scan (scan frame). */
static spx_status rigid_icp(spx_ctx *ctx, const spx_fit_options *o, const double *Y, const double *Yn, int32_t nm,
                            const float *S, int32_t ns, const spx_kdtree *scan_tree, const spx_fit_views *vw, int rounds,
                            int iters, int free_scale, rigid_state *st_io) {
  spx_status st = SPX_OK;
  double *Z = spx_alloc_array(ctx, (size_t)nm * 3, sizeof(double), "rigid");
  float *X = spx_alloc_array(ctx, (size_t)nm * 3, sizeof(float), "rigid");
  int32_t *i_s2m = spx_alloc_array(ctx, (size_t)ns, sizeof(int32_t), "rigid");
  int32_t *i_m2s = spx_alloc_array(ctx, (size_t)nm, sizeof(int32_t), "rigid");
  float *d_s2m = spx_alloc_array(ctx, (size_t)ns, sizeof(float), "rigid");
  float *d_m2s = spx_alloc_array(ctx, (size_t)nm, sizeof(float), "rigid");
  spx_fit_rigid_pair *pairs = spx_alloc_array(ctx, (size_t)(ns + nm), sizeof(spx_fit_rigid_pair), "rigid");
  double *Zn = spx_alloc_array(ctx, (size_t)nm * 3, sizeof(double), "rigid");
  double *Xn = spx_alloc_array(ctx, (size_t)nm * 3, sizeof(double), "rigid");
  unsigned char *ok_m = spx_alloc_array(ctx, (size_t)nm, 1, "rigid");
  spx_kdtree *mt = NULL;
  if (!Z || !X || !i_s2m || !i_m2s || !d_s2m || !d_m2s || !pairs || !Zn || !Xn || !ok_m) {
    st = SPX_E_NOMEM;
    goto cleanup;
  }
  icp c = {o, Z, nm, ok_m, S, ns, i_s2m, i_m2s, pairs, st_io, rounds, free_scale};
  spx_fit_solve_spec solve = {"rigid", icp_residuals, &c, NULL, NULL, NULL, iters, SPX_LS_DENSE_NORMAL_CHOLESKY};
  for (int32_t j = 0; j < nm; j++) spx_rot3_apply(st_io->Rc, Y + j * 3, Z + j * 3), spx_rot3_apply(st_io->Rc, Yn + j * 3, Zn + j * 3);
  for (int r = 0; r <= rounds; r++) {
    double R[9];
    spx_body_rodrigues(st_io->w, R, NULL);
    for (int32_t j = 0; j < nm; j++) {
      double x[3];
      spx_rot3_apply(R, Z + j * 3, x);
      for (int d = 0; d < 3; d++) X[j * 3 + d] = (float)(st_io->s[0] * x[d] + st_io->t[d]);
      spx_rot3_apply(R, Zn + j * 3, Xn + j * 3);
    }
    if ((st = spx_fit_match(ctx, o->threads, X, nm, S, ns, scan_tree, &mt, i_s2m, d_s2m, i_m2s, d_m2s))) goto cleanup;
    pair_filter(X, Xn, nm, i_s2m, i_m2s, vw, ok_m);
    /* score: two-way mean distance over the pairs that count; with fewer than a quarter of the
     * model's points paired, the missing ones count at the worst paired distance */
    double m1 = 0, m2 = 0, worst = 0;
    int32_t n2 = 0;
    for (int32_t i = 0; i < ns; i++) m1 += sqrt(d_s2m[i]);
    for (int32_t j = 0; j < nm; j++)
      if (ok_m[j]) m2 += sqrt(d_m2s[j]), worst = fmax(worst, sqrt(d_m2s[j])), n2++;
    if (n2 < nm / 4) m2 += (nm / 4 - n2) * worst, n2 = nm / 4;
    st_io->score = m1 / ns + (n2 ? m2 / n2 : 0);
    if (r == rounds) break;
    spx_ceres_summary sum;
    if ((st = spx_fit_solve(ctx, o, &solve, r, &sum))) goto cleanup;
    if (!(st_io->s[0] > 1e-3)) st_io->s[0] = 1e-3; /* keep the similarity proper */
  }
cleanup:
  spx_kdtree_free(mt);
  free(Z), free(X), free(i_s2m), free(i_m2s), free(d_s2m), free(d_m2s), free(pairs), free(Zn), free(Xn), free(ok_m);
  return st;
}

#define RIGID_MAXCAND 64

spx_status spx_fit_stage_rigid(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, const float *Sc,
                               int32_t ns, const spx_fit_views *vw, spx_fit_result *r) {
  double t0 = spx_now();
  spx_status st = SPX_OK;
  int32_t nsub = 0, *sidx = spx_fit_subsample(ctx, ns, o->max_points_rigid, o->seed, &nsub);
  int32_t nm = 0, *midx = spx_fit_subsample(ctx, m->nv, o->max_points_rigid, o->seed ^ 0x9e3779b97f4a7c15ULL, &nm);
  float *S = NULL;
  double *Y = NULL, *Yn = NULL, *Vt = NULL, *Nt = NULL;
  spx_kdtree *stree = NULL;
  if (!sidx || !midx) {
    st = SPX_E_NOMEM;
    goto cleanup;
  }
  S = spx_alloc_array(ctx, (size_t)nsub * 3, sizeof(float), "rigid");
  Y = spx_alloc_array(ctx, (size_t)nm * 3, sizeof(double), "rigid");
  Yn = spx_alloc_array(ctx, (size_t)nm * 3, sizeof(double), "rigid");
  Vt = spx_alloc_array(ctx, (size_t)m->nv * 3, sizeof(double), "rigid");
  Nt = spx_alloc_array(ctx, (size_t)m->nv * 3, sizeof(double), "rigid");
  if (!S || !Y || !Yn || !Vt || !Nt) {
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
  for (int32_t i = 0; i < m->nv * 3; i++) Vt[i] = m->v_template[i];
  spx_vertex_normals_d(Vt, m->nv, m->faces, m->nf, Nt);
  for (int32_t j = 0; j < nm; j++)
    for (int d = 0; d < 3; d++) Y[j * 3 + d] = m->v_template[midx[j] * 3 + d] - cm[d], Yn[j * 3 + d] = Nt[midx[j] * 3 + d];
  if ((st = spx_fit_kd_build(ctx, S, nsub, &stree))) goto cleanup;

  /* candidate orientations: 6 axis-aligned ups x 8 headings, plus principal axes */
  rigid_state cand[RIGID_MAXCAND];
  int nc = 0;
  for (int u = 0; u < 6; u++) {
    double up[3] = {0, 0, 0}, a[3] = {0, 0, 0}, b[3];
    up[u / 2] = (u % 2) ? -1.0 : 1.0;
    a[(u / 2 + 1) % 3] = 1.0;
    spx_rot3_cross(up, a, b);
    for (int h = 0; h < 8; h++) {
      double th = h * (M_PI / 4), f[3];
      for (int d = 0; d < 3; d++) f[d] = cos(th) * a[d] + sin(th) * b[d];
      frame_from(up, f, cand[nc++].Rc);
    }
  }
  double ev[3], V[9];
  spx_rot3_sym_eig(C, ev, V);
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
    st = rigid_icp(ctx, o, Y, Yn, mq, S, nq, qt, vw, 2, 6, 0, &cand[c]);
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
    if ((st = rigid_icp(ctx, o, Y, Yn, nm, S, nsub, stree, vw, 5, 15, 1, &cand[k]))) goto cleanup;
  }
  int best = 0;
  for (int k = 1; k < 3 && k < nc; k++)
    if (cand[k].score < cand[best].score) best = k;
  /* one camera's view: the best turned about the model's up axis is refined too (seen from one
   * side, a person's front and back are alike at this coarse level) */
  if (vw->n == 1) {
    rigid_state *flip = &cand[nc];
    *flip = cand[best];
    for (int i = 0; i < 3; i++) flip->Rc[i * 3] = -cand[best].Rc[i * 3], flip->Rc[i * 3 + 2] = -cand[best].Rc[i * 3 + 2];
    if ((st = rigid_icp(ctx, o, Y, Yn, nm, S, nsub, stree, vw, 5, 15, 1, flip))) goto cleanup;
    char note[128];
    snprintf(note, sizeof note, "seen from one camera: the best orientation scores %.2f mm, turned about its up "
             "axis %.2f mm", cand[best].score * 1e3, flip->score * 1e3);
    spx_fit_report(o, "rigid", 0, 0, 0, 0, t0, note);
    if (flip->score < cand[best].score) best = nc;
  }
  double Rw[9], R[9], Rcm[3];
  spx_body_rodrigues(cand[best].w, Rw, NULL);
  spx_rot3_mul(Rw, cand[best].Rc, R);
  spx_rot3_apply(R, cm, Rcm);
  memcpy(r->sim_R, R, sizeof R);
  r->sim_scale = cand[best].s[0];
  for (int d = 0; d < 3; d++) r->sim_t[d] = cand[best].t[d] - r->sim_scale * Rcm[d];
  r->stage_seconds[0] = spx_now() - t0;
  r->stage_mean[0] = cand[best].score * 0.5;
  r->stage_energy[0] = cand[best].score;
  spx_fit_report(o, "rigid", 1, 1, cand[best].score, cand[best].score * 0.5, t0, NULL);
cleanup:
  spx_kdtree_free(stree);
  free(sidx), free(midx), free(S), free(Y), free(Yn), free(Vt), free(Nt);
  return st;
}

