/* Stage 2 of the registration (SPX_FIT_POSE): pose + shape + translation + a body scale. Data
 * terms both ways (scan point → plane of its nearest model vertex, Huber; model vertex → its
 * nearest scan point along the model normal, Cauchy, area-weighted), an annealed pose prior, soft
 * joint limits, a shape prior and a scale prior. The body model and its Jacobian are evaluated
 * once per point in spx_fit_body_prepare; the residuals read them. With SPX_FIT_AID_RESTART, a fit
 * that leaves over 1% of the scan more than 3 cm from the body is run again from its own shape
 * with straight joints (and, with one camera, turned round), and the start that explains the scan
 * best is kept (second_start). With SPX_FIT_AID_SURFACE each scan point's plane target is moved
 * out by the ring gap (spx_fit_ring_gap), so the body's triangles, not its vertices' planes, are
 * fitted to the scan. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "body/rot3.h"
#include "fit/stage.h"

int spx_fit_body_prepare(void *user, int want_jac, int new_point) {
  spx_fit_body *b = user;
  if (!new_point && (!want_jac || b->have_jac)) return 1;
  spx_body_params p = {b->nb, b->betas, b->pose, b->trans, NULL};
  spx_status st;
  if (want_jac) st = spx_body_jacobian(b->ctx, b->m, &p, b->m->nv, NULL, b->F, b->J);
  else st = spx_body_forward_ref(b->ctx, b->m, &p, b->F, NULL);
  b->have_jac = want_jac;
  if (st) b->st = st;
  return st == SPX_OK;
}

static void body_jac_rows(const spx_fit_body *b, int32_t j, const double *wrow, int nrows, double s, double a,
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

int spx_fit_body_plane_cost(void *user, const double *const *par, double *res, double **jac) {
  const spx_fit_body_pair *q = user;
  const spx_fit_body *b = q->b;
  int sb = b->nb ? 3 : 2;
  double s = par[sb][0];
  const double *F = b->F + (size_t)q->j * 3;
  res[0] = q->a * (q->n[0] * (s * F[0] - q->q[0]) + q->n[1] * (s * F[1] - q->q[1]) + q->n[2] * (s * F[2] - q->q[2]));
  if (jac) body_jac_rows(b, q->j, q->n, 1, s, q->a, jac, sb);
  return 1;
}

int spx_fit_l2_prior_cost(void *user, const double *const *par, double *res, double **jac) {
  const spx_fit_prior *d = user;
  const double *x = par[0] + d->offset;
  for (int i = 0; i < d->n; i++) res[i] = d->w * x[i];
  if (jac && jac[0]) {
    int ncols = d->n + d->offset;
    memset(jac[0], 0, (size_t)d->n * (size_t)ncols * sizeof(double));
    for (int i = 0; i < d->n; i++) jac[0][i * ncols + d->offset + i] = d->w;
  }
  return 1;
}

int spx_fit_limit_cost(void *user, const double *const *par, double *res, double **jac) {
  const spx_fit_prior *d = user;
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

int spx_fit_scale_prior_cost(void *user, const double *const *par, double *res, double **jac) {
  const spx_fit_prior *d = user;
  res[0] = d->w * (par[0][0] * d->target - 1.0);
  if (jac && jac[0]) jac[0][0] = d->w * d->target;
  return 1;
}


/* Soft joint limits (radians per axis-angle component): trunk, clavicle and hip helper joints bend
 * little (0.7), limbs, hands and feet up to 1.6; the joints of the neck and head share one budget
 * of NECK_CHAIN (a head turned ~70 degrees), however many the rig has (SMPL two, the default body's
 * cmu_mb rig three): with 0.7 each, a head seen from the front could twist round by 70 degrees and
 * more at no cost, matching a nearly round head about as well. Names of the cmu_mb rig and SMPL. */
