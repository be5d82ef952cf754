/* The registration driver (smplpix/fit.h): options, checks, units, the scan subsamples, the
 * stages in order (lib/fit/stage_rigid.c, stage_pose.c, stage_free.c), then the outputs (scan-space
 * vertices, colours by lib/fit/color.c, the unposed personal template). All solves go through the
 * Ceres bridge (lib/fit/ceres_bridge.cpp); lib/fit/stage.h maps the files. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "body/rot3.h"
#include "fit/stage.h"

void spx_fit_options_default(spx_fit_options *o) {
  *o = (spx_fit_options){.stages = SPX_FIT_ALL, .threads = 1, .nbetas = -1, .unit_scale = 0,
                         .max_points_rigid = 2000, .max_points_pose = 6000, .max_points_free = 100000,
                         .pose_steps = 20, .free_steps = 4, .inner_iterations = 4, .free_inner_iterations = 2,
                         .w_shape = 2e-4, .w_pose = 1e-4, .w_limits = 0.1, .w_scale = 1.0, .w_pose_start = 0.1,
                         .w_m2s = 1.0, .w_lap = 1.0, .w_couple_start = 0.3, .w_couple_end = 0.02,
                         .robust_m = 0.01, .seed = 0x5eed, .progress = NULL, .progress_user = NULL,
                         .ceres_progress = 0, .aids = SPX_FIT_AID_CONTINUE | SPX_FIT_AID_RESTART | SPX_FIT_AID_SURFACE};
}

void spx_fit_result_free(spx_fit_result *r) {
  if (!r) return;
  free(r->betas), free(r->pose), free(r->verts_model), free(r->verts_pose), free(r->verts_scan);
  free(r->colors), free(r->template_unposed), free(r->faces);
  memset(r, 0, sizeof *r);
}

static void work_free(spx_fit_work *w) {
  free(w->Q), free(w->Qf), free(w->Qfv), free(w->wq), free(w->Vf), free(w->N), free(w->idx), free(w->d2);
  free(w->dist), free(w->idx_m), free(w->area), free(w->lim), free(w->msub), free(w->seen), free(w->eyes);
  free(w->fs_j), free(w->fs_q), free(w->fs_n);
  for (int32_t k = 0; w->zg && k < w->neye; k++) spx_fit_zgrid_free(&w->zg[k]);
  free(w->zg);
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
    spx_rot3_cross(e1, e2, n);
    double A = 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) / 3;
    for (int k = 0; k < 3; k++) area[F[k]] += A;
    tot += 3 * A;
  }
  for (int32_t i = 0; i < m->nv; i++) area[i] = tot > 0 ? area[i] / tot : 1.0 / m->nv;
}

/* The result's arrays and the working set of the pose and free stages (but the scan samples). */
static spx_status alloc_all(spx_ctx *ctx, const spx_body_model *m, int32_t nb, int32_t ncol, int32_t ns,
                            spx_fit_result *r, float **Sc, spx_fit_body *b, spx_fit_work *w) {
  int32_t nv = m->nv;
  r->nv = nv, r->nj = m->nj, r->nbetas = nb, r->nf = m->nf;
  r->betas = calloc((size_t)(nb ? nb : 1), sizeof(double));
  r->pose = calloc((size_t)m->nj * 3, sizeof(double));
  r->verts_model = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  r->verts_pose = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  r->verts_scan = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(float), "registration");
  r->template_unposed = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  r->faces = spx_alloc_array(ctx, (size_t)m->nf * 3, sizeof(int32_t), "registration");
  *Sc = spx_alloc_array(ctx, (size_t)ns * 3, sizeof(float), "registration");
  b->F = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  b->J = spx_alloc_array(ctx, (size_t)nv * 3, (size_t)ncol * sizeof(double), "registration jacobian");
  w->Vf = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(float), "registration");
  w->N = spx_alloc_array(ctx, (size_t)nv * 3, sizeof(double), "registration");
  w->idx_m = spx_alloc_array(ctx, (size_t)nv, sizeof(int32_t), "registration");
  w->d2_m = spx_alloc_array(ctx, (size_t)nv, sizeof(float), "registration");
  w->lp = spx_alloc_array(ctx, (size_t)nv, sizeof(spx_fit_lap), "registration");
  w->area = spx_alloc_array(ctx, (size_t)nv, sizeof(double), "registration");
  w->lim = spx_alloc_array(ctx, (size_t)m->nj * 3, sizeof(double), "registration");
  if (!r->betas || !r->pose || !r->verts_model || !r->verts_pose || !r->verts_scan || !r->template_unposed ||
      !r->faces || !*Sc || !b->F || !b->J || !w->Vf || !w->N || !w->idx_m || !w->d2_m || !w->lp || !w->area || !w->lim)
    return spx_fail(ctx, SPX_E_NOMEM, "registration: out of memory");
  memcpy(r->faces, m->faces, (size_t)m->nf * 3 * sizeof(int32_t));
  spx_status st;
  if ((st = spx_fit_vertex_faces(ctx, nv, m->faces, m->nf, &w->vf))) return st;
  if ((st = spx_fit_vertex_neighbours(ctx, nv, m->faces, m->nf, &w->nb))) return st;
  vertex_areas(m, w->area);
  return SPX_OK;
}

