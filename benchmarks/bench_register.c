/* Registration benchmark: a 50k-point synthetic scan registered end to end (time per stage),
 * the 20-seed accuracy protocol (median of the per-seed mean vertex error), and human_woman.obj
 * (SMPL topology, a different mesh from the default body) as a scan: mean scan → surface after
 * pose+shape only and after the free stage.
 * usage: bench_register [--seeds N] [--threads N] [--part all|one|seeds|woman] [--points N] */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../tests/fit_synth.h"
#include "core/internal.h" /* spx_now */
#include "smplpix/smplpix.h"

static void progress(void *user, const spx_fit_progress *p) {
  if (!*(int *)user) return;
  if (p->note) printf("  note: %s\n", p->note);
  else
    printf("  %-5s %2d/%-2d energy %.4e  mean %.2f mm  (%.1f s)\n", p->stage, p->step, p->nsteps, p->energy,
           p->mean_dist * 1e3, p->seconds);
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* one synthetic registration; returns mean vertex error (m) or -1 */
static double run_synth(spx_ctx *ctx, const spx_body_model *m, uint64_t seed, int32_t npts, int threads, int verbose,
                        double *err_pose, double *secs) {
  double *pose = calloc((size_t)m->nj * 3, sizeof(double)), *betas = calloc((size_t)m->nbetas, sizeof(double));
  double *V = malloc((size_t)m->nv * 3 * sizeof(double)), trans[3], R[9], t[3], res = -1;
  spx_mesh scan = {0};
  spx_fit_result r = {0};
  synth_body(m, seed, 0.3, pose, betas, trans);
  spx_body_params p = {m->nbetas, betas, pose, trans, NULL};
  synth_opts so = {npts, 0.002, 0.2, 1, 1.0, 0};
  if (spx_body_forward_ref(ctx, m, &p, V, NULL) || synth_scan(V, m->nv, m->faces, m->nf, &so, seed, &scan, R, t))
    goto done;
  spx_fit_options o;
  spx_fit_options_default(&o);
  o.threads = threads;
  o.progress = progress;
  o.progress_user = &verbose;
  double t0 = spx_now();
  if (spx_fit_register(ctx, m, &scan, &o, &r)) {
    fprintf(stderr, "register failed: %s\n", spx_ctx_message(ctx));
    goto done;
  }
  if (secs) *secs = spx_now() - t0;
  double e = 0, ep = 0;
  for (int32_t i = 0; i < m->nv; i++) {
    double x[3], dd = 0, dp = 0, y[3];
    for (int d = 0; d < 3; d++)
      x[d] = R[d * 3] * V[i * 3] + R[d * 3 + 1] * V[i * 3 + 1] + R[d * 3 + 2] * V[i * 3 + 2] + t[d];
    /* pose-stage vertices in scan space */
    for (int d = 0; d < 3; d++)
      y[d] = r.sim_scale * (r.sim_R[d * 3] * r.verts_pose[i * 3] + r.sim_R[d * 3 + 1] * r.verts_pose[i * 3 + 1] +
                            r.sim_R[d * 3 + 2] * r.verts_pose[i * 3 + 2]) + r.sim_t[d];
    for (int d = 0; d < 3; d++) dd += pow(r.verts_scan[i * 3 + d] - x[d], 2), dp += pow(y[d] - x[d], 2);
    e += sqrt(dd), ep += sqrt(dp);
  }
  res = e / m->nv;
  if (err_pose) *err_pose = ep / m->nv;
  if (verbose)
    printf("  stages: rigid %.2f s, pose %.2f s, free %.2f s\n", r.stage_seconds[0], r.stage_seconds[1],
           r.stage_seconds[2]);
done:
  spx_fit_result_free(&r);
  spx_mesh_free(&scan);
  free(pose), free(betas), free(V);
  return res;
}

int main(int argc, char **argv) {
  int seeds = 20, threads = 2;
  int32_t npts = 50000;
  const char *part = "all";
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--seeds") && i + 1 < argc) seeds = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--threads") && i + 1 < argc) threads = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--part") && i + 1 < argc) part = argv[++i];
    else if (!strcmp(argv[i], "--points") && i + 1 < argc) npts = atoi(argv[++i]);
    else {
      fprintf(stderr, "usage: bench_register [--seeds N] [--threads N] [--part all|one|seeds|woman] [--points N]\n");
      return 2;
    }
  }
  spx_ctx *ctx = NULL;
  spx_body_model m;
  if (spx_ctx_create(&ctx) || spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &m)) {
    fprintf(stderr, "bench_register: %s\n", spx_ctx_message(ctx));
    return 1;
  }
  int all = !strcmp(part, "all");
  if (all || !strcmp(part, "one")) {
    printf("== one %d-point scan (2 mm noise, 20%% holes, random rigid), %d threads\n", npts, threads);
    double ep = 0, secs = 0, e = run_synth(ctx, &m, 1, npts, threads, 1, &ep, &secs);
    printf("total %.2f s; mean vertex error: pose+shape %.2f mm, final %.2f mm\n", secs, ep * 1e3, e * 1e3);
  }
  if (all || !strcmp(part, "seeds")) {
    printf("== accuracy protocol: %d seeds, %d points\n", seeds, npts);
    double *errs = calloc((size_t)seeds, sizeof(double)), *errp = calloc((size_t)seeds, sizeof(double));
    for (int s = 0; s < seeds; s++) {
      double secs = 0;
      errs[s] = run_synth(ctx, &m, 100 + (uint64_t)s, npts, threads, 0, &errp[s], &secs);
      printf("  seed %3d: pose+shape %.2f mm, final %.2f mm (%.1f s)\n", 100 + s, errp[s] * 1e3, errs[s] * 1e3, secs);
      fflush(stdout);
    }
    qsort(errs, (size_t)seeds, sizeof(double), cmp_d);
    qsort(errp, (size_t)seeds, sizeof(double), cmp_d);
    printf("median mean vertex error: pose+shape %.2f mm, final %.2f mm (worst final %.2f mm)\n",
           errp[seeds / 2] * 1e3, errs[seeds / 2] * 1e3, errs[seeds - 1] * 1e3);
    free(errs), free(errp);
  }
  if (all || !strcmp(part, "woman")) {
    spx_mesh w;
    if (spx_mesh_load(ctx, SPX_REPO_DATA "/body/human_woman.obj", &w)) {
      fprintf(stderr, "bench_register: %s\n", spx_ctx_message(ctx));
      return 1;
    }
    double *V = malloc((size_t)w.nv * 3 * sizeof(double));
    for (int32_t i = 0; i < w.nv * 3; i++) V[i] = w.pos[i];
    spx_mesh scan;
    synth_opts so = {npts, 0.0, 0.0, 0, 1.0, 0};
    synth_scan(V, w.nv, w.faces, w.nf, &so, 7, &scan, NULL, NULL);
    for (int full = 0; full < 2; full++) {
      spx_fit_options o;
      spx_fit_options_default(&o);
      o.threads = threads;
      o.stages = full ? SPX_FIT_ALL : (SPX_FIT_RIGID | SPX_FIT_POSE);
      int verbose = 1;
      o.progress = progress;
      o.progress_user = &verbose;
      spx_fit_result r;
      double t0 = spx_now(), mean = 0, med = 0, p95 = 0;
      if (spx_fit_register(ctx, &m, &scan, &o, &r) ||
          spx_fit_surface_distance(ctx, scan.pos, scan.nv, r.verts_scan, r.nv, r.faces, r.nf, NULL, &mean, &med, &p95)) {
        fprintf(stderr, "bench_register: %s\n", spx_ctx_message(ctx));
        return 1;
      }
      printf("human_woman %s: scan->surface mean %.2f mm, median %.2f mm, p95 %.2f mm (%.1f s)\n",
             full ? "after free stage" : "pose+shape only", mean * 1e3, med * 1e3, p95 * 1e3, spx_now() - t0);
      spx_fit_result_free(&r);
    }
    spx_mesh_free(&scan);
    spx_mesh_free(&w);
    free(V);
  }
  spx_body_free(&m);
  spx_ctx_destroy(ctx);
  return 0;
}