#define NECK_CHAIN 1.2
static int named(const char *n, const char *part) {
  size_t L = strlen(part);
  for (const char *c = n; n && *c; c++)
    if (!strncasecmp(c, part, L)) return 1;
  return 0;
}
static void joint_limits(const spx_body_model *m, double *lim) {
  static const char *stiff[] = {"spine", "back", "collar", "hipjoint", "pelvis", "jaw"};
  int32_t nneck = 0;
  for (int32_t k = 0; m->joint_names && k < m->nj; k++)
    nneck += named(m->joint_names[k], "neck") || named(m->joint_names[k], "head");
  for (int32_t k = 0; k < m->nj; k++) {
    double l = 1.6;
    const char *n = m->joint_names ? m->joint_names[k] : NULL;
    for (size_t q = 0; n && q < sizeof stiff / sizeof stiff[0]; q++)
      if (named(n, stiff[q])) l = 0.7;
    if (n && (named(n, "neck") || named(n, "head"))) l = NECK_CHAIN / nneck;
    for (int d = 0; d < 3; d++) lim[k * 3 + d] = l;
  }
}

/* One pose step's problem: the data pairs matched by the stage loop, then the priors. */
typedef struct pose_stage {
  const spx_body_model *m;
  const spx_fit_options *o;
  spx_fit_work *w;
  spx_fit_body *b;
  spx_fit_result *r;
  int32_t steps;
  spx_fit_prior pr_pose, pr_lim, pr_shape, pr_scale;
  double *gap; /* nq: spx_fit_ring_gap of each scan point (SPX_FIT_AID_SURFACE), or NULL */
} pose_stage;

/* verts_pose: the body at the current parameters, with the body scale */
static spx_status pose_vertices(spx_ctx *ctx, void *user) {
  pose_stage *ps = user;
  spx_fit_body *b = ps->b;
  spx_body_params p = {b->nb, b->betas, b->pose, b->trans, NULL};
  spx_status st = spx_body_forward_ref(ctx, ps->m, &p, b->F, NULL);
  if (st) return st;
  for (int32_t i = 0; i < ps->m->nv * 3; i++) ps->r->verts_pose[i] = b->bscale[0] * b->F[i];
  return SPX_OK;
}

