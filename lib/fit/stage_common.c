/* What every registration stage shares (lib/fit/stage.h): two-way nearest neighbours, one Ceres
 * solve from a stage's residual setup, and the outer loop of the pose and free stages (match,
 * solve, measure, report). */
#include <stdlib.h>
#include <string.h>

#include "fit/stage.h"

spx_status spx_fit_ceres_error(spx_ctx *ctx, const char *stage) {
  return spx_fail(ctx, SPX_E_NUMERIC, "registration (%s): %s", stage, spx_ceres_last_error());
}

void spx_fit_report(const spx_fit_options *o, const char *stage, int32_t step, int32_t n, double energy, double mean,
                    double t0, const char *note) {
  if (!o->progress) return;
  spx_fit_progress p = {stage, step, n, energy, mean, spx_now() - t0, note};
  o->progress(o->progress_user, &p);
}

spx_status spx_fit_match(spx_ctx *ctx, int threads, const float *V, int32_t nv, const float *Q, int32_t nq,
                         const spx_kdtree *qt, spx_kdtree **mt, int32_t *idx, float *d2, int32_t *idx_m, float *d2_m) {
  spx_status st;
  spx_kdtree_free(*mt);
  *mt = NULL;
  if ((st = spx_fit_kd_build(ctx, V, nv, mt))) return st;
  if ((st = spx_fit_kd_query(ctx, *mt, Q, nq, 1, idx, d2, threads))) return st;
  return spx_fit_kd_query(ctx, qt, V, nv, 1, idx_m, d2_m, threads);
}

spx_status spx_fit_solve(spx_ctx *ctx, const spx_fit_options *o, const spx_fit_solve_spec *s, int32_t step,
                         spx_ceres_summary *sum) {
  spx_ceres_problem *pb = spx_ceres_problem_create(s->prepare, s->prepare_user);
  if (!pb) return spx_fit_ceres_error(ctx, s->stage);
  spx_status st = s->residuals(ctx, pb, s->user, step);
  if (!st) {
    spx_ceres_options co;
    spx_ceres_options_default(&co);
    co.threads = o->threads;
    co.max_iterations = s->max_iterations;
    co.linear_solver = s->linear_solver;
    co.progress = o->ceres_progress != 0;
    if (s->prepare_status) *s->prepare_status = SPX_OK;
    int rc = spx_ceres_solve(pb, &co, sum);
    if (s->prepare_status && *s->prepare_status) st = *s->prepare_status;
    else if (rc) st = spx_fit_ceres_error(ctx, s->stage);
  }
  spx_ceres_problem_destroy(pb);
  return st;
}

int spx_fit_m2s_ok(const spx_fit_work *w, int32_t j) {
  const double *n = w->N + (size_t)j * 3, *nk = w->N + (size_t)w->idx[w->idx_m[j]] * 3;
  if (n[0] * nk[0] + n[1] * nk[1] + n[2] * nk[2] < 0.3) return 0;
  return !w->neye || w->seen[j];
}

static double mean_of(const float *d, int32_t n) {
  double s = 0;
  for (int32_t i = 0; i < n; i++) s += d[i];
  return n ? s / n : 0;
}

static void to_float(const double *V, int32_t n, float *out) {
  for (int32_t i = 0; i < n; i++) out[i] = (float)V[i];
}

spx_status spx_fit_run_stage(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, spx_fit_work *w,
                             const spx_fit_stage *s, spx_fit_result *r) {
  double t0 = spx_now();
  int32_t nv = m->nv;
  spx_kdtree *qt = NULL, *mt = NULL;
  int32_t nmeas = s->nq < SPX_FIT_MEASURE_POINTS ? s->nq : SPX_FIT_MEASURE_POINTS;
  spx_status st = spx_fit_kd_build(ctx, s->Q, s->nq, &qt);
  for (int32_t step = 0; !st && step < s->steps; step++) {
    if (s->vertices && (st = s->vertices(ctx, s->solve.user))) break;
    to_float(s->V, nv * 3, w->Vf);
    spx_vertex_normals_d(s->V, nv, m->faces, m->nf, w->N);
    if ((st = spx_fit_match(ctx, o->threads, w->Vf, nv, s->Q, s->nq, qt, &mt, w->idx, w->d2, w->idx_m, w->d2_m)))
      break;
    if (w->neye) memset(w->seen, 0, (size_t)nv);
    for (int32_t k = 0; k < w->neye; k++) spx_fit_visibility(&w->zg[k], w->Vf, w->N, nv, SPX_FIT_VIEW_TOL, w->seen);
    w->nfs = 2 * step >= s->steps ? spx_fit_free_space_pairs(w, w->Vf, nv, w->fs_j, w->fs_q, w->fs_n) : 0;
    spx_ceres_summary sum;
    if ((st = spx_fit_solve(ctx, o, &s->solve, step, &sum))) break;
    /* progress: mean scan → surface distance at the new parameters */
    if (s->vertices && (st = s->vertices(ctx, s->solve.user))) break;
    to_float(s->V, nv * 3, w->Vf);
    if ((st = spx_fit_surface_distance_adj(ctx, s->Q, nmeas, w->Vf, nv, m->faces, &w->vf, o->threads, w->dist)))
      break;
    double md = mean_of(w->dist, nmeas) * r->sim_scale;
    r->stage_energy[s->slot] = sum.final_cost;
    r->stage_mean[s->slot] = md;
    spx_fit_report(o, s->name, step + 1, s->steps, sum.final_cost, md, t0, NULL);
  }
  if (!st) r->stage_seconds[s->slot] = spx_now() - t0;
  spx_kdtree_free(qt);
  spx_kdtree_free(mt);
  return st;
}