/* r->unit_scale (detected or checked) and the scan in metres into Sc. */
static spx_status scan_metres(spx_ctx *ctx, const spx_mesh *scan, const spx_fit_options *o, spx_fit_result *r,
                              float *Sc) {
  int32_t ns = scan->nv;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int32_t i = 0; i < ns; i++)
    for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], scan->pos[i * 3 + d]), hi[d] = fmax(hi[d], scan->pos[i * 3 + d]);
  double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
  if (!(ext > 0)) return spx_fail(ctx, SPX_E_ARG, "registration: the scan has no extent (all points equal)");
  const char *note = NULL;
  spx_status st = spx_fit_units(ctx, ext, o->unit_scale, &r->unit_scale, &note);
  if (st) return st;
  if (note) spx_fit_report(o, "units", 0, 0, 0, 0, spx_now(), note);
  for (int32_t i = 0; i < ns * 3; i++) Sc[i] = (float)(scan->pos[i] * r->unit_scale);
  return SPX_OK;
}

/* scan (metres) → model frame: R^T (p - t) / s */
static void to_model(const spx_fit_result *r, const float *p, float *q) {
  double e[3] = {p[0] - r->sim_t[0], p[1] - r->sim_t[1], p[2] - r->sim_t[2]}, x[3];
  spx_rot3_apply_t(r->sim_R, e, x);
  for (int d = 0; d < 3; d++) q[d] = (float)(x[d] / r->sim_scale);
}

/* The cameras of the options (view, or nviews / view_eyes / point_view), checked, in scan metres. */
static spx_status views_of(spx_ctx *ctx, const spx_fit_options *o, const spx_mesh *scan, double unit,
                           spx_fit_views *vw) {
  memset(vw, 0, sizeof *vw);
  int32_t n = o->nviews > 0 ? o->nviews : o->view ? 1 : 0;
  if (!n) return SPX_OK;
  const double *e = o->nviews > 0 ? o->view_eyes : o->view_eye;
  if (!e) return spx_fail(ctx, SPX_E_ARG, "registration: %d cameras without their centres (view_eyes)", (int)n);
  if (n > 1 && !o->point_view)
    return spx_fail(ctx, SPX_E_ARG, "registration: %d cameras without the camera of each point (point_view)", (int)n);
  if (!(vw->eyes = spx_alloc_array(ctx, (size_t)n, 3 * sizeof(double), "registration"))) return SPX_E_NOMEM;
  vw->n = n;
  for (int32_t k = 0; k < n * 3; k++) {
    if (!isfinite(e[k])) return spx_fail(ctx, SPX_E_ARG, "registration: camera %d's centre is not finite", (int)(k / 3));
    vw->eyes[k] = e[k] * unit;
  }
  if (o->nviews > 0 && o->point_view) {
    vw->of = o->point_view;
    for (int32_t i = 0; i < scan->nv; i++)
      if (vw->of[i] < 0 || vw->of[i] >= n)
        return spx_fail(ctx, SPX_E_ARG, "registration: point %d's camera %d is not one of the %d", (int)i,
                        (int)vw->of[i], (int)n);
  }
  return SPX_OK;
}