static spx_status pose_residuals(spx_ctx *ctx, spx_ceres_problem *pb, void *user, int32_t step) {
  pose_stage *ps = user;
  const spx_fit_options *o = ps->o;
  spx_fit_work *w = ps->w;
  spx_fit_body *b = ps->b;
  int K3 = 3 * ps->m->nj, nb = b->nb;
  double frac = ps->steps > 1 ? (double)step / (ps->steps - 1) : 1.0;
  double thr = fmax(0.08, 0.3 * pow(0.7, step)); /* pair rejection distance (m) */
  double robust = o->robust_m * pow(4.0, 1.0 - frac); /* 4x → 1x */
  int sizes[4] = {K3, nb, 3, 1};
  double *blocks[4] = {b->pose, b->betas, b->trans, b->bscale};
  int nblk = 4;
  if (!nb) sizes[1] = 3, sizes[2] = 1, blocks[1] = b->trans, blocks[2] = b->bscale, nblk = 3;
  double a1 = sqrt(1.0 / w->nq);
  int32_t np = 0;
  if (ps->gap) spx_fit_ring_gap(w->Q, w->nq, w->idx, w->d2, thr, ps->r->verts_pose, w->N, ps->m->faces, &w->vf,
                                ps->gap);
  for (int32_t i = 0; i < w->nq; i++) {
    if (w->d2[i] > thr * thr) continue;
    spx_fit_body_pair *q = w->bp + np++;
    double g = ps->gap ? ps->gap[i] : 0;
    q->b = b, q->j = w->idx[i], q->a = a1 * (w->wq && i < w->nqf ? sqrt(w->wq[i]) : 1.0);
    for (int d = 0; d < 3; d++) q->n[d] = w->N[q->j * 3 + d], q->q[d] = w->Q[i * 3 + d] + g * q->n[d];
    if (spx_ceres_add_residual(pb, spx_fit_body_plane_cost, q, 1, nblk, sizes, blocks, SPX_LOSS_HUBER, q->a * robust))
      return spx_fit_ceres_error(ctx, "pose");
  }
  for (int32_t jj = 0; jj < w->nms; jj++) {
    int32_t j = w->msub[jj];
    if (w->d2_m[j] > thr * thr || !spx_fit_m2s_ok(w, j)) continue;
    spx_fit_body_pair *q = w->bp + np++;
    double a2 = sqrt(o->w_m2s * w->area[j] * w->msub_w);
    q->b = b, q->j = j, q->a = a2;
    for (int d = 0; d < 3; d++) q->q[d] = w->Q[w->idx_m[j] * 3 + d], q->n[d] = w->N[j * 3 + d];
    /* point-to-plane (model normal): converges much faster than point-to-point */
    if (spx_ceres_add_residual(pb, spx_fit_body_plane_cost, q, 1, nblk, sizes, blocks, SPX_LOSS_CAUCHY, a2 * 2 * robust))
      return spx_fit_ceres_error(ctx, "pose");
  }
  /* free space: vertices outside a camera's silhouette, towards it (area-weighted like the
   * model → scan term over the whole model) */
  for (int32_t k = 0; k < w->nfs; k++) {
    int32_t j = w->fs_j[k];
    spx_fit_body_pair *q = w->bp + np++;
    double a = sqrt(W_FREE_SPACE * w->area[j]);
    q->b = b, q->j = j, q->a = a;
    for (int d = 0; d < 3; d++) q->q[d] = w->fs_q[k * 3 + d], q->n[d] = w->fs_n[k * 3 + d];
    if (spx_ceres_add_residual(pb, spx_fit_body_plane_cost, q, 1, nblk, sizes, blocks, SPX_LOSS_HUBER, a * robust))
      return spx_fit_ceres_error(ctx, "pose");
  }
  /* priors: the pose prior is annealed from 10x down to 1x */
  ps->pr_pose.w = o->w_pose_start * pow(o->w_pose / o->w_pose_start, frac);
  int one = 1;
  if (spx_ceres_add_residual(pb, spx_fit_l2_prior_cost, &ps->pr_pose, K3 - 3, 1, &K3, &b->pose, SPX_LOSS_NONE, 0) ||
      spx_ceres_add_residual(pb, spx_fit_limit_cost, &ps->pr_lim, K3 - 3, 1, &K3, &b->pose, SPX_LOSS_NONE, 0) ||
      (nb && spx_ceres_add_residual(pb, spx_fit_l2_prior_cost, &ps->pr_shape, nb, 1, &nb, &b->betas, SPX_LOSS_NONE, 0)) ||
      spx_ceres_add_residual(pb, spx_fit_scale_prior_cost, &ps->pr_scale, 1, 1, &one, (double *const *)&blocks[nblk - 1],
                             SPX_LOSS_NONE, 0))
    return spx_fit_ceres_error(ctx, "pose");
  b->have_jac = 0;
  return SPX_OK;
}

/* Beyond this distance (metres) from the posed body a scan point is unexplained, and a seen
 * vertex unsupported; both distances are cut there in the score, so that clutter cannot decide. */
#define POSE_FAR 0.03

/* How well the posed body V (model frame) explains the scan sample Q, from the scan and its
 * cameras alone: the mean scan → surface distance plus the area-weighted mean distance from each
 * vertex a camera would have seen (every vertex without cameras) to its nearest scan point, both
 * cut at POSE_FAR, in metres. *far: the share of scan points farther than POSE_FAR. Uses w's
 * scratch (Vf, N, dist, idx_m, d2_m, seen). */
static spx_status pose_score(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, spx_fit_work *w,
                             const double *V, double scale, double *score, double *far) {
  int32_t nv = m->nv;
  for (int32_t i = 0; i < nv * 3; i++) w->Vf[i] = (float)V[i];
  spx_vertex_normals_d(V, nv, m->faces, m->nf, w->N);
  spx_kdtree *qt = NULL;
  spx_status st = spx_fit_surface_distance_adj(ctx, w->Q, w->nq, w->Vf, nv, m->faces, &w->vf, o->threads, w->dist);
  if (!st) st = spx_fit_kd_build(ctx, w->Q, w->nq, &qt);
  if (!st) st = spx_fit_kd_query(ctx, qt, w->Vf, nv, 1, w->idx_m, w->d2_m, o->threads);
  spx_kdtree_free(qt);
  if (st) return st;
  if (w->neye) memset(w->seen, 0, (size_t)nv);
  for (int32_t k = 0; k < w->neye; k++) spx_fit_visibility(&w->zg[k], w->Vf, w->N, nv, SPX_FIT_VIEW_TOL, w->seen);
  double s1 = 0, s2 = 0, a2 = 0;
  int32_t nfar = 0;
  for (int32_t i = 0; i < w->nq; i++) {
    double d = w->dist[i] * scale;
    nfar += d > POSE_FAR;
    s1 += fmin(d, POSE_FAR);
  }
  for (int32_t j = 0; j < nv; j++)
    if (!w->neye || w->seen[j]) s2 += w->area[j] * fmin(sqrt(w->d2_m[j]) * scale, POSE_FAR), a2 += w->area[j];
  *score = s1 / (w->nq ? w->nq : 1) + (a2 > 0 ? s2 / a2 : 0);
  *far = (double)nfar / (w->nq ? w->nq : 1);
  return SPX_OK;
}

/* The pose stage's result (parameters, posed vertices, figures), kept while a second start runs. */
typedef struct pose_keep {
  double *pose, *betas, *verts, trans[3], bscale, seconds, energy, mean;
} pose_keep;

static void pose_copy(int to_keep, pose_keep *k, spx_fit_body *b, spx_fit_result *r, int32_t K3, int32_t nv) {
  double *dst[3] = {k->pose, k->betas, k->verts}, *src[3] = {b->pose, b->betas, r->verts_pose};
  size_t n[3] = {(size_t)K3, (size_t)b->nb, (size_t)nv * 3};
  for (int a = 0; a < 3; a++) memcpy(to_keep ? dst[a] : src[a], to_keep ? src[a] : dst[a], n[a] * sizeof(double));
  double *kd[7] = {&k->trans[0], &k->trans[1], &k->trans[2], &k->bscale, &k->seconds, &k->energy, &k->mean};
  double *bd[7] = {&b->trans[0], &b->trans[1], &b->trans[2], &b->bscale[0], &r->stage_seconds[1], &r->stage_energy[1],
                   &r->stage_mean[1]};
  for (int a = 0; a < 7; a++) *(to_keep ? kd[a] : bd[a]) = *(to_keep ? bd[a] : kd[a]);
}

/* The axis-angle vector of rotation R (angle in [0, pi]). */
static void rot_to_aa(const double R[9], double w[3]) {
  double c = fmax(-1.0, fmin(1.0, 0.5 * (R[0] + R[4] + R[8] - 1))), th = acos(c);
  double v[3] = {R[7] - R[5], R[2] - R[6], R[3] - R[1]}, sn = sin(th);
  if (sn > 1e-6) {
    for (int d = 0; d < 3; d++) w[d] = th * v[d] / (2 * sn);
    return;
  }
  if (th < 1.0) {
    for (int d = 0; d < 3; d++) w[d] = 0.5 * v[d];
    return;
  }
  /* about pi: the axis is the largest column of (R + I) / 2 */
  int a = R[0] >= R[4] && R[0] >= R[8] ? 0 : R[4] >= R[8] ? 1 : 2;
  double col[3] = {R[a] + (a == 0), R[3 + a] + (a == 1), R[6 + a] + (a == 2)};
  double n = sqrt(col[0] * col[0] + col[1] * col[1] + col[2] * col[2]);
  for (int d = 0; d < 3; d++) w[d] = th * col[d] / n;
}

/* The root turned half a turn about the model's up axis (y): the person seen from the other side. */
static void turn_root(double *root) {
  double R[9], T[9], Y[9] = {-1, 0, 0, 0, 1, 0, 0, 0, -1};
  spx_body_rodrigues(root, R, NULL);
  spx_rot3_mul(Y, R, T);
  rot_to_aa(T, root);
}