/* The pose and free stages' scan samples (model frame) with their cameras, their buffers and the
 * model subsample of the pose stage's model → scan term. */
static spx_status pose_samples(spx_ctx *ctx, const spx_fit_options *o, const float *Sc, int32_t ns, int32_t nv,
                               const spx_fit_views *vw, const spx_fit_result *r, spx_fit_work *w) {
  int32_t mp = o->max_points_pose, mf = o->max_points_free;
  int32_t nmax = mp > mf ? mp : mf;
  if (nmax <= 0 || nmax > ns) nmax = ns;
  int32_t nsel = 0;
  int32_t *sidx = spx_fit_subsample(ctx, ns, nmax, o->seed * 31 + 7, &nsel);
  if (!sidx) return SPX_E_NOMEM;
  w->nq = mp > 0 && mp < nsel ? mp : nsel;
  w->nqf = mf > 0 && mf < nsel ? mf : nsel;
  int32_t nbig = w->nq > w->nqf ? w->nq : w->nqf;
  w->Q = spx_alloc_array(ctx, (size_t)w->nq * 3, sizeof(float), "registration");
  w->Qf = spx_alloc_array(ctx, (size_t)w->nqf * 3, sizeof(float), "registration");
  w->idx = spx_alloc_array(ctx, (size_t)nbig, sizeof(int32_t), "registration");
  w->d2 = spx_alloc_array(ctx, (size_t)nbig, sizeof(float), "registration");
  w->dist = spx_alloc_array(ctx, (size_t)nbig, sizeof(float), "registration");
  /* pairs: scan → model (in the free stage one per vertex, spx_fit_gather_scan), model → scan, free
   * space, and in the free stage the coupling */
  w->bp = spx_alloc_array(ctx, (size_t)w->nq + 2 * (size_t)nv, sizeof(spx_fit_body_pair), "registration");
  w->fp = spx_alloc_array(ctx, 4 * (size_t)nv, sizeof(spx_fit_free_pair), "registration");
  if (!w->Q || !w->Qf || !w->idx || !w->d2 || !w->dist || !w->bp || !w->fp) {
    free(sidx);
    return SPX_E_NOMEM;
  }
  for (int32_t i = 0; i < w->nq; i++) to_model(r, Sc + (size_t)sidx[i] * 3, w->Q + i * 3);
  for (int32_t i = 0; i < w->nqf; i++) to_model(r, Sc + (size_t)sidx[i] * 3, w->Qf + i * 3);
  if (vw->of) {
    w->Qfv = spx_alloc_array(ctx, (size_t)w->nqf, sizeof(int32_t), "registration");
    for (int32_t i = 0; w->Qfv && i < w->nqf; i++) w->Qfv[i] = vw->of[sidx[i]];
  }
  free(sidx);
  if (vw->of && !w->Qfv) return SPX_E_NOMEM;
  if (vw->n) {
    w->eyes = spx_alloc_array(ctx, (size_t)vw->n, 3 * sizeof(double), "registration");
    w->fs_j = spx_alloc_array(ctx, (size_t)nv, sizeof(int32_t), "registration");
    w->fs_q = spx_alloc_array(ctx, (size_t)nv, 3 * sizeof(double), "registration");
    w->fs_n = spx_alloc_array(ctx, (size_t)nv, 3 * sizeof(double), "registration");
    if (!w->eyes || !w->fs_j || !w->fs_q || !w->fs_n) return SPX_E_NOMEM;
    w->neye = vw->n, w->cams_given = 1;
    for (int32_t k = 0; k < vw->n; k++) {
      float e[3] = {(float)vw->eyes[k * 3], (float)vw->eyes[k * 3 + 1], (float)vw->eyes[k * 3 + 2]}, em[3];
      to_model(r, e, em);
      for (int d = 0; d < 3; d++) w->eyes[k * 3 + d] = em[d];
    }
  }
  int32_t nms = 0;
  if (!(w->msub = spx_fit_subsample(ctx, nv, mp > 0 ? (mp + 1) / 2 : nv, o->seed ^ 0xabcdefULL, &nms))) return SPX_E_NOMEM;
  w->nms = nms;
  double asum = 0;
  for (int32_t j = 0; j < nms; j++) asum += w->area[w->msub[j]];
  w->msub_w = asum > 0 ? 1.0 / asum : 1.0;
  return SPX_OK;
}

/* w->wq: the area weights of the free stage's sample (AREA_K neighbours). */
#define AREA_K 16
static spx_status area_weights(spx_ctx *ctx, const spx_fit_options *o, spx_fit_work *w) {
  if (!(w->wq = spx_alloc_array(ctx, (size_t)w->nqf, sizeof(float), "registration"))) return SPX_E_NOMEM;
  return spx_fit_area_weights(ctx, w->Qf, w->nqf, AREA_K, o->threads, w->wq);
}

/* Without a camera: a scan that covers less than 3/4 of the body (by area, within 3 cm of the
 * rigidly placed template), on one side (the covered surface's mean normal is over 0.25 long),
 * is taken as one camera's view from 3 m along that mean normal. Sets w->neye and w->eyes. */
static spx_status infer_view(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, spx_fit_work *w,
                             const double *V, const char **note) {
  int32_t nv = m->nv;
  spx_kdtree *qt = NULL;
  spx_status st = spx_fit_kd_build(ctx, w->Q, w->nq, &qt);
  for (int32_t i = 0; !st && i < nv * 3; i++) w->Vf[i] = (float)V[i];
  if (!st) st = spx_fit_kd_query(ctx, qt, w->Vf, nv, 1, w->idx_m, w->d2_m, o->threads);
  spx_kdtree_free(qt);
  if (st) return st;
  spx_vertex_normals_d(V, nv, m->faces, m->nf, w->N);
  double cov = 0, mn[3] = {0, 0, 0}, c[3] = {0, 0, 0};
  for (int32_t j = 0; j < nv; j++) {
    for (int d = 0; d < 3; d++) c[d] += V[j * 3 + d] / nv;
    if (w->d2_m[j] > 0.03 * 0.03) continue;
    cov += w->area[j];
    for (int d = 0; d < 3; d++) mn[d] += w->area[j] * w->N[j * 3 + d];
  }
  double len = cov > 0 ? sqrt(mn[0] * mn[0] + mn[1] * mn[1] + mn[2] * mn[2]) / cov : 0;
  if (cov < 0.75 && len > 0.25) {
    if (!(w->eyes = spx_alloc_array(ctx, 1, 3 * sizeof(double), "registration"))) return SPX_E_NOMEM;
    w->neye = 1;
    for (int d = 0; d < 3; d++) w->eyes[d] = c[d] + 3.0 * mn[d] / (len * cov);
    *note = "the scan covers one side of the body: fitted as seen from that side";
  }
  return SPX_OK;
}

/* What each camera saw (view.c): its depth grid of the free stage's scan sample (the larger one,
 * so that each camera of several keeps enough points for a fine grid), used by both stages; with
 * free space (freespace.c) also its silhouette. */
static spx_status camera_grids(spx_ctx *ctx, const spx_fit_options *o, spx_fit_work *w) {
  if (!(w->zg = calloc((size_t)w->neye, sizeof *w->zg)))
    return spx_fail(ctx, SPX_E_NOMEM, "registration: out of memory");
  spx_status st = SPX_OK;
  for (int32_t k = 0; !st && k < w->neye; k++) {
    st = spx_fit_zgrid_build(ctx, w->eyes + k * 3, w->Qf, w->nqf, w->Qfv, k, &w->zg[k]);
    if (!st && w->cams_given && (o->aids & SPX_FIT_AID_FREESPACE)) st = spx_fit_zgrid_silhouette(ctx, &w->zg[k]);
  }
  w->free_space = !st && w->cams_given && (o->aids & SPX_FIT_AID_FREESPACE);
  return st;
}