/* The second starts (SPX_FIT_AID_RESTART): pose stages from the best fit so far's shape,
 * translation and root orientation with every other joint straight, then (one camera) the same
 * with the root turned about the up axis. A limb (or the head) drawn away from its scan points
 * early, while the shape is still far from the person's, ends beyond the pairs' reach and stays
 * there; from the shape the first start found, it is fitted again from the straight pose. The
 * start whose body explains the scan best (pose_score) is kept. */
static spx_status second_start(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, spx_fit_work *w,
                               spx_fit_body *b, spx_fit_result *r, const spx_fit_stage *s, double s1, double f1) {
  int32_t K3 = 3 * m->nj, nv = m->nv;
  pose_keep k = {.pose = malloc((size_t)K3 * sizeof(double)),
                 .betas = malloc((size_t)(b->nb ? b->nb : 1) * sizeof(double)),
                 .verts = malloc((size_t)nv * 3 * sizeof(double))};
  spx_status st = SPX_OK;
  if (!k.pose || !k.betas || !k.verts) st = spx_fail(ctx, SPX_E_NOMEM, "registration (pose): out of memory");
  double best = s1, secs = r->stage_seconds[1];
  for (int t = 0; !st && t < (w->neye == 1 ? 2 : 1); t++) {
    double t0 = spx_now(), s2 = 0, f2 = 0;
    pose_copy(1, &k, b, r, K3, nv);
    for (int32_t i = 3; i < K3; i++) b->pose[i] = 0;
    if (t) turn_root(b->pose);
    st = spx_fit_run_stage(ctx, m, o, w, s, r);
    if (!st) st = pose_score(ctx, m, o, w, r->verts_pose, r->sim_scale, &s2, &f2);
    if (st) break;
    char note[220];
    snprintf(note, sizeof note, "%.1f%% of the scan over %.0f mm from the posed body: a start from straight joints%s "
             "scores %.2f mm (%.1f%% far) against %.2f mm: %s", f1 * 100, POSE_FAR * 1e3, t ? ", turned round" : "",
             s2 * 1e3, f2 * 100, best * 1e3, s2 < best ? "kept" : "dropped");
    spx_fit_report(o, "pose", 0, 0, 0, 0, t0, note);
    secs += r->stage_seconds[1];
    if (s2 < best) best = s2;
    else pose_copy(0, &k, b, r, K3, nv);
  }
  r->stage_seconds[1] = secs;
  free(k.pose), free(k.betas), free(k.verts);
  return st;
}

/* Share of the scan sample (over POSE_FAR from the posed body) above which the second start runs. */
#define POSE_FAR_SHARE 0.01

spx_status spx_fit_stage_pose(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, spx_fit_work *w,
                              spx_fit_body *b, spx_fit_result *r) {
  int32_t K3 = 3 * m->nj, nb = b->nb;
  joint_limits(m, w->lim);
  pose_stage ps = {m, o, w, b, r, o->pose_steps > 0 ? o->pose_steps : 1,
                   {.n = K3 - 3, .offset = 3}, {.n = K3 - 3, .w = o->w_limits, .offset = 3, .lims = w->lim + 3},
                   {.n = nb, .w = o->w_shape}, {.n = 1, .w = o->w_scale, .target = r->sim_scale}, NULL};
  if (o->aids & SPX_FIT_AID_SURFACE)
    if (!(ps.gap = spx_alloc_array(ctx, (size_t)w->nq + 1, sizeof(double), "pose stage"))) return SPX_E_NOMEM;
  spx_fit_stage s = {"pose", 1, ps.steps, w->Q, w->nq, r->verts_pose, pose_vertices,
                     {"pose", pose_residuals, &ps, spx_fit_body_prepare, b, &b->st, o->inner_iterations,
                      SPX_LS_DENSE_NORMAL_CHOLESKY}};
  spx_status st = spx_fit_run_stage(ctx, m, o, w, &s, r);
  double s1 = 0, f1 = 0;
  int restart = !st && (o->aids & SPX_FIT_AID_RESTART);
  if (restart) st = pose_score(ctx, m, o, w, r->verts_pose, r->sim_scale, &s1, &f1);
  if (restart && !st && f1 > POSE_FAR_SHARE) st = second_start(ctx, m, o, w, b, r, &s, s1, f1);
  free(ps.gap);
  return st;
}