/* r->verts_scan (input units), the colours of a coloured scan and the unposed template. F: nv*3
 * scratch. */
static spx_status outputs(spx_ctx *ctx, const spx_body_model *m, const spx_mesh *scan, const float *Sc, int threads,
                          double *F, spx_fit_result *r) {
  int32_t nv = m->nv;
  for (int32_t i = 0; i < nv; i++) {
    double x[3];
    spx_rot3_apply(r->sim_R, r->verts_model + i * 3, x);
    for (int d = 0; d < 3; d++) r->verts_scan[i * 3 + d] = (float)((r->sim_scale * x[d] + r->sim_t[d]) / r->unit_scale);
  }
  spx_status st;
  if (scan->col && (st = spx_fit_transfer_colors(ctx, scan, Sc, threads, r))) return st;
  double *posed = F; /* registration without the body scale */
  for (int32_t i = 0; i < nv * 3; i++) posed[i] = r->verts_model[i] / r->body_scale;
  spx_body_params p = {r->nbetas, r->betas, r->pose, r->trans, NULL};
  return spx_body_unpose_ref(ctx, m, &p, posed, 1, r->template_unposed);
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
  spx_fit_work w;
  memset(&w, 0, sizeof w);
  spx_fit_body b;
  memset(&b, 0, sizeof b);
  spx_fit_views vw = {0, NULL, NULL};
  float *Sc = NULL;
  spx_fit_result *r = out;
  spx_status st = alloc_all(ctx, m, nb, ncol, ns, r, &Sc, &b, &w);
  if (!st) st = scan_metres(ctx, scan, &o, r, Sc);
  if (!st) st = views_of(ctx, &o, scan, r->unit_scale, &vw);
  if (st) goto cleanup;

  r->sim_scale = 1.0;
  spx_rot3_eye(r->sim_R);
  if ((st = spx_fit_stage_rigid(ctx, m, &o, Sc, ns, &vw, r))) goto cleanup;
  r->stages_done |= SPX_FIT_RIGID;
  b.ctx = ctx, b.m = m, b.nb = nb, b.ncol = ncol, b.pose = r->pose, b.betas = r->betas;
  b.bscale[0] = 1.0 / r->sim_scale; /* the scan is metric after the unit check: start at true size */
  for (int32_t i = 0; i < nv * 3; i++) r->verts_pose[i] = m->v_template[i];

  if (o.stages & (SPX_FIT_POSE | SPX_FIT_FREE)) {
    if ((st = pose_samples(ctx, &o, Sc, ns, nv, &vw, r, &w))) goto cleanup;
    const char *note = NULL;
    if (!vw.n && (st = infer_view(ctx, m, &o, &w, r->verts_pose, &note))) goto cleanup;
    if (note) spx_fit_report(&o, "view", 0, 0, 0, 0, spx_now(), note);
    if (w.neye && !(w.seen = spx_alloc_array(ctx, (size_t)nv, 1, "registration"))) {
      st = SPX_E_NOMEM;
      goto cleanup;
    }
    if (w.neye && (st = camera_grids(ctx, &o, &w))) goto cleanup;
    if (w.neye && (o.aids & SPX_FIT_AID_DENSITY) && (st = area_weights(ctx, &o, &w))) goto cleanup;
    if ((st = spx_fit_stage_pose(ctx, m, &o, &w, &b, r))) goto cleanup;
    r->stages_done |= SPX_FIT_POSE;
    memcpy(r->trans, b.trans, sizeof r->trans);
  }
  r->body_scale = (r->stages_done & SPX_FIT_POSE) ? b.bscale[0] : 1.0;
  memcpy(r->verts_model, r->verts_pose, (size_t)nv * 3 * sizeof(double));

  if (o.stages & SPX_FIT_FREE) {
    if ((st = spx_fit_stage_free(ctx, m, &o, &w, r))) goto cleanup;
    r->stages_done |= SPX_FIT_FREE;
  }
  st = outputs(ctx, m, scan, Sc, o.threads, b.F, r);
cleanup:
  free(Sc), free(b.F), free(b.J), free(vw.eyes);
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
